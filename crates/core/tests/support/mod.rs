//! Synthetic scans for the detector tests and bench: a VLP-16 ray-cast through the mount against an
//! analytic field (ground, crop rows of ellipsoid bushes, gaps, weeds, a closed canopy, curved rows, a
//! row end), with seeded range noise, and the ground-truth rows seen from any robot pose.
#![allow(dead_code)]

use croprow_core::geometry::wrap_angle;
use croprow_core::{Detection, DetectorConfig, Mount, Point3, Pose2, RowDetector, Scan};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A row-crop field in the world frame: rows along +x, the lane centre of the robot at y = 0, row k at
/// `(k + ½)·spacing + curve(x)`.
#[derive(Debug, Clone)]
pub struct Field {
    /// Row spacing, m.
    pub spacing_m: f64,
    /// Rows k in `-rows_each_side..rows_each_side`.
    pub rows_each_side: i32,
    /// Bush height above the ground, m.
    pub plant_height_m: f64,
    /// Bush half-width across the row, m.
    pub plant_half_width_m: f64,
    /// Distance between bushes along the row, m, and their half-length.
    pub plant_period_m: f64,
    pub plant_half_length_m: f64,
    /// Closed canopy: leaves between the rows at this height, m.
    pub canopy_floor_m: Option<f64>,
    /// Curved rows: `amplitude · sin(2πx / wavelength)`, m.
    pub curve_amplitude_m: f64,
    pub curve_wavelength_m: f64,
    /// Stretches `(k, x_from, x_to)` of row k without plants, m.
    pub gaps: Vec<(i32, f64, f64)>,
    /// Rows k absent entirely.
    pub missing_rows: Vec<i32>,
    /// Where every row ends, m (world x).
    pub row_end_x_m: Option<f64>,
    /// Fraction of 0.25 m cells between the rows holding a weed (1-8 cm tall).
    pub weed_density: f64,
}

impl Default for Field {
    fn default() -> Self {
        Self {
            spacing_m: 0.75,
            rows_each_side: 4,
            plant_height_m: 0.5,
            plant_half_width_m: 0.15,
            plant_period_m: 0.3,
            plant_half_length_m: 0.2,
            canopy_floor_m: None,
            curve_amplitude_m: 0.0,
            curve_wavelength_m: 100.0,
            gaps: Vec::new(),
            missing_rows: Vec::new(),
            row_end_x_m: None,
            weed_density: 0.0,
        }
    }
}

/// Cheap deterministic hash of a cell, in [0, 1).
fn hash01(i: i64, j: i64, salt: u64) -> f64 {
    let mut h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ salt;
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

impl Field {
    pub fn young_corn() -> Self {
        Self { plant_height_m: 0.25, plant_half_width_m: 0.1, plant_half_length_m: 0.12, ..Self::default() }
    }

    pub fn grown_closed() -> Self {
        Self { plant_height_m: 0.7, plant_half_width_m: 0.3, canopy_floor_m: Some(0.4), ..Self::default() }
    }

    pub fn curve(&self, x: f64) -> f64 {
        self.curve_amplitude_m * (std::f64::consts::TAU * x / self.curve_wavelength_m).sin()
    }

    pub fn curve_slope(&self, x: f64) -> f64 {
        let w = std::f64::consts::TAU / self.curve_wavelength_m;
        self.curve_amplitude_m * w * (w * x).cos()
    }

    pub fn row_y(&self, k: i32, x: f64) -> f64 {
        (k as f64 + 0.5) * self.spacing_m + self.curve(x)
    }

    fn planted(&self, k: i32, x: f64) -> bool {
        k >= -self.rows_each_side
            && k < self.rows_each_side
            && !self.missing_rows.contains(&k)
            && self.row_end_x_m.is_none_or(|e| x <= e)
            && !self.gaps.iter().any(|&(g, a, b)| g == k && x >= a && x <= b)
    }

    /// Surface height at world (x, y), m.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        let cos = 1.0 / (1.0 + self.curve_slope(x).powi(2)).sqrt();
        let u = (y - self.curve(x)) / self.spacing_m - 0.5;
        let k = u.round();
        let d = (u - k) * self.spacing_m * cos;
        let k = k as i32;
        let mut h = 0.0f64;
        let in_field = k >= -self.rows_each_side - 1
            && k <= self.rows_each_side
            && self.row_end_x_m.is_none_or(|e| x <= e);
        if self.planted(k, x) {
            // Nearest bush along the row (and its neighbour, since bushes overlap).
            let m = (x / self.plant_period_m).round();
            for n in [m - 1.0, m, m + 1.0] {
                let dx = x - n * self.plant_period_m;
                let q = 1.0 - (d / self.plant_half_width_m).powi(2) - (dx / self.plant_half_length_m).powi(2);
                if q > 0.0 {
                    h = h.max(self.plant_height_m * q.sqrt());
                }
            }
        }
        if in_field && let Some(f) = self.canopy_floor_m {
            h = h.max(f);
        }
        if self.weed_density > 0.0 && in_field {
            let cell = 0.25;
            let (ci, cj) = ((x / cell).floor() as i64, (y / cell).floor() as i64);
            if hash01(ci, cj, 1) < self.weed_density {
                let (wx, wy) = ((ci as f64 + 0.5) * cell, (cj as f64 + 0.5) * cell);
                let wh = 0.01 + 0.07 * hash01(ci, cj, 2);
                let r2 = ((x - wx).powi(2) + (y - wy).powi(2)) / 0.06f64.powi(2);
                if r2 < 1.0 {
                    h = h.max(wh * (1.0 - r2).sqrt());
                }
            }
        }
        h
    }

    /// Truth of row k seen from `pose`: lateral offset where it crosses base_link's y axis, m, and its
    /// heading relative to the robot, rad; `None` when it does not cross within 5 m.
    pub fn truth(&self, k: i32, pose: &Pose2) -> Option<(f64, f64)> {
        let (s, c) = pose.yaw.sin_cos();
        let f = |t: f64| {
            let (x, y) = (pose.x - s * t, pose.y + c * t);
            y - self.row_y(k, x)
        };
        let (mut lo, mut hi) = (-5.0, 5.0);
        if f(lo) * f(hi) > 0.0 {
            return None;
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if f(lo) * f(mid) <= 0.0 { hi = mid } else { lo = mid }
        }
        let t = 0.5 * (lo + hi);
        let x = pose.x - s * t;
        Some((t, wrap_angle(self.curve_slope(x).atan() - pose.yaw)))
    }
}

/// A VLP-16: 16 beams at -15..+15° in 2° steps, `azimuth_step_deg` apart, range noise σ.
#[derive(Debug, Clone)]
pub struct Lidar {
    pub azimuth_step_deg: f64,
    pub range_sigma_m: f64,
    pub max_range_m: f64,
    /// Organised cloud: a NaN point for every ray without a return (16 × 1800 points per scan), as
    /// Velodyne drivers publish it with `organize_cloud`.
    pub organized: bool,
    rng: ChaCha8Rng,
}

impl Lidar {
    pub fn vlp16(seed: u64) -> Self {
        Self {
            azimuth_step_deg: 0.2,
            range_sigma_m: 0.03,
            max_range_m: 8.0,
            organized: false,
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// One revolution from the robot at `pose` (world = odom), in the sensor frame. Rays that miss give
    /// no point, or a NaN point in an organised cloud.
    pub fn scan(&mut self, field: &Field, pose: &Pose2, mount: &Mount) -> Vec<Point3> {
        let robot = Isometry3::from_parts(
            Translation3::new(pose.x, pose.y, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, pose.yaw),
        );
        let world = robot * mount.isometry();
        let origin = world.translation.vector;
        let noise = Normal::new(0.0, self.range_sigma_m.max(1e-12)).expect("valid sigma");
        let top = field.plant_height_m.max(field.canopy_floor_m.unwrap_or(0.0)) + 0.01;
        let n_az = (360.0 / self.azimuth_step_deg).round() as usize;
        let mut out = Vec::with_capacity(16 * n_az);
        for a in 0..n_az {
            let az = (a as f64 * self.azimuth_step_deg).to_radians();
            for ring in 0..16 {
                let el = (-15.0 + 2.0 * ring as f64).to_radians();
                let d_s = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
                let d = world.rotation * d_s;
                if let Some(r) = cast(field, &origin, &d, top, self.max_range_m) {
                    let r = r + noise.sample(&mut self.rng);
                    out.push(Point3::new((d_s.x * r) as f32, (d_s.y * r) as f32, (d_s.z * r) as f32));
                } else if self.organized {
                    out.push(Point3::new(f32::NAN, f32::NAN, f32::NAN));
                }
            }
        }
        out
    }
}

/// Range to the first surface hit along `d` from `o`, m.
fn cast(field: &Field, o: &Vector3<f64>, d: &Vector3<f64>, top: f64, max_r: f64) -> Option<f64> {
    if d.z > -1e-3 {
        return None;
    }
    let step = 0.01;
    // Jump straight to the layer where plants can be.
    let mut r = ((o.z - top) / -d.z).max(0.0);
    let mut prev = r;
    while r <= max_r {
        let p = o + d * r;
        if p.z <= field.height(p.x, p.y) {
            let (mut lo, mut hi) = (prev, r);
            for _ in 0..8 {
                let mid = 0.5 * (lo + hi);
                let q = o + d * mid;
                if q.z <= field.height(q.x, q.y) { hi = mid } else { lo = mid }
            }
            return Some(hi);
        }
        prev = r;
        r += step;
    }
    None
}

/// Robot poses driving along the lane centre from `x0` to `x1`, `step_m` apart, with a lateral offset
/// and a heading error relative to the rows.
pub fn drive(field: &Field, x0: f64, x1: f64, step_m: f64, lateral_m: f64, yaw_err_rad: f64) -> Vec<Pose2> {
    let n = ((x1 - x0) / step_m).floor() as usize;
    (0..=n)
        .map(|i| {
            let x = x0 + i as f64 * step_m;
            Pose2::new(x, field.curve(x) + lateral_m, field.curve_slope(x).atan() + yaw_err_rad)
        })
        .collect()
}

/// Per-scan errors of one run, after `skip` scans of convergence.
#[derive(Debug, Clone, Default)]
pub struct Errors {
    /// |offset error| of the first left and right rows, m, per scan where both truth and estimate exist.
    pub offset_m: Vec<f64>,
    /// |heading error|, rad.
    pub heading_rad: Vec<f64>,
    /// Scans where the detector had no row while the truth had one, or picked the wrong row.
    pub misses: usize,
    pub detections: Vec<Detection>,
}

impl Errors {
    pub fn mean(v: &[f64]) -> f64 {
        if v.is_empty() { f64::NAN } else { v.iter().sum::<f64>() / v.len() as f64 }
    }
    pub fn max(v: &[f64]) -> f64 {
        v.iter().copied().fold(0.0, f64::max)
    }
    pub fn summary(&self) -> String {
        format!(
            "offset mean {:.1} cm max {:.1} cm | heading mean {:.2}° max {:.2}° | misses {} of {}",
            100.0 * Self::mean(&self.offset_m),
            100.0 * Self::max(&self.offset_m),
            Self::mean(&self.heading_rad).to_degrees(),
            Self::max(&self.heading_rad).to_degrees(),
            self.misses,
            self.offset_m.len() / 2 + self.misses
        )
    }
}

/// Drives `poses` over `field` with `config`, 10 Hz, perfect odometry; scores the first left row
/// (k = 0 at the lane centre) and the first right row (k = -1) after `skip` scans.
pub fn run(field: &Field, config: DetectorConfig, poses: &[Pose2], skip: usize, seed: u64) -> Errors {
    run_with_odometry(field, config, poses, poses, skip, seed)
}

/// Odometry that drifts: each step's true motion scaled by `1 + scale_err` and its heading change
/// biased by `yaw_drift_rad_per_m` per metre travelled, integrated from the first true pose.
pub fn drifting_odometry(poses: &[Pose2], scale_err: f64, yaw_drift_rad_per_m: f64) -> Vec<Pose2> {
    let mut odom = Vec::with_capacity(poses.len());
    let mut cur = poses.first().copied().unwrap_or_default();
    for (i, p) in poses.iter().enumerate() {
        if let Some(prev) = i.checked_sub(1).and_then(|k| poses.get(k)) {
            let rel = prev.relative(p);
            let dist = rel.x.hypot(rel.y);
            let step = Pose2::new(
                rel.x * (1.0 + scale_err),
                rel.y * (1.0 + scale_err),
                rel.yaw + yaw_drift_rad_per_m * dist,
            );
            cur = cur.compose(&step);
        }
        odom.push(cur);
    }
    odom
}

/// As [`run`], with the detector fed `odometry` instead of the true poses (the truth still scores it).
pub fn run_with_odometry(
    field: &Field,
    config: DetectorConfig,
    poses: &[Pose2],
    odometry: &[Pose2],
    skip: usize,
    seed: u64,
) -> Errors {
    let mount = Mount::default();
    let mut lidar = Lidar::vlp16(seed);
    let mut det = RowDetector::new(config).expect("valid config");
    let mut e = Errors::default();
    for (i, (pose, odom)) in poses.iter().zip(odometry).enumerate() {
        let pts = lidar.scan(field, pose, &mount);
        let d = det.detect(
            Scan { stamp_s: i as f64 * 0.1, points: &pts, twist: None, attitude: None },
            *odom,
            &mount,
        );
        e.detections.push(d);
        if i < skip {
            continue;
        }
        for (est, k) in [(d.left, 0), (d.right, -1)] {
            let Some((t_off, t_head)) = field.truth(k, pose) else { continue };
            match est {
                Some(r) if (r.offset_m - t_off).abs() < 0.5 * field.spacing_m => {
                    e.offset_m.push((r.offset_m - t_off).abs());
                    e.heading_rad.push(wrap_angle(r.heading_rad - t_head).abs());
                }
                _ => e.misses += 1,
            }
        }
    }
    e
}
