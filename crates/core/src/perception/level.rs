//! Self-levelling (default mode): the tilt of the surface below the sensor, measured from each scan,
//! so that a LiDAR knocked a few degrees off its configured mount still sees a level ground.
//!
//! It sits inside preprocessing, between the crop into `base_link` (with the CONFIGURED mount) and
//! the virtual ground plane. A pitch error of 3° moves the ground 26 cm at 5 m: past a row end the bare
//! ground then rises into the canopy band ("phantom rows"), and a roll error lifts one side's canopy
//! and lowers the other's. `base_link` stands on the ground, so the ground (or, in a closed canopy, the
//! canopy top, parallel to it) is level in `base_link` up to terrain relief; whatever tilt the scan
//! shows is the mount's.
//!
//! Per scan: the cropped points are binned in `level_cell_m` cells around the sensor; a cell's height
//! is its [`LOW_RANK`]-th lowest return (ground between the rows, or the canopy top where none shows
//! through). A plane `z = c + a·x + b·y` is fitted to those cell heights: the best of a few seeded
//! RANSAC hypotheses (so that a closed canopy ending at a headland, half canopy top and half ground,
//! locks onto one surface rather than bridging them), refined by Tukey-weighted least squares. A fit
//! with fewer than `level_min_cells` inlier cells, or too little spread in x or y to fix both slopes,
//! is refused and the previous estimate is held. The slopes become a roll and pitch, clamped to
//! `level_max_tilt_deg` and low-passed with `level_time_constant_s` (a knocked mount is followed
//! within about three time constants; a single noisy scan, the robot's own pitching or a 0.2 m bump
//! moves it little). The cropped points are then rotated about the sensor origin by the inverse of
//! that tilt: a mount error is a rotation of the sensor about its own origin, so this also removes the
//! sideways shift a roll error gives the canopy. Yaw errors are invisible to a ground plane and stay.
//!
//! The paper mode stays unlevelled (its Table I yardstick is the paper's method as published).

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

use super::config::{DetectorConfig, DetectorMode};
use super::rng::Rng;

/// A cell's height is its `LOW_RANK`-th lowest return (1-based): the lowest one or two can be noise
/// below the ground, and cells with fewer returns are not used.
const LOW_RANK: usize = 3;
/// Seeded RANSAC hypotheses per scan (three cells each).
const RANSAC_ITERATIONS: usize = 48;
/// A cell is an inlier of a plane when its height lies within this of it, m: ground noise and the
/// few centimetres of soil roughness, well under a young crop's 10-20 cm.
const INLIER_M: f64 = 0.04;
/// Tukey biweight cut-off of the refinement, m: cells further off the plane get no weight.
const TUKEY_M: f64 = 0.08;
/// Weighted least-squares passes of the refinement.
const REFINE_PASSES: usize = 4;
/// Smallest share of the cells that must lie on the fitted surface. A ground or a closed canopy top
/// holds most cells; a tall crop whose low returns are leaves at every height (grown corn from inside
/// the rows) fits no plane, and a fit through a fifth of its cells tilted the scan by ±1° from one
/// scan to the next (soak seed 726, which then never acquired its lane).
const MIN_INLIER_SHARE: f64 = 0.5;
/// Fewest standard deviation of the inlier cells along x and along y, m, for both slopes to be fixed.
const MIN_SPREAD_M: f64 = 0.4;
/// One scan never weighs more in the low-pass than this much time of scans, s: after a long hold
/// (refused fits) a single fit does not replace the estimate outright.
const MAX_STEP_S: f64 = 0.2;
/// Seed of the RANSAC sampler (any constant: the same scan always gives the same fit).
const SEED: u64 = 0x6C65_7665_6C00_0001;

/// What the levelling did on the last scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum LevelStatus {
    /// Levelling is off (`detector.level_enabled = false`, or the paper mode).
    Off,
    /// No scan has given a fit yet: the points are used as the configured mount gives them.
    NoEstimate,
    /// This scan's fit updated the estimate, and the points were levelled by it.
    Measured,
    /// This scan's fit was refused (too few cells on one surface, or too little spread); the previous
    /// estimate levelled the points.
    Held,
}

impl LevelStatus {
    /// Stable lower-case name, as written in logs and JSON lines.
    pub fn as_str(&self) -> &'static str {
        match self {
            LevelStatus::Off => "off",
            LevelStatus::NoEstimate => "no_estimate",
            LevelStatus::Measured => "measured",
            LevelStatus::Held => "held",
        }
    }
}

/// The tilt of the surface below the sensor as the CONFIGURED mount shows it, in `base_link`, rad
/// (REP-103: roll about x, positive lifts the left side; pitch about y, positive dips the front).
/// A LiDAR pitched δ further nose-down than its configured mount sees the ground pitched −δ; one
/// rolled δ further sees it rolled −δ. Both 0 until a fit is made, and while levelling is off.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Tilt {
    /// Roll of the surface, rad.
    pub roll_rad: f64,
    /// Pitch of the surface, rad.
    pub pitch_rad: f64,
    /// What the last scan did to the estimate.
    pub status: LevelStatus,
    /// Cells of the last scan on the fitted surface (0 when no fit was tried).
    pub support: usize,
}

/// One grid cell: the lowest [`LOW_RANK`] of the returns that fell in it, by height, lowest first.
/// The places not yet filled hold an infinite height, so the cell holds `LOW_RANK` returns once its
/// last height is finite: no count to raise per return, whose stores and reloads chained the returns
/// of a cell one after the other.
#[derive(Debug, Clone, Copy)]
struct Cell {
    low: [[f32; 3]; LOW_RANK],
}

impl Default for Cell {
    fn default() -> Self {
        Self { low: [[0.0, 0.0, f32::INFINITY]; LOW_RANK] }
    }
}

impl Cell {
    /// The cell's height, its [`LOW_RANK`]-th lowest return, once it holds that many.
    fn height_return(&self) -> Option<&[f32; 3]> {
        self.low.last().filter(|q| q[2] < f32::INFINITY)
    }

    /// Adds the finite return `p`: it goes after every entry as low as it or lower, the entries above
    /// it move up by one and the highest drops out.
    fn insert(&mut self, p: [f32; 3]) {
        // Most returns of a full cell lie above its lowest few: nothing to move (a cell not yet full
        // has an infinite last height).
        if self.low.last().is_some_and(|q| q[2] <= p[2]) {
            return;
        }
        // Each place takes the entry below it, `p` or its own entry, chosen by comparisons rather than
        // found by a search: a cell's returns come in no order of height, and the search's branches
        // mispredicted. Empty places are infinitely high, so `p` fills the first of them.
        let old = self.low;
        let mut after_p = false;
        let mut below = p;
        for (slot, q) in self.low.iter_mut().zip(old) {
            let p_before_q = p[2] < q[2];
            *slot = if after_p {
                below
            } else if p_before_q {
                p
            } else {
                q
            };
            after_p = p_before_q;
            below = q;
        }
    }
}

/// A plane `z = c + a·x + b·y` in sensor-centred `base_link` axes, m.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Plane {
    a: f64,
    b: f64,
    c: f64,
}

impl Plane {
    fn residual(&self, s: &[f64; 3]) -> f64 {
        s[2] - self.c - self.a * s[0] - self.b * s[1]
    }
}

/// The levelling stage: the cell grid and fit buffers (allocated once, for the configured range and
/// cell size) and the filtered estimate, which survives [`RowDetector::reset`](super::RowDetector::reset)
/// (it belongs to the mount, not to a lane).
#[derive(Debug, Clone)]
pub(crate) struct Level {
    cells: Vec<Cell>,
    nx: usize,
    ny: usize,
    cell_m: f64,
    half_width_m: f64,
    /// Cell heights `(x, y, z)` relative to the sensor origin (x, y) and `base_link` (z), m.
    samples: Vec<[f64; 3]>,
    /// The scan's finite cropped points relative to the sensor origin (x, y) and `base_link` (z), m:
    /// converted once for the four refit passes, in the binning pass, which computes them anyway (a
    /// refused fit pays only their stores).
    relative: Columns,
    /// A refit pass's Tukey weight of each of `relative`, and the indices of those with a weight.
    weights: Vec<f64>,
    weighted: Vec<usize>,
    residuals: Vec<f64>,
    rng: Rng,
    /// Filtered (roll, pitch), rad, and the stamp of the last fit that updated it, s.
    estimate: Option<(f64, f64)>,
    last_fit_s: Option<f64>,
    status: LevelStatus,
    support: usize,
}

impl Level {
    pub(crate) fn new(config: &DetectorConfig) -> Self {
        let cell_m = config.level_cell_m;
        // The crop keeps points within range_m of the sensor and ahead of it.
        let nx = (config.range_m / cell_m).ceil().max(1.0) as usize;
        let ny = 2 * nx;
        Self {
            cells: vec![Cell::default(); nx * ny],
            nx,
            ny,
            cell_m,
            half_width_m: nx as f64 * cell_m,
            samples: Vec::with_capacity(nx * ny),
            relative: Columns::default(),
            weights: Vec::new(),
            weighted: Vec::new(),
            residuals: Vec::with_capacity(nx * ny),
            rng: Rng::new(SEED),
            estimate: None,
            last_fit_s: None,
            status: if config.level_enabled && config.mode == DetectorMode::Default {
                LevelStatus::NoEstimate
            } else {
                LevelStatus::Off
            },
            support: 0,
        }
    }

    /// The estimate after the last scan.
    pub(crate) fn tilt(&self) -> Tilt {
        let (roll_rad, pitch_rad) = self.estimate.unwrap_or((0.0, 0.0));
        Tilt { roll_rad, pitch_rad, status: self.status, support: self.support }
    }

    /// Measures this scan's tilt from `cropped` (`base_link`, m; the sensor origin at `origin`) and
    /// returns the rotation that levels the points about the sensor origin, or `None` when there is no
    /// estimate (or levelling is off).
    pub(crate) fn update(
        &mut self,
        t_s: f64,
        cropped: &[[f32; 3]],
        origin: [f32; 3],
        config: &DetectorConfig,
    ) -> Option<Rotation3<f64>> {
        self.support = 0;
        if !config.level_enabled {
            self.status = LevelStatus::Off;
            return None;
        }
        self.fill_samples(cropped, origin);
        let bound = config.level_max_tilt_deg.to_radians();
        match self.fit(config.level_min_cells, bound) {
            Some((roll, pitch)) => {
                let raw = (roll.clamp(-bound, bound), pitch.clamp(-bound, bound));
                let next = match (self.estimate, self.last_fit_s) {
                    (Some((r0, p0)), Some(t0)) => {
                        let dt = (t_s - t0).clamp(0.0, MAX_STEP_S);
                        let alpha = 1.0 - (-dt / config.level_time_constant_s).exp();
                        (r0 + alpha * (raw.0 - r0), p0 + alpha * (raw.1 - p0))
                    }
                    _ => raw,
                };
                self.estimate = Some(next);
                self.last_fit_s = Some(t_s);
                self.status = LevelStatus::Measured;
            }
            None => {
                self.status =
                    if self.estimate.is_some() { LevelStatus::Held } else { LevelStatus::NoEstimate };
            }
        }
        let (roll, pitch) = self.estimate?;
        // The surface's orientation is Ry(pitch)·Rx(roll); levelling undoes it.
        Some(Rotation3::from_euler_angles(roll, pitch, 0.0).transpose())
    }

    /// Bins the cropped points around the sensor and keeps each full cell's height, and keeps the
    /// finite points relative to the sensor for the refit (`relative`).
    fn fill_samples(&mut self, cropped: &[[f32; 3]], origin: [f32; 3]) {
        self.cells.iter_mut().for_each(|c| *c = Cell::default());
        let inv = 1.0 / self.cell_m;
        // Written slot by slot and cut to the count at the end (the slots left from the last scan are
        // overwritten first): no push's capacity check per column and point.
        let Columns { x: xs, y: ys, z: zs } = &mut self.relative;
        for column in [&mut *xs, &mut *ys, &mut *zs] {
            column.resize(cropped.len(), 0.0);
        }
        // Locals, so that the loop keeps them in registers rather than reloading them through `self`
        // after every store.
        let (xs, ys, zs) = (&mut xs[..], &mut ys[..], &mut zs[..]);
        let (cells, nx, ny, half_width_m) = (&mut self.cells[..], self.nx, self.ny, self.half_width_m);
        let mut finite = 0;
        for p in cropped {
            if !p.iter().all(|v| v.is_finite()) {
                continue;
            }
            let (dx, rel_y) = ((p[0] - origin[0]) as f64, (p[1] - origin[1]) as f64);
            if let (Some(x), Some(y), Some(z)) = (xs.get_mut(finite), ys.get_mut(finite), zs.get_mut(finite))
            {
                (*x, *y, *z) = (dx, rel_y, p[2] as f64);
            }
            finite += 1;
            let dy = rel_y + half_width_m;
            if dx < 0.0 || dy < 0.0 {
                continue;
            }
            // `as i64` is one instruction where `as usize` is a dozen (x86 has no unsigned 64-bit
            // conversion); both are ≥ 0 here and saturate far beyond the grid, so the same cells.
            let (ix, iy) = ((dx * inv) as i64, (dy * inv) as i64);
            if ix < nx as i64
                && iy < ny as i64
                && let Some(c) = cells.get_mut(iy as usize * nx + ix as usize)
            {
                c.insert([p[0] - origin[0], p[1] - origin[1], p[2]]);
            }
        }
        let Columns { x: xs, y: ys, z: zs } = &mut self.relative;
        for column in [xs, ys, zs] {
            column.truncate(finite);
        }
        self.samples.clear();
        for p in self.cells.iter().filter_map(Cell::height_return) {
            self.samples.push([p[0] as f64, p[1] as f64, p[2] as f64]);
        }
    }

    /// The robust plane of the cell heights as (roll, pitch), rad, or `None` when refused.
    fn fit(&mut self, min_cells: usize, bound_rad: f64) -> Option<(f64, f64)> {
        let n = self.samples.len();
        if n < min_cells.max(3) {
            return None;
        }
        // Hypotheses steeper than twice the bound are wild triangles, not a tilt worth clamping.
        let max_slope = (2.0 * bound_rad).min(1.0).tan();
        let mut best: Option<(usize, Plane)> = None;
        if let Some(prior) = self.prior_plane() {
            best = Some((self.inliers(&prior), prior));
        }
        for _ in 0..RANSAC_ITERATIONS {
            let (i, j, k) = (self.rng.below(n), self.rng.below(n), self.rng.below(n));
            let (Some(p), Some(q), Some(r)) = (self.samples.get(i), self.samples.get(j), self.samples.get(k))
            else {
                continue;
            };
            let Some(plane) = plane_through(p, q, r) else { continue };
            if plane.a.abs() > max_slope || plane.b.abs() > max_slope {
                continue;
            }
            let count = self.inliers(&plane);
            if best.is_none_or(|(c, _)| count > c) {
                best = Some((count, plane));
            }
        }
        let (_, mut plane) = best?;
        for _ in 0..REFINE_PASSES {
            plane = refine(&plane, self.samples.iter().copied())?;
        }
        let (count, sx, sy) = self.inlier_spread(&plane);
        self.support = count;
        if count < min_cells
            || (count as f64) < MIN_INLIER_SHARE * n as f64
            || sx < MIN_SPREAD_M
            || sy < MIN_SPREAD_M
        {
            return None;
        }
        // A cell's low return sits lower the more returns the cell holds (the minimum of more range
        // noise), so near cells read lower than far ones: a bias of 0.4° nose-up on a level simulated
        // field. The returns themselves scatter evenly about the surface: refit them.
        // Every return, not a subsample: refitting an even subsample of 2048 returns in 2 passes moved
        // Table I's grown-soybean following from 1.07 to 1.38 cm.
        for _ in 0..REFINE_PASSES {
            plane = self.refine_returns(&plane)?;
        }
        let pitch = -plane.a.atan();
        let roll = plane.b.atan2((1.0 + plane.a * plane.a).sqrt());
        (roll.is_finite() && pitch.is_finite()).then_some((roll, pitch))
    }

    /// The current estimate as a plane through the median cell height (a hypothesis that keeps the
    /// fit on the surface it followed when two compete).
    fn prior_plane(&mut self) -> Option<Plane> {
        let (roll, pitch) = self.estimate?;
        let (a, b) = (-pitch.tan(), roll.tan() * (1.0 + pitch.tan().powi(2)).sqrt());
        self.residuals.clear();
        self.residuals.extend(self.samples.iter().map(|s| s[2] - a * s[0] - b * s[1]));
        let mid = self.residuals.len() / 2;
        let (_, &mut c, _) = self.residuals.select_nth_unstable_by(mid, f64::total_cmp);
        Some(Plane { a, b, c })
    }

    /// [`refine`] over the scan's returns (`relative`), the same sums in the same order, in three
    /// loops: every return's weight (no branch, two returns per instruction), the indices of the
    /// returns with a weight (no branch either), and their sums. A loop that skipped the returns past
    /// the cut-off as it summed would mispredict at every change of side along the rings, a thousand
    /// times a pass.
    fn refine_returns(&mut self, plane: &Plane) -> Option<Plane> {
        let Columns { x, y, z } = &self.relative;
        let len = x.len().min(y.len()).min(z.len());
        self.weights.resize(len, 0.0);
        self.weighted.resize(len, 0);
        let (weights, weighted) = (&mut self.weights[..], &mut self.weighted[..]);
        for (((w, &x), &y), &z) in weights.iter_mut().zip(x).zip(y).zip(z) {
            *w = tukey_weight(plane.residual(&[x, y, z]));
        }
        let mut n = 0;
        for (i, &w) in weights.iter().enumerate() {
            if let Some(slot) = weighted.get_mut(n) {
                *slot = i;
            }
            n += usize::from(w != 0.0);
        }
        let mut sums = NormalSums::default();
        let (x, y, z) = (&x[..len], &y[..len], &z[..len]);
        for &i in weighted.iter().take(n) {
            if let (Some(&w), Some(&x), Some(&y), Some(&z)) = (weights.get(i), x.get(i), y.get(i), z.get(i)) {
                sums.add(w, &[x, y, z]);
            }
        }
        sums.solve()
    }

    fn inliers(&self, plane: &Plane) -> usize {
        self.samples.iter().filter(|s| plane.residual(s).abs() < INLIER_M).count()
    }

    /// Inlier count and the standard deviations of the inliers' x and y, m.
    fn inlier_spread(&self, plane: &Plane) -> (usize, f64, f64) {
        let (mut n, mut sx, mut sy, mut sxx, mut syy) = (0usize, 0.0, 0.0, 0.0, 0.0);
        for s in self.samples.iter().filter(|s| plane.residual(s).abs() < INLIER_M) {
            n += 1;
            sx += s[0];
            sy += s[1];
            sxx += s[0] * s[0];
            syy += s[1] * s[1];
        }
        if n == 0 {
            return (0, 0.0, 0.0);
        }
        let k = n as f64;
        let var = |sq: f64, s: f64| (sq / k - (s / k).powi(2)).max(0.0).sqrt();
        (n, var(sxx, sx), var(syy, sy))
    }
}

/// Points as one column per axis, m: a loop over them reads each axis contiguously, two points per
/// instruction.
#[derive(Debug, Clone, Default)]
struct Columns {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
}

/// Tukey biweight of a point `residual` m off the plane: 0 at and past the cut-off, and only there
/// (inside it 1 − u² ≥ 2⁻⁵³, whose square is far from underflow); NaN for a NaN residual, which is
/// not cut off.
fn tukey_weight(residual: f64) -> f64 {
    let u = residual / TUKEY_M;
    if u.abs() >= 1.0 { 0.0 } else { (1.0 - u * u) * (1.0 - u * u) }
}

/// The weighted least-squares normal equations of a plane `z = c + a·x + b·y`: the six distinct sums
/// of the symmetric matrix and the three of the right-hand side, accumulated by hand (hot loop).
#[derive(Debug, Clone, Copy, Default)]
struct NormalSums {
    sw: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
    sz: f64,
    sxz: f64,
    syz: f64,
}

impl NormalSums {
    fn add(&mut self, w: f64, s: &[f64; 3]) {
        let (wx, wy) = (w * s[0], w * s[1]);
        self.sw += w;
        self.sx += wx;
        self.sy += wy;
        self.sxx += wx * s[0];
        self.sxy += wx * s[1];
        self.syy += wy * s[1];
        self.sz += w * s[2];
        self.sxz += wx * s[2];
        self.syz += wy * s[2];
    }

    /// The plane, `None` when the sums do not fix one.
    fn solve(&self) -> Option<Plane> {
        let m =
            Matrix3::new(self.sw, self.sx, self.sy, self.sx, self.sxx, self.sxy, self.sy, self.sxy, self.syy);
        let p = m.cholesky()?.solve(&Vector3::new(self.sz, self.sxz, self.syz));
        let plane = Plane { c: p.x, a: p.y, b: p.z };
        [plane.a, plane.b, plane.c].iter().all(|v| v.is_finite()).then_some(plane)
    }
}

/// One Tukey-weighted least-squares pass of `samples` (x, y, z, m) from `plane`; `None` when too few
/// lie near it to fix a plane.
fn refine(plane: &Plane, samples: impl Iterator<Item = [f64; 3]>) -> Option<Plane> {
    let mut sums = NormalSums::default();
    for s in samples {
        let w = tukey_weight(plane.residual(&s));
        if w != 0.0 {
            sums.add(w, &s);
        }
    }
    sums.solve()
}

/// The plane through three cell heights, `None` when they are (nearly) collinear in x-y.
fn plane_through(p: &[f64; 3], q: &[f64; 3], r: &[f64; 3]) -> Option<Plane> {
    let (ux, uy, uz) = (q[0] - p[0], q[1] - p[1], q[2] - p[2]);
    let (vx, vy, vz) = (r[0] - p[0], r[1] - p[1], r[2] - p[2]);
    let det = ux * vy - uy * vx;
    // Cells at least a cell apart span at least ~0.25 m²; smaller triangles give wild slopes.
    if det.abs() < 0.05 {
        return None;
    }
    let a = (uz * vy - uy * vz) / det;
    let b = (ux * vz - uz * vx) / det;
    Some(Plane { a, b, c: p[2] - a * p[0] - b * p[1] })
}

#[cfg(test)]
mod tests {
    use super::*;

    const ORIGIN: [f32; 3] = [0.6, 0.0, 1.5];

    fn config() -> DetectorConfig {
        DetectorConfig::default()
    }

    /// Points on a grid ahead of the sensor (x 0.8-4.5 m, y ±3 m, 5 cm apart) in the sensor-level
    /// frame, `height(x, y)` giving z, then seen through a surface tilt (roll, pitch) about the sensor.
    fn scan(roll: f64, pitch: f64, height: impl Fn(f64, f64) -> f64) -> Vec<[f32; 3]> {
        let tilt = Rotation3::from_euler_angles(roll, pitch, 0.0);
        let o = Vector3::new(ORIGIN[0] as f64, ORIGIN[1] as f64, ORIGIN[2] as f64);
        let mut pts = Vec::new();
        for i in 0..75 {
            for j in 0..121 {
                let (x, y) = (0.8 + 0.05 * i as f64, -3.0 + 0.05 * j as f64);
                let p = o + tilt * (Vector3::new(x, y, height(x, y)) - o);
                pts.push([p.x as f32, p.y as f32, p.z as f32]);
            }
        }
        pts
    }

    /// Young crop: bare ground with rows 0.76 m apart, 0.25 m wide and 0.3 m tall.
    fn rows(x: f64, y: f64) -> f64 {
        let _ = x;
        let d = (y / 0.76).rem_euclid(1.0) * 0.76;
        if d.min(0.76 - d) < 0.125 { 0.3 } else { 0.0 }
    }

    fn run(level: &mut Level, pts: &[[f32; 3]], scans: usize) -> Option<Rotation3<f64>> {
        let cfg = config();
        let mut out = None;
        for k in 0..scans {
            out = level.update(0.1 * k as f64, pts, ORIGIN, &cfg);
        }
        out
    }

    #[test]
    fn a_cell_keeps_its_lowest_returns_first_come_first_among_equals() {
        // Heights with many ties, in no order: after each return the cell holds the lowest
        // `LOW_RANK` so far as a stable sort by height gives them (x tells the returns apart).
        let heights = [0.3f32, 0.1, 0.3, 0.1, 0.2, 0.1, 0.05, 0.3, 0.05, 0.2, -0.1, 0.1, -0.1, 0.4];
        let mut cell = Cell::default();
        let mut seen: Vec<[f32; 3]> = Vec::new();
        for (i, &z) in heights.iter().enumerate() {
            let p = [i as f32, 0.0, z];
            cell.insert(p);
            seen.push(p);
            let mut sorted = seen.clone();
            sorted.sort_by(|a, b| a[2].total_cmp(&b[2]));
            let filled = seen.len().min(LOW_RANK);
            assert_eq!(cell.low.get(..filled), sorted.get(..filled), "after {i}");
            assert_eq!(cell.height_return(), sorted.get(LOW_RANK - 1), "after {i}");
        }
    }

    #[test]
    fn a_tilted_ground_is_recovered_within_a_fifth_of_a_degree() {
        // Ground and young rows rolled 2.5° and pitched -3°: every scan's fit within 0.2° of both.
        let (roll, pitch) = (2.5f64.to_radians(), -3f64.to_radians());
        let pts = scan(roll, pitch, rows);
        let mut level = Level::new(&config());
        let q = run(&mut level, &pts, 5).expect("levelled");
        let t = level.tilt();
        assert_eq!(t.status, LevelStatus::Measured);
        assert!((t.roll_rad - roll).abs() < 0.2f64.to_radians(), "{t:?}");
        assert!((t.pitch_rad - pitch).abs() < 0.2f64.to_radians(), "{t:?}");
        // Levelled about the sensor, the ground 2-4 m ahead is back at z = 0 within 2 cm.
        let o = Vector3::new(ORIGIN[0] as f64, ORIGIN[1] as f64, ORIGIN[2] as f64);
        let tilt = Rotation3::from_euler_angles(roll, pitch, 0.0);
        for (x, y) in [(2.0, 0.38), (4.0, -1.14), (3.0, 1.9)] {
            let seen = o + tilt * (Vector3::new(x, y, 0.0) - o);
            let back = o + q * (seen - o);
            assert!(
                back.z.abs() < 0.02 && (back.x - x).abs() < 0.02 && (back.y - y).abs() < 0.02,
                "{back:?}"
            );
        }
    }

    #[test]
    fn a_closed_canopy_top_gives_the_tilt() {
        // No ground in view: an undulating canopy top 0.6 m up (±4 cm), pitched 3°: within 0.3°.
        let pitch = 3f64.to_radians();
        let pts = scan(0.0, pitch, |x, y| 0.6 + 0.04 * (7.0 * x).sin() * (5.0 * y).cos());
        let mut level = Level::new(&config());
        run(&mut level, &pts, 5).expect("levelled");
        let t = level.tilt();
        assert!((t.pitch_rad - pitch).abs() < 0.3f64.to_radians(), "{t:?}");
        assert!(t.roll_rad.abs() < 0.3f64.to_radians(), "{t:?}");
    }

    #[test]
    fn a_closed_canopy_ending_ahead_does_not_bridge_canopy_and_ground() {
        // Canopy top 0.6 m up to x = 2.6 m, bare ground beyond, both level: the fit takes one surface
        // (a plane bridging them would pitch 9°), so the tilt stays under 0.3°.
        let pts = scan(0.0, 0.0, |x, _| if x < 2.6 { 0.6 } else { 0.0 });
        let mut level = Level::new(&config());
        run(&mut level, &pts, 5);
        let t = level.tilt();
        assert!(t.pitch_rad.abs() < 0.3f64.to_radians() && t.roll_rad.abs() < 0.3f64.to_radians(), "{t:?}");
    }

    #[test]
    fn too_few_cells_give_no_correction() {
        // A narrow strip straight ahead (|y| < 0.3 m): too little spread to fix the roll.
        let pts: Vec<[f32; 3]> = scan(0.02, 0.05, rows).into_iter().filter(|p| p[1].abs() < 0.3).collect();
        let mut level = Level::new(&config());
        assert!(run(&mut level, &pts, 3).is_none());
        assert_eq!(level.tilt().status, LevelStatus::NoEstimate);
        assert_eq!((level.tilt().roll_rad, level.tilt().pitch_rad), (0.0, 0.0));
        // Empty scans too.
        assert!(level.update(1.0, &[], ORIGIN, &config()).is_none());
    }

    #[test]
    fn a_refused_fit_holds_the_previous_estimate() {
        let pitch = -2f64.to_radians();
        let mut level = Level::new(&config());
        run(&mut level, &scan(0.0, pitch, rows), 3).expect("levelled");
        let before = level.tilt();
        assert!(level.update(5.0, &[], ORIGIN, &config()).is_some());
        let after = level.tilt();
        assert_eq!(after.status, LevelStatus::Held);
        assert_eq!((after.roll_rad, after.pitch_rad), (before.roll_rad, before.pitch_rad));
    }

    #[test]
    fn a_knocked_mount_is_followed_within_two_seconds() {
        // Level for 2 s, then pitched 3°: after 2 s more of 10 Hz scans the estimate is within 0.2° of it
        // (time constant 0.5 s: e^-4 of the step is left).
        let cfg = config();
        let mut level = Level::new(&cfg);
        let (flat, knocked) = (scan(0.0, 0.0, rows), scan(0.0, -3f64.to_radians(), rows));
        for k in 0..20 {
            level.update(0.1 * k as f64, &flat, ORIGIN, &cfg);
        }
        assert!(level.tilt().pitch_rad.abs() < 0.1f64.to_radians(), "{:?}", level.tilt());
        for k in 20..40 {
            level.update(0.1 * k as f64, &knocked, ORIGIN, &cfg);
        }
        assert!(
            (level.tilt().pitch_rad + 3f64.to_radians()).abs() < 0.2f64.to_radians(),
            "{:?}",
            level.tilt()
        );
    }

    #[test]
    fn the_estimate_is_clamped_to_the_bound() {
        // A 9° tilt with a 6° bound: levelled by 6°, never more.
        let mut level = Level::new(&config());
        run(&mut level, &scan(0.0, 9f64.to_radians(), rows), 3).expect("levelled");
        assert!((level.tilt().pitch_rad - 6f64.to_radians()).abs() < 1e-9, "{:?}", level.tilt());
    }

    #[test]
    fn non_finite_points_never_reach_the_estimate() {
        // The crop drops non-finite points; even if some slipped through, the estimate stays finite.
        let mut pts = scan(0.01, 0.02, rows);
        pts.extend([[f32::NAN, 0.0, 0.0], [2.0, f32::INFINITY, 0.0], [2.0, 0.0, f32::NEG_INFINITY]]);
        let mut level = Level::new(&config());
        let q = run(&mut level, &pts, 3).expect("levelled");
        let t = level.tilt();
        assert!(t.roll_rad.is_finite() && t.pitch_rad.is_finite());
        assert!(q.matrix().iter().all(|v| v.is_finite()));
    }

    #[test]
    fn off_means_no_correction() {
        let cfg = DetectorConfig { level_enabled: false, ..config() };
        let mut level = Level::new(&cfg);
        assert!(level.update(0.0, &scan(0.0, 0.05, rows), ORIGIN, &cfg).is_none());
        assert_eq!(level.tilt().status, LevelStatus::Off);
    }
}
