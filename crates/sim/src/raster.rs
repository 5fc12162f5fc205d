//! The LiDAR's fast path: instead of marching each ray through the grid, the primitives near the
//! sensor are rasterised into the scan's range image (beams × azimuth columns, a z-buffer of the
//! nearest hit and its class). It sits between [`crate::lidar::Lidar`] (which fires the rays and adds
//! noise) and [`crate::scene::Scene`] (which holds the primitives and the grid marcher).
//!
//! Exact by construction, not by tuning:
//! - every ray that points down starts with its flat-ground hit (one division) and keeps the nearest
//!   primitive hit found by the exact ray-primitive intersection of the scene;
//! - a primitive is tried only on the pixels of its footprint: the beams whose cone passes within its
//!   bounding sphere's angular radius and the azimuth columns within the sphere's azimuth half-width
//!   (both widened by a milliradian and a column for rounding);
//! - only primitives listed in the grid cells that the rays' first [`NEAR_RADIUS_M`] metres (horizontal)
//!   inside the canopy slab cross are rasterised, so a ray's answer is final only when it lies within
//!   that stretch; every other ray (pointing up, grazing far out, or over relief) goes to the marcher.

use crate::scene::{Class, Scene};

/// Horizontal reach of the rasterised region from the sensor, m. Rays whose first hit lies farther
/// (side beams grazing over the canopy) are handed to the grid marcher; a larger reach rasterises more
/// primitives, a smaller one marches more rays.
const NEAR_RADIUS_M: f32 = 5.0;

/// Angular slack of a footprint, rad: covers the f32 rounding of the ray directions (microradians).
const ANGLE_SLACK_RAD: f32 = 1e-3;

/// The scan's geometry as the rasteriser sees it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Layout<'a> {
    /// Unit beam directions in the sensor frame, column-major (`column * beams + beam`).
    pub dirs: &'a [[f32; 3]],
    /// Beams per column.
    pub beams: usize,
    /// Columns per revolution.
    pub columns: usize,
    /// Azimuth step between columns, rad; column `c` points at azimuth `π - c·step`.
    pub step_rad: f32,
    /// Per beam, sine and cosine of its elevation in the sensor frame.
    pub sin_el: &'a [f32],
    /// See `sin_el`.
    pub cos_el: &'a [f32],
}

/// A sensor pose in the field frame: origin (m) and rotation (sensor -> field, row-major).
#[derive(Debug, Clone, Copy)]
pub(crate) struct SensorPose {
    /// Sensor origin, m.
    pub origin: [f32; 3],
    /// Rotation matrix, sensor -> field.
    pub rot: [[f32; 3]; 3],
}

impl SensorPose {
    /// A sensor-frame direction in the field frame.
    #[inline]
    pub fn to_field(self, ds: [f32; 3]) -> [f32; 3] {
        let r = &self.rot;
        [
            r[0][0] * ds[0] + r[0][1] * ds[1] + r[0][2] * ds[2],
            r[1][0] * ds[0] + r[1][1] * ds[1] + r[1][2] * ds[2],
            r[2][0] * ds[0] + r[2][1] * ds[1] + r[2][2] * ds[2],
        ]
    }

    /// A field-frame vector in the sensor frame.
    #[inline]
    fn to_sensor(self, p: [f32; 3]) -> [f32; 3] {
        let r = &self.rot;
        [
            r[0][0] * p[0] + r[1][0] * p[1] + r[2][0] * p[2],
            r[0][1] * p[0] + r[1][1] * p[1] + r[2][1] * p[2],
            r[0][2] * p[0] + r[1][2] * p[1] + r[2][2] * p[2],
        ]
    }
}

/// Reusable buffers of the rasteriser: allocated on the first scan, reused after.
#[derive(Debug, Clone, Default)]
pub(crate) struct Raster {
    /// Field-frame ray directions of the block.
    world: Vec<[f32; 3]>,
    /// Per ray: nearest hit so far (m), or a negative value for a ray the marcher handles.
    depth: Vec<f32>,
    /// Per ray: class of the nearest hit, `None` while nothing was hit within range.
    class: Vec<Option<Class>>,
    /// Per ray: how far along the ray the rasterised region certainly reaches, m.
    reach: Vec<f32>,
    /// Per primitive: the last block that gathered it (deduplicates primitives listed in several cells).
    stamp: Vec<u32>,
    epoch: u32,
    /// Primitives gathered for the block.
    gathered: Vec<u32>,
    /// Footprints of the gathered primitives, then the same sorted by near distance.
    footprints: Vec<Footprint>,
    order: Vec<Footprint>,
    /// Counting-sort buckets.
    buckets: Vec<u32>,
}

/// Where a primitive can appear in the range image: its bounding sphere seen from the sensor.
#[derive(Debug, Clone, Copy)]
struct Footprint {
    /// No ray meets the primitive closer than this, m.
    t_near: f32,
    prim: u32,
    /// Beams `b_lo..=b_hi` pass within the sphere's angular radius.
    b_lo: u16,
    b_hi: u16,
    /// Whether the sphere holds the sensor or the vertical axis: every column then.
    full: bool,
    /// Sensor-frame height and horizontal distance of the centre, and the tangent length
    /// `sqrt(dist² - r²)`, m: they give each beam's chord through the sphere's angular disc.
    z: f32,
    h: f32,
    tangent: f32,
    /// Fractional column of the centre.
    centre: f32,
}

/// Width of a depth bucket of the front-to-back sort, m.
const BUCKET_M: f32 = 0.05;

impl Raster {
    /// Projects the gathered primitives and orders their footprints nearest first (by bucket of
    /// `BUCKET_M`), so that a pixel already hit in front of a primitive skips it with one comparison.
    fn sort_front_to_back(&mut self, scene: &Scene, layout: &Layout<'_>, pose: &SensorPose) {
        self.footprints.clear();
        for &k in &self.gathered {
            if let Some(f) = Self::project(scene, layout, pose, k) {
                self.footprints.push(f);
            }
        }
        let bucket = |f: &Footprint| ((f.t_near.max(0.0) / BUCKET_M) as usize).min(4095);
        self.buckets.clear();
        self.buckets.resize(4097, 0);
        for f in &self.footprints {
            if let Some(n) = self.buckets.get_mut(bucket(f) + 1) {
                *n += 1;
            }
        }
        for b in 1..self.buckets.len() {
            let prev = self.buckets.get(b - 1).copied().unwrap_or(0);
            if let Some(n) = self.buckets.get_mut(b) {
                *n += prev;
            }
        }
        self.order.clear();
        self.order.resize(
            self.footprints.len(),
            Footprint {
                t_near: 0.0,
                prim: 0,
                b_lo: 1,
                b_hi: 0,
                full: false,
                z: 0.0,
                h: 0.0,
                tangent: 0.0,
                centre: 0.0,
            },
        );
        for f in &self.footprints {
            if let Some(slot) = self.buckets.get_mut(bucket(f))
                && let Some(out) = self.order.get_mut(*slot as usize)
            {
                *out = *f;
                *slot += 1;
            }
        }
    }
}

impl Raster {
    /// Casts columns `first..last` from `pose` and writes one result per ray (column-major, as
    /// `layout.dirs`) into `out`: the same first hit `(t, class)` within `t_max` as `Scene::cast`.
    pub fn cast(
        &mut self,
        scene: &Scene,
        layout: &Layout<'_>,
        pose: &SensorPose,
        first: usize,
        last: usize,
        t_max: f32,
        out: &mut Vec<Option<(f32, Class)>>,
    ) {
        out.clear();
        let beams = layout.beams;
        let rays = layout.dirs.get(first * beams..last * beams).unwrap_or(&[]);
        let o = pose.origin;
        self.world.clear();
        self.world.extend(rays.iter().map(|&ds| pose.to_field(ds)));
        self.depth.clear();
        self.class.clear();
        self.reach.clear();
        // The region the rays cross inside the canopy slab within the reach: its bounding box.
        let top = scene.top_z();
        let mut bbox = [f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY];
        let flat = scene.is_flat();
        for d in &self.world {
            let (mut depth, mut class, mut reach) = (-1.0, None, -1.0);
            if flat && d[2] < 0.0 {
                let t_ground = -o[2] / d[2];
                let h = (d[0] * d[0] + d[1] * d[1]).sqrt();
                let t_reach = if h > 0.0 { NEAR_RADIUS_M / h } else { f32::INFINITY };
                (depth, class) =
                    if t_ground <= t_max { (t_ground, Some(Class::Ground)) } else { (t_max, None) };
                reach = t_reach.min(t_ground).min(t_max);
                let t_in = ((top - o[2]) / d[2]).clamp(0.0, reach);
                for t in [t_in, reach] {
                    let (x, y) = (o[0] + t * d[0], o[1] + t * d[1]);
                    bbox = [bbox[0].min(x), bbox[1].min(y), bbox[2].max(x), bbox[3].max(y)];
                }
            }
            self.depth.push(depth);
            self.class.push(class);
            self.reach.push(reach);
        }
        if bbox[0] <= bbox[2] {
            self.gather(scene, bbox);
            self.sort_front_to_back(scene, layout, pose);
            let order = std::mem::take(&mut self.order);
            for f in &order {
                self.draw(scene, layout, o, f, first, last);
            }
            self.order = order;
        }
        for (k, d) in self.world.iter().enumerate() {
            let depth = self.depth.get(k).copied().unwrap_or(-1.0);
            let reach = self.reach.get(k).copied().unwrap_or(-1.0);
            let class = self.class.get(k).copied().flatten();
            out.push(match class {
                Some(c) if depth >= 0.0 && depth <= reach => Some((depth, c)),
                _ => scene.cast(o, *d, t_max),
            });
        }
    }

    /// Collects, once each, the primitives listed in the grid cells over `bbox` (`[x0, y0, x1, y1]`).
    fn gather(&mut self, scene: &Scene, bbox: [f32; 4]) {
        self.gathered.clear();
        if self.stamp.len() != scene.primitive_count() {
            self.stamp.clear();
            self.stamp.resize(scene.primitive_count(), 0);
            self.epoch = 0;
        }
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.stamp.fill(0);
            self.epoch = 1;
        }
        let (stamp, epoch, gathered) = (&mut self.stamp, self.epoch, &mut self.gathered);
        scene.visit_cells(bbox[0], bbox[2], bbox[1], bbox[3], |k| {
            if let Some(s) = stamp.get_mut(k as usize)
                && *s != epoch
            {
                *s = epoch;
                gathered.push(k);
            }
        });
    }

    /// The footprint of primitive `k` in the range image, or `None` when no beam passes near it.
    fn project(scene: &Scene, layout: &Layout<'_>, pose: &SensorPose, k: u32) -> Option<Footprint> {
        let (_, sphere) = scene.prim(k)?;
        let o = pose.origin;
        let q = pose.to_sensor([sphere[0] - o[0], sphere[1] - o[1], sphere[2] - o[2]]);
        let dist2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
        let dist = dist2.sqrt();
        let r = sphere[3] + ANGLE_SLACK_RAD * dist + 1e-4;
        let h = (q[0] * q[0] + q[1] * q[1]).sqrt();
        let all = Footprint {
            t_near: dist - r,
            prim: k,
            b_lo: 0,
            b_hi: layout.beams.saturating_sub(1) as u16,
            full: true,
            z: q[2],
            h,
            tangent: 0.0,
            centre: 0.0,
        };
        // No ray can meet the primitive before `t_near`.
        if all.t_near <= 0.0 {
            return Some(all);
        }
        // A beam's cone passes within the sphere's angular radius `a` of its centre when
        // cos(elevation difference) >= cos(a), i.e. `h·cos(el) + z·sin(el) >= sqrt(dist² - r²)`.
        let tangent = (dist2 - r * r).max(0.0).sqrt();
        let (mut b_lo, mut b_hi) = (usize::MAX, 0);
        for (b, (s, c)) in layout.sin_el.iter().zip(layout.cos_el).enumerate() {
            if h * c + q[2] * s >= tangent {
                b_lo = b_lo.min(b);
                b_hi = b;
            }
        }
        if b_lo > b_hi {
            return None;
        }
        let (b_lo, b_hi) = (b_lo as u16, b_hi as u16);
        if r >= h {
            return Some(Footprint { b_lo, b_hi, ..all });
        }
        let centre = (std::f32::consts::PI - q[1].atan2(q[0])) / layout.step_rad;
        Some(Footprint { b_lo, b_hi, full: false, tangent, centre, ..all })
    }

    /// Runs the footprint's primitive's exact intersection on every pixel of the footprint in columns
    /// `first..last` whose nearest hit so far lies beyond the primitive's near distance.
    fn draw(
        &mut self,
        scene: &Scene,
        layout: &Layout<'_>,
        o: [f32; 3],
        f: &Footprint,
        first: usize,
        last: usize,
    ) {
        let Some((prim, _)) = scene.prim(f.prim) else { return };
        let (beams, columns) = (layout.beams, layout.columns as i32);
        let (first_i, last_i) = (first as i32, last as i32);
        let class = prim.class();
        for b in f.b_lo as usize..=f.b_hi as usize {
            let (Some(&sin_b), Some(&cos_b)) = (layout.sin_el.get(b), layout.cos_el.get(b)) else { continue };
            let (c_lo, c_hi) = if f.full {
                (0, columns - 1)
            } else {
                // The beam's chord through the sphere's angular disc: directions at elevation `el`
                // within angle `a` of the centre differ from it in azimuth by `Δ` with
                // cos Δ = (cos a - sin e·sin el) / (cos e·cos el) = (tangent - z·sin el) / (h·cos el).
                let cos_d = (f.tangent - f.z * sin_b) / (f.h * cos_b);
                if cos_d <= -1.0 || cos_d.is_nan() {
                    (0, columns - 1)
                } else {
                    // Δ = 2·asin(x) with x = sin(Δ/2), and asin(x) <= x + (π/2 - 1)·x³ on [0, 1].
                    let x = (0.5 * (1.0 - cos_d.min(1.0))).sqrt().min(1.0);
                    let delta = 2.0 * x * (1.0 + (std::f32::consts::FRAC_PI_2 - 1.0) * x * x);
                    let half = delta / layout.step_rad + 1.0;
                    let (lo, hi) = ((f.centre - half).floor() as i32, (f.centre + half).ceil() as i32);
                    (lo, hi.min(lo + columns - 1))
                }
            };
            for shift in [-columns, 0, columns] {
                let (lo, hi) = ((c_lo + shift).max(first_i), (c_hi + shift).min(last_i - 1));
                for c in lo..=hi {
                    let i = (c - first_i) as usize * beams + b;
                    let (Some(depth), Some(d)) = (self.depth.get_mut(i), self.world.get(i)) else { continue };
                    if *depth <= f.t_near {
                        continue;
                    }
                    if let Some(t) = prim.intersect(o, *d, 0.0, *depth) {
                        *depth = t;
                        if let Some(c) = self.class.get_mut(i) {
                            *c = Some(class);
                        }
                    }
                }
            }
        }
    }
}
