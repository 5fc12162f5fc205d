//! Step 1 of both pipelines (paper Sec. III-A-1): one pass over the scan that maps each point to
//! `base_link`, keeps the frontal field of view within range, then keeps the canopy: the points above a
//! virtual ground plane.
//!
//! The plane is parallel to the ground (horizontal in `base_link`, which is how the paper's
//! `v⊥ = R_y,θ · [0 0 1]ᵀ` reads once the mount rotation is applied) and sits at the height of the
//! centroid of the cropped points (eqs. 1-2), raised by `plane_raise_m`. The default mode instead places
//! it halfway between robust ground and canopy-top levels (5th and 95th height percentiles), which keeps
//! low weeds and ground noise out even when most returns come from the ground, and drops returns
//! floating more than [`ABOVE_TOP_M`] above the canopy top (dust, insects). In the default mode the
//! cropped points are first cleared of clutter (returns alone in their voxel: dust and insects, which
//! would otherwise lift the 95th percentile off a young crop; see [`Clutter`]) and levelled by the tilt
//! the scan shows ([`super::level`]), so that a LiDAR off its configured mount still puts the plane
//! parallel to the ground.

use nalgebra::Rotation3;

use crate::geometry::{Attitude, Mount};

use super::Scan;
use super::config::DetectorConfig;
use super::deskew::Deskew;
use super::holes::Holes;
use super::interleave::for_each_interleaved;
use super::level::Level;

/// Height histogram bin, m, and its span below/above `base_link`'s origin for the robust plane.
const Z_BIN_M: f32 = 0.01;
const Z_MIN_M: f32 = -2.0;
const Z_BINS: usize = 500;
/// Default mode: returns more than this above the 95th height percentile are not canopy, m. A crop's
/// top is a continuous surface whose highest returns lie within centimetres of that percentile; a
/// return floating well above it is dust, an insect or a bird, and its height-squared weight in the
/// row fit would outweigh dozens of plant returns (soak seed 561: 56 such returns per scan turned the
/// start-up heading by 10°). Not lower: 0.3 m cut into the tops of a grown soybean canopy and a lane
/// re-entry was refused as the wrong lane (`soak_acquire`, seed 11).
const ABOVE_TOP_M: f32 = 0.5;

/// Slots of the clutter test's voxel count table (a power of two, for the mask). A scan's cropped
/// returns occupy a few thousand voxels, so two voxels rarely share a slot; when they do, the slot's
/// count is their sum, which can only keep a return that should have gone, never drop one.
const VOXEL_SLOTS: usize = 1 << 16;
/// Returns whose voxel indices are floored together in one loop over their coordinates, which the
/// compiler vectorises (the floors were most of the test's cost when done point by point).
const FLOOR_CHUNK: usize = 64;

/// The clutter test: counts the cropped returns per voxel in hashed tables allocated once. Dust and
/// insects are sparse in the air (one return per 2-3 voxels of 0.2 m at the soak's densest, 600 a
/// scan), a surface hit by the scanner is dense along each ring (about fourteen returns per 0.2 m at
/// 4 m), so a return whose voxel holds fewer than `min_points` returns is clutter. Two grids half a voxel apart
/// count the returns, and a return is kept when either of its voxels is dense: a surface lying on a
/// voxel face of one grid (the ground at z = 0) would otherwise be split between two voxels and thinned.
#[derive(Debug, Clone)]
struct Clutter {
    /// The two grids' count tables, [`VOXEL_SLOTS`] each. Zero between scans: each scan clears the
    /// few thousand slots it counted in, where clearing the whole 256 KB cost more than the count.
    counts: Box<[u16; 2 * VOXEL_SLOTS]>,
    /// Each point's slot in the two tables, hashed once per scan (the test reads them three times).
    slots: Vec<[u32; 2]>,
}

/// `x.floor() as i32` without the call to `floorf` that baseline x86-64 (no SSE4.1) makes for it: the
/// same value for every `x`, saturating likewise.
fn floor_i32(x: f32) -> i32 {
    let t = x as i32;
    t.saturating_sub(i32::from(t as f32 > x))
}

/// 1.5·2²³ and its bits. Adding it to an `f32` of magnitude under [`FLOOR_SMALL`] rounds that to an
/// integer exactly (the sum lies in 2²³..=2²⁴, where the spacing of `f32` is 1) and leaves the integer
/// in the sum's bits: a floor made of additions, a bit cast and a compare, which the compiler
/// vectorises, where the saturating `as i32` of [`floor_i32`] stays one lane at a time.
const ROUNDER: f32 = 12_582_912.0;
const ROUNDER_BITS: i32 = 0x4B40_0000;
/// Magnitude under which [`floor_small`] equals [`floor_i32`] (2²²).
const FLOOR_SMALL: f32 = 4_194_304.0;

/// `x.floor() as i32` for |x| < [`FLOOR_SMALL`] (the caller checks): the exact floor, as
/// [`floor_i32`] gives it.
fn floor_small(x: f32) -> i32 {
    let r = x + ROUNDER;
    let nearest = (r.to_bits() as i32).wrapping_sub(ROUNDER_BITS);
    nearest - i32::from(r - ROUNDER > x)
}

/// The spatial hash's primes for the x, y and z voxel index (Teschner et al. 2003): the wrapping
/// products, xor-ed, mix the three indices.
const AXIS_PRIMES: [u32; 3] = [73_856_093, 19_349_663, 83_492_791];

/// Table slot of a voxel (in one grid's table), from its indices times [`AXIS_PRIMES`].
fn voxel_slot(&[i, j, k]: &[u32; 3]) -> u32 {
    (i ^ j ^ k) & (VOXEL_SLOTS as u32 - 1)
}

impl Clutter {
    fn new() -> Self {
        Self { counts: Box::new([0; 2 * VOXEL_SLOTS]), slots: Vec::new() }
    }

    /// Appends to `slots` the table slots of each point's voxels of side `inv_m`⁻¹: in grid 0, and in
    /// grid 1 (shifted by half a voxel, in the second table).
    fn hash_points(points: &[[f32; 3]], inv_m: f32, slots: &mut Vec<[u32; 2]>) {
        for chunk in points.chunks(FLOOR_CHUNK) {
            let (mut grid0, mut grid1) = ([[0u32; 3]; FLOOR_CHUNK], [[0u32; 3]; FLOOR_CHUNK]);
            let coordinates = chunk.as_flattened();
            let (flat0, flat1) = (grid0.as_flattened_mut(), grid1.as_flattened_mut());
            // Grid 0 has no shift: `q + 0.0` differs from `q` only for q = -0.0, which floors to the
            // same 0.
            let mut small = true;
            for ((v, i0), i1) in coordinates.iter().zip(flat0.iter_mut()).zip(flat1.iter_mut()) {
                let (q0, q1) = (v * inv_m, v * inv_m + 0.5);
                small &= (q0.abs() < FLOOR_SMALL) & (q1.abs() < FLOOR_SMALL);
                *i0 = floor_small(q0) as u32;
                *i1 = floor_small(q1) as u32;
            }
            if !small {
                // A coordinate millions of voxels out (or not a number): the general floor.
                for ((v, i0), i1) in coordinates.iter().zip(flat0.iter_mut()).zip(flat1.iter_mut()) {
                    *i0 = floor_i32(v * inv_m) as u32;
                    *i1 = floor_i32(v * inv_m + 0.5) as u32;
                }
            }
            // The products lane by lane, four points at a time (the primes repeat every three lanes):
            // vectorised, where three multiplications per voxel one after the other queue on the one
            // scalar multiplier.
            for lanes in flat0.chunks_exact_mut(12).chain(flat1.chunks_exact_mut(12)) {
                for (v, prime) in lanes.iter_mut().zip(AXIS_PRIMES.iter().cycle()) {
                    *v = v.wrapping_mul(*prime);
                }
            }
            slots.extend(
                grid0
                    .iter()
                    .zip(&grid1)
                    .take(chunk.len())
                    .map(|(a, b)| [voxel_slot(a), VOXEL_SLOTS as u32 + voxel_slot(b)]),
            );
        }
    }

    /// Drops from `points` every point whose voxels (side `voxel_m`) in both grids hold fewer than
    /// `min_points` points, when those are at least `min_share` of the points; keeps the order of the
    /// rest. Returns how many were dropped.
    fn retain_dense(
        &mut self,
        points: &mut Vec<[f32; 3]>,
        voxel_m: f32,
        min_points: usize,
        min_share: f32,
    ) -> usize {
        if min_points <= 1 || points.is_empty() {
            return 0;
        }
        self.slots.clear();
        Self::hash_points(points, 1.0 / voxel_m, &mut self.slots);
        // The mask keeps every slot inside the tables, so the indexing needs no bounds check.
        let slot = |s: u32| s as usize & (2 * VOXEL_SLOTS - 1);
        let counts = &mut self.counts;
        for_each_interleaved(&self.slots, |&[s0, s1]| {
            for s in [s0, s1] {
                let c = &mut counts[slot(s)];
                *c = c.saturating_add(1);
            }
        });
        let counts = &self.counts;
        let dense = |&[s0, s1]: &[u32; 2]| {
            usize::from(counts[slot(s0)]) >= min_points || usize::from(counts[slot(s1)]) >= min_points
        };
        let lone = self.slots.iter().filter(|s| !dense(s)).count();
        let dropped = if (lone as f32) < min_share * points.len() as f32 {
            0
        } else {
            // `retain` visits the points once each, in order: the slots are walked beside them.
            let mut slots = self.slots.iter();
            points.retain(|_| slots.next().is_some_and(dense));
            lone
        };
        for &s in self.slots.as_flattened() {
            self.counts[slot(s)] = 0;
        }
        dropped
    }
}

/// `base_link -> sensor` as f32 for the per-point loop.
#[derive(Debug, Clone, Copy)]
struct Frame {
    r: [[f32; 3]; 3],
    t: [f32; 3],
}

impl Frame {
    fn new(mount: &Mount) -> Self {
        let iso = mount.isometry();
        let m = iso.rotation.to_rotation_matrix();
        let mut r = [[0.0f32; 3]; 3];
        for (i, row) in r.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = m[(i, j)] as f32;
            }
        }
        let t = iso.translation.vector;
        Self { r, t: [t.x as f32, t.y as f32, t.z as f32] }
    }
}

/// Where the virtual ground plane goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PlaneRule {
    /// Through the centroid of the cropped points (paper eqs. 1-2).
    Centroid,
    /// Halfway between the 5th and 95th height percentiles of the cropped points, at least
    /// `min_plant_height_m` above the 5th.
    Percentile,
}

/// Buffers of the preprocessing step, allocated once.
#[derive(Debug, Clone)]
pub(crate) struct Preprocessor {
    /// Cropped points in `base_link`, m: ground and canopy.
    pub(crate) cropped: Vec<[f32; 3]>,
    /// Canopy points `(x, y, h)` in `base_link`, m, with `h` the height above the plane.
    pub(crate) canopy: Vec<[f32; 3]>,
    /// Height of the plane used on the last scan, m in `base_link`.
    pub(crate) plane_z_m: f32,
    /// The levelling stage and its estimate (default mode).
    pub(crate) level: Level,
    /// Sectors of the last scan with no return (default mode, `hold_scan_holes`).
    pub(crate) holes: Holes,
    z_hist: Vec<u32>,
    clutter: Clutter,
}

impl Preprocessor {
    pub(crate) fn new(capacity: usize, config: &DetectorConfig) -> Self {
        Self {
            cropped: Vec::with_capacity(capacity),
            canopy: Vec::with_capacity(capacity),
            plane_z_m: 0.0,
            level: Level::new(config),
            holes: Holes::default(),
            z_hist: vec![0; Z_BINS],
            clutter: Clutter::new(),
        }
    }

    /// Crops the scan's points, undoes their motion skew when `deskew` is given, clears them of clutter
    /// and levels them under the percentile rule, puts them upright by the scan's attitude, and splits
    /// off the canopy. Returns the number of finite points in the scan. Never allocates once the
    /// buffers have grown to the largest scan seen.
    pub(crate) fn run(
        &mut self,
        scan: &Scan<'_>,
        mount: &Mount,
        config: &DetectorConfig,
        rule: PlaneRule,
        deskew: Option<Deskew>,
    ) -> usize {
        let (t_s, points) = (scan.stamp_s, scan.points);
        self.cropped.clear();
        let f = Frame::new(mount);
        let (r_max2, r_min2) =
            ((config.range_m * config.range_m) as f32, (config.min_range_m * config.min_range_m) as f32);
        let tan_half = (config.fov_deg.to_radians() * 0.5).tan() as f32;
        let mut finite = 0usize;
        for p in points {
            if !p.is_finite() {
                continue;
            }
            finite += 1;
            let r2 = p.x * p.x + p.y * p.y + p.z * p.z;
            let in_range = !(r2 > r_max2 || r2 < r_min2);
            // The FOV is horizontal, about the sensor origin, in base_link's heading: with a tilted
            // sensor that is what "frontal 120°" means on the ground.
            let dx = f.r[0][0] * p.x + f.r[0][1] * p.y + f.r[0][2] * p.z;
            let dy = f.r[1][0] * p.x + f.r[1][1] * p.y + f.r[1][2] * p.z;
            let in_fov = !(dx <= 0.0 || dy.abs() > dx * tan_half);
            let z = f.r[2][0] * p.x + f.r[2][1] * p.y + f.r[2][2] * p.z + f.t[2];
            let b = [dx + f.t[0], dy + f.t[1], z];
            // Every finite return is pushed, and the length then keeps or drops it: returns near the
            // range's edge go in and out, and a branch on the crop mispredicted there.
            let kept = in_range & in_fov;
            let len = self.cropped.len();
            // Deskewed after the crop: only the kept returns pay for it, and the crop's edges move by
            // millimetres at most.
            self.cropped.push(match &deskew {
                Some(d) if kept => d.apply(p, b),
                _ => b,
            });
            self.cropped.truncate(len + usize::from(kept));
        }
        self.holes.begin(mount);
        if rule == PlaneRule::Percentile && config.hold_scan_holes {
            // A pass of its own: the crop's loop above stays branch-free.
            self.holes.count(points);
            self.holes.finish();
        }
        if rule == PlaneRule::Percentile {
            self.clutter.retain_dense(
                &mut self.cropped,
                config.clutter_voxel_m as f32,
                config.clutter_min_points,
                config.clutter_min_share as f32,
            );
            self.level_cropped(t_s, f.t, config);
        }
        if let Some(attitude) = scan.attitude {
            self.upright(&attitude);
        }
        if self.cropped.is_empty() {
            self.canopy.clear();
            self.plane_z_m = 0.0;
            return finite;
        }
        let (base, top) = match rule {
            PlaneRule::Centroid => {
                let z_sum: f64 = self.cropped.iter().map(|p| p[2] as f64).sum();
                ((z_sum / self.cropped.len() as f64) as f32, f32::INFINITY)
            }
            PlaneRule::Percentile => self.percentile_levels(config.min_plant_height_m as f32),
        };
        self.plane_z_m = base + config.plane_raise_m as f32;
        let plane = self.plane_z_m;
        self.holes.set_canopy(f64::from(plane), f64::from(top - ABOVE_TOP_M));
        // Every return is written to the next free slot and only a canopy return takes it: canopy and
        // ground returns alternate along the rings, and a branch on the side mispredicted at every
        // change. The slots left from the last scan are overwritten before they are read.
        self.canopy.resize(self.cropped.len(), [0.0; 3]);
        let mut n = 0;
        for p in &self.cropped {
            if let Some(slot) = self.canopy.get_mut(n) {
                *slot = [p[0], p[1], p[2] - plane];
            }
            n += usize::from(p[2] > plane && p[2] <= top);
        }
        self.canopy.truncate(n);
        finite
    }

    /// Updates the tilt estimate from this scan and rotates the cropped points about the sensor origin
    /// `o` (`base_link`, m) by the correction, when there is one.
    fn level_cropped(&mut self, t_s: f64, o: [f32; 3], config: &DetectorConfig) {
        let Some(q) = self.level.update(t_s, &self.cropped, o, config) else { return };
        let m = q.matrix();
        let mut r = [[0.0f32; 3]; 3];
        for (i, row) in r.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = m[(i, j)] as f32;
            }
        }
        for p in &mut self.cropped {
            let d = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
            for (out, row) in p.iter_mut().zip(&r) {
                *out = row[0] * d[0] + row[1] * d[1] + row[2] * d[2];
            }
            for (out, oi) in p.iter_mut().zip(&o) {
                *out += oi;
            }
        }
    }

    /// Moves each cropped point to where it stands over the ground as seen from gravity's vertical:
    /// its `x` and `y` are those of the point turned by the robot's roll and pitch about `base_link`'s
    /// origin, its height stays the one above the plane the robot stands on. A plant grows along
    /// gravity, so on a slope its canopy leans, in `base_link`, by its height times the roll; upright,
    /// the canopy stands over its stems again, while the canopy plane and the levelling keep the
    /// heights they were made for (the ground in view tilts with the robot).
    fn upright(&mut self, attitude: &Attitude) {
        let m = Rotation3::from_euler_angles(attitude.roll_rad, attitude.pitch_rad, 0.0);
        let r = |i: usize, j: usize| m[(i, j)] as f32;
        let (rx, ry) = ([r(0, 0), r(0, 1), r(0, 2)], [r(1, 0), r(1, 1), r(1, 2)]);
        for p in &mut self.cropped {
            let [x, y, z] = *p;
            *p = [rx[0] * x + rx[1] * y + rx[2] * z, ry[0] * x + ry[1] * y + ry[2] * z, z];
        }
    }

    /// The canopy plane (halfway between the 5th and 95th height percentiles, at least `min_height_m`
    /// above the 5th) and the highest canopy return believed ([`ABOVE_TOP_M`] over the 95th).
    fn percentile_levels(&mut self, min_height_m: f32) -> (f32, f32) {
        self.z_hist.iter_mut().for_each(|c| *c = 0);
        let hist = &mut self.z_hist;
        for_each_interleaved(&self.cropped, |p| {
            // Clamped to the bins (or NaN, cast to 0): there `as u32` is `as usize` in a third of the
            // instructions (x86 has no unsigned 64-bit conversion).
            let i = ((p[2] - Z_MIN_M) / Z_BIN_M).clamp(0.0, (Z_BINS - 1) as f32) as u32 as usize;
            if let Some(c) = hist.get_mut(i) {
                *c += 1;
            }
        });
        let n = self.cropped.len() as u64;
        let (lo, hi) = (quantile_bin(&self.z_hist, n, 5), quantile_bin(&self.z_hist, n, 95));
        let ground = Z_MIN_M + Z_BIN_M * (lo as f32 + 0.5);
        let top = Z_MIN_M + Z_BIN_M * (hi as f32 + 1.0) + ABOVE_TOP_M;
        ((Z_MIN_M + Z_BIN_M * (lo + hi + 1) as f32 * 0.5).max(ground + min_height_m), top)
    }
}

/// The bin holding the `pct`-th percentile of a histogram with `n` entries.
fn quantile_bin(hist: &[u32], n: u64, pct: u64) -> usize {
    let target = (n * pct).div_ceil(100).max(1);
    let mut acc = 0u64;
    for (i, &c) in hist.iter().enumerate() {
        acc += c as u64;
        if acc >= target {
            return i;
        }
    }
    hist.len().saturating_sub(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point3;

    /// A scan at t = 0 of a level robot, for the preprocessing alone.
    fn level(points: &[Point3]) -> Scan<'_> {
        Scan { stamp_s: 0.0, points, twist: None, attitude: None }
    }

    fn sensor_point(mount: &Mount, base: [f64; 3]) -> Point3 {
        let p = mount.isometry().inverse_transform_point(&nalgebra::Point3::new(base[0], base[1], base[2]));
        Point3::new(p.x as f32, p.y as f32, p.z as f32)
    }

    #[test]
    fn crops_fov_and_range_and_keeps_points_above_the_centroid() {
        let mount = Mount::default();
        let cfg = DetectorConfig::paper();
        let pts = [
            sensor_point(&mount, [2.5, 0.0, 0.0]), // ground ahead: kept, below the plane
            sensor_point(&mount, [2.5, 0.4, 0.5]), // plant top ahead: canopy
            sensor_point(&mount, [2.5, 5.0, 0.0]), // out of range
            sensor_point(&mount, [0.7, 1.5, 0.0]), // ahead of the sensor by 0.1 m but 86° aside: out of FOV
            sensor_point(&mount, [-1.0, 0.0, 0.0]), // behind the sensor
            Point3::new(f32::NAN, 0.0, 0.0),
        ];
        let mut pre = Preprocessor::new(8, &cfg);
        let finite = pre.run(&level(&pts), &mount, &cfg, PlaneRule::Centroid, None);
        assert_eq!(finite, 5);
        assert_eq!(pre.cropped.len(), 2);
        assert!((pre.plane_z_m - 0.25).abs() < 1e-4, "{}", pre.plane_z_m);
        assert_eq!(pre.canopy.len(), 1);
        assert!((pre.canopy[0][0] - 2.5).abs() < 1e-4 && (pre.canopy[0][1] - 0.4).abs() < 1e-4);
    }

    /// 100 returns in `base_link`: 90 on the ground along x from 2 m, 1 cm apart (as dense as a ring
    /// 4 m away), and a plant top of 10 returns at 0.4 m, 5 mm apart.
    fn ground_with_plant_tops(mount: &Mount) -> Vec<Point3> {
        let ground = (0..90).map(|i| sensor_point(mount, [2.0 + 0.01 * i as f64, 0.0, 0.0]));
        let top = (0..10).map(|i| sensor_point(mount, [2.52 + 0.005 * i as f64, 0.0, 0.4]));
        ground.chain(top).collect()
    }

    #[test]
    fn a_rolled_robot_sees_a_canopy_over_its_stems_once_upright() {
        // The robot stands on ground sloping up to its left by 2°. A plant 1 m tall grows straight up
        // from the ground 0.5 m to the left: in base_link, whose z is square to the slope, its top
        // leans uphill by 1·sin 2° = 3.5 cm.
        let roll: f64 = 2f64.to_radians();
        let up_in_body =
            nalgebra::Rotation3::from_euler_angles(roll, 0.0, 0.0).inverse() * nalgebra::Vector3::z();
        let mount = Mount::default();
        let cfg = DetectorConfig::default();
        let mut pts = Vec::new();
        for i in 0..60 {
            let x = 2.0 + 0.02 * i as f64;
            let top = nalgebra::Vector3::new(x, 0.5, 0.0) + up_in_body;
            pts.push(sensor_point(&mount, [x, 0.0, 0.0]));
            pts.push(sensor_point(&mount, [top.x, top.y, top.z]));
        }
        let canopy_y = |attitude: Option<Attitude>| {
            let mut pre = Preprocessor::new(128, &cfg);
            let scan = Scan { stamp_s: 0.0, points: &pts, twist: None, attitude };
            pre.run(&scan, &mount, &cfg, PlaneRule::Percentile, None);
            assert_eq!(pre.canopy.len(), 60);
            pre.canopy.iter().map(|p| p[1] as f64).sum::<f64>() / 60.0
        };
        let leaning = canopy_y(None);
        assert!((leaning - (0.5 + roll.sin())).abs() < 0.001, "{leaning}");
        let upright = canopy_y(Some(Attitude { roll_rad: roll, pitch_rad: 0.0 }));
        // Over the stem, 0.5·cos 2° m across the level ground.
        assert!((upright - 0.5 * roll.cos()).abs() < 0.001, "{upright}");
    }

    #[test]
    fn percentile_plane_ignores_a_ground_majority() {
        let mount = Mount::default();
        let cfg = DetectorConfig::default();
        // 90 ground points and 10 canopy points at 0.4 m: the centroid (0.04 m) would let ground noise
        // through; the percentile rule puts the plane near 0.2 m.
        let pts = ground_with_plant_tops(&mount);
        let mut pre = Preprocessor::new(8, &cfg);
        pre.run(&level(&pts), &mount, &cfg, PlaneRule::Percentile, None);
        assert!((pre.plane_z_m - 0.2).abs() < 0.02, "{}", pre.plane_z_m);
        assert_eq!(pre.canopy.len(), 10);
    }

    #[test]
    fn returns_floating_above_the_canopy_are_not_canopy() {
        // 90 ground points, 10 plant tops at 0.4 m and one return at 1.2 m (0.8 m above the 95th
        // percentile, over the 0.5 m allowed): the plant tops stay, the floating return goes. The
        // clutter test is off: it alone would take the lone return.
        let mount = Mount::default();
        let cfg = DetectorConfig { clutter_min_points: 0, ..DetectorConfig::default() };
        let mut pts = ground_with_plant_tops(&mount);
        pts.push(sensor_point(&mount, [2.5, 0.2, 1.2]));
        let mut pre = Preprocessor::new(8, &cfg);
        pre.run(&level(&pts), &mount, &cfg, PlaneRule::Percentile, None);
        assert_eq!(pre.canopy.len(), 10);
        assert!(pre.canopy.iter().all(|p| p[2] < 0.3), "{:?}", pre.canopy);
    }

    /// `n` returns alone in their voxels, 0.8-1.4 m above the ground 1.5-3 m ahead (dust, insects).
    fn dust(mount: &Mount, n: usize) -> impl Iterator<Item = Point3> + '_ {
        (0..n).map(move |k| {
            let f = k as f64 / n as f64;
            sensor_point(mount, [1.5 + 1.5 * f, -1.0 + 2.0 * f, 0.8 + 0.6 * ((7.0 * f) % 1.0)])
        })
    }

    #[test]
    fn lone_returns_in_the_air_do_not_lift_the_plane_off_a_young_crop() {
        // The fixture plus 12 returns of dust (11 % of the scan, more than the 5 % above the 95th
        // percentile): with every return kept the percentile lands in the dust and the plane rises over
        // the plant tops (soak seeds 148, 307); the clutter test drops the dust and the plane stays
        // halfway to the tops (±2 cm, the histogram's bins).
        let mount = Mount::default();
        let pts: Vec<Point3> = ground_with_plant_tops(&mount).into_iter().chain(dust(&mount, 12)).collect();
        let kept = DetectorConfig { clutter_min_points: 0, ..DetectorConfig::default() };
        let mut pre = Preprocessor::new(8, &kept);
        pre.run(&level(&pts), &mount, &kept, PlaneRule::Percentile, None);
        assert!(pre.plane_z_m > 0.4, "the dust no longer lifts the plane: {}", pre.plane_z_m);
        let cfg = DetectorConfig::default();
        let mut pre = Preprocessor::new(8, &cfg);
        pre.run(&level(&pts), &mount, &cfg, PlaneRule::Percentile, None);
        assert_eq!(pre.cropped.len(), 100);
        assert!((pre.plane_z_m - 0.2).abs() < 0.02, "{}", pre.plane_z_m);
        assert_eq!(pre.canopy.len(), 10);
    }

    #[test]
    fn a_surface_on_a_voxel_face_is_kept_whole() {
        // 200 ground returns 1.4 cm apart (a ring 4 m away) an eighth 3 mm above z = 0 and the rest 3 mm below, across a face of the
        // first grid's voxels: none may be dropped as clutter.
        let cfg = DetectorConfig::default();
        let mut points: Vec<[f32; 3]> = (0..200)
            .map(|i| [2.0 + 0.014 * i as f32, 0.3, if i % 8 == 0 { 0.003 } else { -0.003 }])
            .collect();
        let mut clutter = Clutter::new();
        // Every lone return counts: the share test would otherwise keep a thinned face.
        clutter.retain_dense(&mut points, cfg.clutter_voxel_m as f32, cfg.clutter_min_points, 0.0);
        assert_eq!(points.len(), 200);
    }

    #[test]
    fn the_count_tables_are_clear_after_every_scan() {
        // Each scan clears only the slots it counted in: the tables must end all zero, whether the
        // returns were kept (share test) or thinned, so that the next scan counts from zero.
        let mount = Mount::default();
        let cfg = DetectorConfig::default();
        let base: Vec<[f32; 3]> = ground_with_plant_tops(&mount)
            .into_iter()
            .chain(dust(&mount, 12))
            .map(|p| {
                let b = mount
                    .isometry()
                    .transform_point(&nalgebra::Point3::new(p.x as f64, p.y as f64, p.z as f64));
                [b.x as f32, b.y as f32, b.z as f32]
            })
            .collect();
        let mut clutter = Clutter::new();
        for min_share in [0.5, 0.0] {
            let mut points = base.clone();
            clutter.retain_dense(&mut points, cfg.clutter_voxel_m as f32, cfg.clutter_min_points, min_share);
            assert!(clutter.counts.iter().all(|&c| c == 0));
        }
    }

    #[test]
    fn chunked_hashing_gives_each_point_its_voxels() {
        // Every point's slots as the per-point floors give them, in chunks with and without a
        // coordinate too far out for the fast floor (1e7 voxels), and across a partial last chunk.
        let inv = 1.0 / 0.2;
        let reference = |p: &[f32; 3]| {
            let slot = |shift: f32| {
                let [i, j, k] = p.map(|v| floor_i32(v * inv + shift) as u32);
                let [a, b, c] = AXIS_PRIMES;
                (i.wrapping_mul(a) ^ j.wrapping_mul(b) ^ k.wrapping_mul(c)) & (VOXEL_SLOTS as u32 - 1)
            };
            [slot(0.0), VOXEL_SLOTS as u32 + slot(0.5)]
        };
        let mut points: Vec<[f32; 3]> = (0..150)
            .map(|i| {
                let f = i as f32;
                [0.37 * f - 20.0, (0.11 * f).sin() * 3.0, if i % 3 == 0 { -0.0 } else { 0.013 * f - 1.0 }]
            })
            .collect();
        if let Some(p) = points.get_mut(70) {
            *p = [2.0e6, -1.0, 0.5];
        }
        let mut slots = Vec::new();
        Clutter::hash_points(&points, inv, &mut slots);
        assert_eq!(slots, points.iter().map(reference).collect::<Vec<_>>());
    }

    #[test]
    fn floor_i32_is_floor_then_cast() {
        for x in [-3.0e9_f32, -2.5, -2.0, -1.5, -0.0, 0.0, 0.3, 1.0, 1.7, 2.0e9, 3.0e9, f32::NAN] {
            assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
        }
    }

    #[test]
    fn floor_small_is_floor_i32_below_its_bound() {
        // Integers, the floats either side of them and of the half-integers, ±0, and the bound's edge.
        let mut xs = vec![-0.0f32, 0.0, FLOOR_SMALL.next_down(), -FLOOR_SMALL.next_down()];
        for k in -300..300 {
            for base in [k as f32, k as f32 + 0.5, k as f32 * 9_973.25, k as f32 * 13_981.0] {
                xs.extend([base, base.next_up(), base.next_down()]);
            }
        }
        for x in xs.into_iter().filter(|x| x.abs() < FLOOR_SMALL) {
            assert_eq!(floor_small(x), floor_i32(x), "{x}");
        }
    }

    #[test]
    fn a_few_lone_returns_are_kept() {
        // The fixture plus 2 lone returns (2 % of the scan, under the 3 % share): a young crop's
        // sparse leaf edges, not dust; every return stays.
        let mount = Mount::default();
        let pts: Vec<Point3> = ground_with_plant_tops(&mount).into_iter().chain(dust(&mount, 2)).collect();
        let cfg = DetectorConfig::default();
        let mut pre = Preprocessor::new(8, &cfg);
        pre.run(&level(&pts), &mount, &cfg, PlaneRule::Percentile, None);
        assert_eq!(pre.cropped.len(), 102);
    }
}
