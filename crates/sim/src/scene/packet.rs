//! Beam packets: a few rays that share an origin and nearly a direction (one VLP-16 laser fired at
//! consecutive azimuths) cast together through the scene's grid, so that they share the cell walk and
//! the scan of each cell's primitive list instead of repeating them ray by ray.
//!
//! Seen from above, the rays of a packet fan out in a thin wedge from the sensor. The wedge's cells are
//! visited in order of their nearest distance to the sensor in the ground plane (`ρ_min`), band by band;
//! every primitive listed in a visited cell at the packet's height is tested against every ray still
//! searching, with the scene's own intersection code. A ray stops once its best hit lies closer (in the
//! ground plane) than the next cell: any hit it has not found lies in a cell not yet visited, hence
//! farther. So a packet returns exactly what [`Scene::cast`] returns for each ray, bit for bit where
//! the nearest hit is unique (a test compares whole revolutions).
//!
//! Rays the wedge does not suit fall back to [`Scene::cast`]: rays that rise or are near vertical,
//! relief (the packet takes the flat ground analytically), packets fanning wider than ~25°, and rays
//! still searching past `REACH_M` (grazing side beams, whose wedge grows wide far out).

use super::{Class, Prim, Scene};

/// Rays per packet at most (the lanes of the per-cell tests).
pub(crate) const LANES: usize = 8;

/// Width of a band of cells sorted together, m (ground-plane distance from the sensor).
const BAND_M: f32 = 0.3;
/// Rays still searching this far from the sensor (ground plane) continue alone, m.
const REACH_M: f32 = 12.0;
/// Slack of the wedge's cell tests and of the stopping rule, m: covers f32 rounding of distances.
const SLACK_M: f32 = 1e-3;
/// Cosine of the widest angle a packet's ray may make with the packet's mean direction (25°).
const MIN_COS: f32 = 0.906;
/// Rays whose horizontal component is below this (steeper than ~87°) are cast alone.
const MIN_HORIZONTAL: f32 = 0.05;

/// Reused buffers of the packet caster: the cells of the band being visited, with their `ρ_min`.
#[derive(Debug, Clone, Default)]
pub(crate) struct Scratch {
    cells: Vec<(f32, u32)>,
}

/// One ray of a packet while it searches.
#[derive(Debug, Clone, Copy)]
struct Ray {
    d: [f32; 3],
    /// Unit horizontal direction and the horizontal length of `d`.
    u: [f32; 2],
    horizontal: f32,
    /// Height change per metre of ground-plane distance.
    slope: f32,
    /// Start of the ray's stretch through the scene's height slab.
    t_lo: f32,
    /// Nearest hit so far, or the end of the stretch while `found` is false, and its class.
    best: f32,
    class: Class,
    found: bool,
    /// Still looking for a nearer hit.
    searching: bool,
}

impl Scene {
    /// Casts the unit rays `o + t·dirs[k]` (field frame, at most [`LANES`]) and writes each one's first
    /// hit with `t ≤ t_max` to `out[k]`, as [`Scene::cast`] would.
    pub(crate) fn cast_packet(
        &self,
        o: [f32; 3],
        dirs: &[[f32; 3]],
        t_max: f32,
        out: &mut [Option<(f32, Class)>],
        scratch: &mut Scratch,
    ) {
        let mut rays = [Ray::IDLE; LANES];
        let mut mean = [0f32; 2];
        for ((&d, slot), ray) in dirs.iter().zip(out.iter_mut()).zip(rays.iter_mut()) {
            *slot = None;
            match self.packet_ray(o, d, t_max) {
                Start::Done(hit) => *slot = hit,
                Start::Alone => *slot = self.cast(o, d, t_max),
                Start::Search(r) => {
                    mean = [mean[0] + r.u[0], mean[1] + r.u[1]];
                    *ray = r;
                }
            }
        }
        let norm = (mean[0] * mean[0] + mean[1] * mean[1]).sqrt();
        if norm == 0.0 {
            return;
        }
        let wedge = Wedge::around([mean[0] / norm, mean[1] / norm], rays.iter().filter(|r| r.searching).map(|r| r.u));
        let complete = match wedge {
            Some(w) => self.walk(o, &w, &mut rays, scratch),
            None => false,
        };
        for ((r, slot), &d) in rays.iter().zip(out.iter_mut()).zip(dirs) {
            if r.searching {
                // Unless the walk visited every cell, one it did not may hold a nearer hit: the ray goes
                // alone, from the start.
                *slot = if complete { r.hit() } else { self.cast(o, d, t_max) };
            } else if r.found {
                *slot = r.hit();
            }
        }
    }

    /// How a ray enters a packet.
    fn packet_ray(&self, o: [f32; 3], d: [f32; 3], t_max: f32) -> Start {
        let horizontal = (d[0] * d[0] + d[1] * d[1]).sqrt();
        if !self.relief.is_flat() || !(d[2] < 0.0) || !(horizontal >= MIN_HORIZONTAL) {
            // A rising ray from above everything meets nothing; the packet does not handle the rest.
            if d[2] >= 0.0 && o[2] > self.top_z {
                return Start::Done(None);
            }
            return Start::Alone;
        }
        // The stretch through the height slab, clipped as `Scene::cast` clips it (d[2] < 0 here).
        let ta = (self.top_z - o[2]) / d[2];
        let tb = (self.bottom_z - o[2]) / d[2];
        let t_lo = 0f32.max(ta.min(tb));
        let t_hi = t_max.min(ta.max(tb));
        if !(t_lo < t_hi) {
            return Start::Done(None);
        }
        // Flat ground: the crossing `Scene::cast` finds, in or out of the grid.
        let t_ground = -o[2] / d[2];
        let ground = t_ground >= t_lo && t_ground <= t_hi;
        Start::Search(Ray {
            d,
            u: [d[0] / horizontal, d[1] / horizontal],
            horizontal,
            slope: d[2] / horizontal,
            t_lo,
            best: if ground { t_ground } else { t_hi },
            class: Class::Ground,
            found: ground,
            searching: true,
        })
    }

    /// Visits the wedge's cells in order of `ρ_min`, band by band, until no ray searches or the packet's
    /// reach is passed. True when every ray's answer is final.
    fn walk(&self, o: [f32; 3], wedge: &Wedge, rays: &mut [Ray; LANES], scratch: &mut Scratch) -> bool {
        let cell = self.cell_m;
        let diag = cell * std::f32::consts::SQRT_2;
        // Nothing lies above top_z: start with the cells that reach where the first ray dips under it.
        let mut rho_a = rays
            .iter()
            .filter(|r| r.searching)
            .map(|r| (self.top_z - o[2]) / r.slope - diag)
            .fold(f32::INFINITY, f32::min)
            .max(0.0);
        // Beyond the farthest grid corner there are no cells.
        let (gx1, gy1) = (self.x0 + self.nx as f32 * cell, self.y0 + self.ny as f32 * cell);
        let fx = (self.x0 - o[0]).abs().max((gx1 - o[0]).abs());
        let fy = (self.y0 - o[1]).abs().max((gy1 - o[1]).abs());
        let grid_far = (fx * fx + fy * fy).sqrt();
        while rho_a < grid_far {
            if rho_a >= REACH_M {
                return false;
            }
            let rho_b = rho_a + BAND_M;
            self.band_cells(o, wedge, rho_a, rho_b, diag, &mut scratch.cells);
            for &(rho_min, c) in &scratch.cells {
                if !retire(rays, rho_min) {
                    return true;
                }
                self.visit(o, rays, c as usize, rho_min, rho_min + diag);
            }
            if !retire(rays, rho_b) {
                return true;
            }
            rho_a = rho_b;
        }
        true
    }

    /// The cells of the wedge whose `ρ_min` lies in `[rho_a, rho_b)`, sorted by it, into `cells`.
    fn band_cells(&self, o: [f32; 3], w: &Wedge, rho_a: f32, rho_b: f32, diag: f32, cells: &mut Vec<(f32, u32)>) {
        cells.clear();
        let cell = self.cell_m;
        // Bounding box of the wedge between rho_a and rho_b + diag (a cell whose ρ_min is in the band
        // reaches at most that far): the four corners and the apex of the outer arc's tangents.
        let r1 = rho_b + diag;
        let outer = r1 / w.cos_half;
        let pts = [
            [rho_a * w.left[0], rho_a * w.left[1]],
            [rho_a * w.right[0], rho_a * w.right[1]],
            [r1 * w.left[0], r1 * w.left[1]],
            [r1 * w.right[0], r1 * w.right[1]],
            [outer * w.centre[0], outer * w.centre[1]],
        ];
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for p in pts {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let index = |v: f32, origin: f32, n: i32| ((v - origin) * self.inv_cell).floor().clamp(-1.0, n as f32) as i32;
        let i0 = index(o[0] + lo[0] - SLACK_M, self.x0, self.nx).max(0);
        let i1 = index(o[0] + hi[0] + SLACK_M, self.x0, self.nx).min(self.nx - 1);
        let j0 = index(o[1] + lo[1] - SLACK_M, self.y0, self.ny).max(0);
        let j1 = index(o[1] + hi[1] + SLACK_M, self.y0, self.ny).min(self.ny - 1);
        let half = 0.5 * cell;
        for j in j0..=j1 {
            let cy0 = self.y0 + j as f32 * cell;
            let dy = (cy0 - o[1]).max(0.0).max(o[1] - (cy0 + cell));
            for i in i0..=i1 {
                let cx0 = self.x0 + i as f32 * cell;
                let dx = (cx0 - o[0]).max(0.0).max(o[0] - (cx0 + cell));
                let rho_min = (dx * dx + dy * dy).sqrt();
                if rho_min < rho_a || rho_min >= rho_b {
                    continue;
                }
                let centre = [cx0 + half - o[0], cy0 + half - o[1]];
                if w.touches(centre, half) {
                    cells.push((rho_min, (j * self.nx + i) as u32));
                }
            }
        }
        cells.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    }

    /// Tests the primitives of cell `c` (ground-plane distances `rho_min..rho_max` from the sensor) at
    /// the searching rays' heights against every searching ray.
    fn visit(&self, o: [f32; 3], rays: &mut [Ray; LANES], c: usize, rho_min: f32, rho_max: f32) {
        // The rays descend: over the cell they lie between their heights at rho_max and rho_min.
        let (mut z_low, mut z_high) = (f32::INFINITY, f32::NEG_INFINITY);
        for r in rays.iter().filter(|r| r.searching) {
            z_low = z_low.min(o[2] + r.slope * rho_max);
            z_high = z_high.max(o[2] + r.slope * rho_min);
        }
        match self.heights.get(c) {
            Some(&h) if z_low <= h => {}
            _ => return,
        }
        let Some(info) = self.cells.get(c) else { return };
        let (refs, prims) = (self.refs.as_slice(), self.prims.as_slice());
        for r in refs.get(info.start as usize..info.end as usize).unwrap_or(&[]) {
            if r.z_max < z_low {
                break;
            }
            if r.z_min > z_high {
                continue;
            }
            if let Some(p) = prims.get(r.prim as usize) {
                test(p, o, rays);
            }
        }
    }
}

/// Tests one primitive against every searching ray, keeping each ray's nearest hit.
#[inline]
fn test(p: &Prim, o: [f32; 3], rays: &mut [Ray; LANES]) {
    for r in rays.iter_mut().filter(|r| r.searching) {
        if let Some(t) = p.intersect(o, r.d, r.t_lo, r.best) {
            r.best = t;
            r.class = p.class;
            r.found = true;
        }
    }
}

/// Stops the rays whose best hit (or end) lies nearer (ground plane) than `rho`: no cell from there on
/// can hold a nearer hit. False when no ray searches any more.
#[inline]
fn retire(rays: &mut [Ray; LANES], rho: f32) -> bool {
    let mut any = false;
    for r in rays.iter_mut() {
        r.searching &= r.best * r.horizontal >= rho - SLACK_M;
        any |= r.searching;
    }
    any
}

/// How a ray enters a packet.
enum Start {
    /// Its answer is known already.
    Done(Option<(f32, Class)>),
    /// The packet does not handle it.
    Alone,
    /// It searches with the packet.
    Search(Ray),
}

impl Ray {
    /// A lane without a ray.
    const IDLE: Self = Self {
        d: [0.0; 3],
        u: [0.0; 2],
        horizontal: 0.0,
        slope: 0.0,
        t_lo: 0.0,
        best: 0.0,
        class: Class::Ground,
        found: false,
        searching: false,
    };

    fn hit(&self) -> Option<(f32, Class)> {
        self.found.then_some((self.best, self.class))
    }
}

/// The wedge a packet's rays span seen from above, apex at the sensor.
#[derive(Debug, Clone, Copy)]
struct Wedge {
    centre: [f32; 2],
    /// The extreme rays' unit directions, left (counter-clockwise) and right of the centre.
    left: [f32; 2],
    right: [f32; 2],
    cos_half: f32,
}

impl Wedge {
    /// The wedge around `centre` holding every direction of `dirs`; `None` when wider than `MIN_COS`.
    fn around(centre: [f32; 2], dirs: impl Iterator<Item = [f32; 2]>) -> Option<Self> {
        let (mut left, mut right) = ((0f32, centre), (0f32, centre));
        let mut cos_half = 1f32;
        for u in dirs {
            let side = centre[0] * u[1] - centre[1] * u[0];
            let cos = centre[0] * u[0] + centre[1] * u[1];
            cos_half = cos_half.min(cos);
            if side > left.0 {
                left = (side, u);
            }
            if side < right.0 {
                right = (side, u);
            }
        }
        (cos_half >= MIN_COS).then_some(Self { centre, left: left.1, right: right.1, cos_half })
    }

    /// Whether the square of half-side `half` centred at `c` (relative to the apex) may meet the
    /// wedge: it reaches into the half-planes left of the right ray, right of the left ray, and ahead.
    fn touches(&self, c: [f32; 2], half: f32) -> bool {
        // For a unit normal n, the square's farthest reach along n is n·c + half·(|nx| + |ny|).
        let reach = |n: [f32; 2]| n[0] * c[0] + n[1] * c[1] + half * (n[0].abs() + n[1].abs()) >= -SLACK_M;
        let (l, r) = (self.left, self.right);
        // Left of the right ray: normal (-r.y, r.x); right of the left ray: normal (l.y, -l.x).
        reach([-r[1], r[0]]) && reach([l[1], -l[0]]) && reach(self.centre)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Crop, Field, FieldConfig, Stage};

    /// The rays of one VLP-16 revolution (16 beams, 1800 columns, column-major) from a sensor 1.5 m over
    /// `(x, y)`, heading `yaw`, pitched 30° down, in the field frame.
    fn revolution(yaw: f32) -> Vec<[f32; 3]> {
        let (sp, cp) = 30f32.to_radians().sin_cos();
        let (sy, cy) = yaw.sin_cos();
        let mut dirs = Vec::with_capacity(1800 * 16);
        for c in 0..1800 {
            let az = (180.0 - c as f32 * 0.2).to_radians();
            for b in 0..16 {
                let el = (-15.0 + 2.0 * b as f32).to_radians();
                let s = [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()];
                // Pitch down about y, then yaw about z.
                let p = [cp * s[0] + sp * s[2], s[1], -sp * s[0] + cp * s[2]];
                dirs.push([cy * p[0] - sy * p[1], sy * p[0] + cy * p[1], p[2]]);
            }
        }
        dirs
    }

    /// Every ray of whole revolutions cast in packets and alone: same hits (within 1 mm) and classes.
    fn packets_match_single_rays(config: FieldConfig, poses: &[(f32, f32, f32)], min_crop_hits: usize) {
        let field = Field::generate(&config, 3).unwrap();
        let s = field.scene();
        let mut scratch = Scratch::default();
        let (mut crop, mut mismatches) = (0, Vec::new());
        for &(x, y, yaw) in poses {
            let o = [x, y, 1.5];
            let dirs = revolution(yaw);
            for beam in 0..16 {
                let rays: Vec<[f32; 3]> = dirs.iter().skip(beam).step_by(16).copied().collect();
                for chunk in rays.chunks(LANES) {
                    let mut out = [None; LANES];
                    s.cast_packet(o, chunk, 100.0, &mut out[..chunk.len()], &mut scratch);
                    for (d, packet) in chunk.iter().zip(out) {
                        let alone = s.cast(o, *d, 100.0);
                        let same = match (packet, alone) {
                            (None, None) => true,
                            (Some((tp, cp)), Some((ta, ca))) => (tp - ta).abs() < 1e-3 && cp == ca,
                            _ => false,
                        };
                        crop += usize::from(matches!(alone, Some((_, Class::Crop))));
                        if !same {
                            mismatches.push((o, *d, packet, alone));
                        }
                    }
                }
            }
        }
        assert!(mismatches.is_empty(), "{} mismatches, first {:?}", mismatches.len(), mismatches.first());
        // The rays must exercise the plants, not only the ground.
        assert!(crop > min_crop_hits, "{crop} crop hits");
    }

    #[test]
    fn packets_match_single_rays_over_grown_corn() {
        let config = FieldConfig {
            crop: Crop::Corn,
            stage: Stage::Grown,
            rows: 8,
            length_m: 12.0,
            weeds_per_m2: 2.0,
            ..FieldConfig::default()
        };
        packets_match_single_rays(config, &[(4.0, 2.625, 0.0), (6.0, 2.3, 0.3), (11.5, 0.0, -2.5)], 10_000);
    }

    #[test]
    fn packets_match_single_rays_over_young_soybean() {
        let config = FieldConfig {
            crop: Crop::Soybean,
            stage: Stage::Young,
            rows: 8,
            length_m: 12.0,
            weeds_per_m2: 2.0,
            ..FieldConfig::default()
        };
        packets_match_single_rays(config, &[(4.0, 2.625, 0.0), (-1.0, 3.0, 0.8)], 2_000);
    }
}
