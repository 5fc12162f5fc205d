//! A ray-cast Velodyne VLP-16: 16 beams from -15° to +15°, 0.2° azimuth steps at 10 Hz, range noise,
//! a 0.9 m blind zone, 100 m range and optional dropout. It reads the field's scene and writes points in
//! the SENSOR frame (what a Velodyne driver publishes) plus, for evaluation only, each point's true class.
//!
//! The sweep is modelled: [`Lidar::cast_columns`] fires a range of azimuth columns from one sensor pose,
//! so a caller that advances the robot between calls gets the motion skew of a real spinning sensor.
//! Columns are fired clockwise seen from above, starting behind the sensor (azimuth 180°), like the
//! sample recording; a scan is stamped at its last firing. [`Lidar::scan`] fires a whole revolution
//! from one pose.
//!
//! ```
//! use croprow_sim::{Field, FieldConfig, Lidar, LidarConfig, ScanBuffer, BodyPose};
//! use croprow_core::Pose2;
//! let field = Field::generate(&FieldConfig { length_m: 10.0, ..FieldConfig::default() }, 1).unwrap();
//! let mut lidar = Lidar::new(&LidarConfig::default(), 1).unwrap();
//! let mut scan = ScanBuffer::default();
//! lidar.scan(&field, &BodyPose::planar(Pose2::new(2.0, 5.625, 0.0)), &mut scan);
//! assert!(scan.points.len() > 10_000);
//! ```

use croprow_core::error::check_range;
use croprow_core::{ConfigError, Mount, Point3, Pose2};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use crate::field::Field;
use crate::scene::{Class, PACKET_LANES};

/// Parameters of the simulated LiDAR. Defaults: a Velodyne VLP-16 on the paper's mount.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LidarConfig {
    /// `base_link -> sensor`. Default: (0.6, 0, 1.5) m, pitched 30° down (paper Sec. V).
    pub mount: Mount,
    /// Number of beams (lasers). Default 16 (VLP-16).
    pub beams: u32,
    /// Elevation of the lowest beam in the sensor frame, deg. Default -15 (VLP-16).
    pub elevation_min_deg: f64,
    /// Elevation of the highest beam, deg. Default 15 (VLP-16: 2° steps).
    pub elevation_max_deg: f64,
    /// Azimuth step between firings, deg. Default 0.2 (VLP-16 at 10 Hz).
    pub azimuth_step_deg: f64,
    /// Revolutions per second, Hz. Default 10.
    pub rate_hz: f64,
    /// Standard deviation of the range noise, m. Default 0.03 (VLP-16 datasheet: ±3 cm).
    pub range_noise_m: f64,
    /// Returns closer than this are dropped, m. Default 0.9 (VLP-16 blind zone).
    pub min_range_m: f64,
    /// Maximum range, m. Default 100 (VLP-16).
    pub max_range_m: f64,
    /// Probability that a return is lost, in [0, 1). Default 0.
    pub dropout_probability: f64,
}

impl Default for LidarConfig {
    fn default() -> Self {
        Self {
            mount: Mount::default(),
            beams: 16,
            elevation_min_deg: -15.0,
            elevation_max_deg: 15.0,
            azimuth_step_deg: 0.2,
            rate_hz: 10.0,
            range_noise_m: 0.03,
            min_range_m: 0.9,
            max_range_m: 100.0,
            dropout_probability: 0.0,
        }
    }
}

impl LidarConfig {
    /// Checks every field, naming the first bad one (`lidar.mount.z_m`, `lidar.beams`, ...).
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.mount.validate().map_err(|e| match e {
            ConfigError::Invalid { field, reason } => ConfigError::invalid(format!("lidar.{field}"), reason),
            other => other,
        })?;
        check_range("lidar.beams", self.beams as f64, 1.0, 128.0)?;
        check_range("lidar.elevation_min_deg", self.elevation_min_deg, -90.0, 90.0)?;
        check_range("lidar.elevation_max_deg", self.elevation_max_deg, self.elevation_min_deg, 90.0)?;
        check_range("lidar.azimuth_step_deg", self.azimuth_step_deg, 0.01, 10.0)?;
        check_range("lidar.rate_hz", self.rate_hz, 1.0, 50.0)?;
        check_range("lidar.range_noise_m", self.range_noise_m, 0.0, 1.0)?;
        check_range("lidar.min_range_m", self.min_range_m, 0.0, 10.0)?;
        check_range("lidar.max_range_m", self.max_range_m, self.min_range_m + 0.1, 1000.0)?;
        check_range("lidar.dropout_probability", self.dropout_probability, 0.0, 0.99)?;
        Ok(())
    }
}

/// A 3-D pose of `base_link` in the field frame: the planar pose plus what the terrain adds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BodyPose {
    /// x, y, yaw in the field frame.
    pub pose: Pose2,
    /// Height of `base_link` (the ground under the robot centre), m.
    pub z_m: f64,
    /// Roll, rad (REP-103).
    pub roll_rad: f64,
    /// Pitch, rad (REP-103: positive nose down).
    pub pitch_rad: f64,
}

impl BodyPose {
    /// A pose on flat ground.
    pub fn planar(pose: Pose2) -> Self {
        Self { pose, ..Self::default() }
    }

    /// `field -> base_link` as an isometry.
    pub fn isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(self.pose.x, self.pose.y, self.z_m),
            UnitQuaternion::from_euler_angles(self.roll_rad, self.pitch_rad, self.pose.yaw),
        )
    }
}

/// A scan being filled: sensor-frame points and their true classes, index for index. Reused across
/// scans: [`ScanBuffer::clear`] keeps the allocation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanBuffer {
    /// Points in the sensor frame at their firing time, m.
    pub points: Vec<Point3>,
    /// True class of each point (evaluation only).
    pub classes: Vec<Class>,
}

impl ScanBuffer {
    /// Empties the buffer, keeping its capacity.
    pub fn clear(&mut self) {
        self.points.clear();
        self.classes.clear();
    }
}

/// The simulated sensor: precomputed beam directions and its own seeded noise stream.
#[derive(Debug, Clone)]
pub struct Lidar {
    config: LidarConfig,
    /// Unit beam directions in the sensor frame, column-major (`column * beams + beam`).
    dirs: Vec<[f32; 3]>,
    columns: usize,
    mount: Isometry3<f64>,
    rng: ChaCha8Rng,
    /// Hits of the columns being cast, one packet per beam (allocated once): the packets write their
    /// answers in place, and the returns are then read column by column.
    hits: Vec<[Option<(f32, Class)>; PACKET_LANES]>,
}

impl Lidar {
    /// A sensor from a validated configuration and a seed for its noise.
    pub fn new(config: &LidarConfig, seed: u64) -> Result<Self, ConfigError> {
        config.validate()?;
        let columns = (360.0 / config.azimuth_step_deg).round() as usize;
        let beams = config.beams as usize;
        let mut dirs = Vec::with_capacity(columns * beams);
        for c in 0..columns {
            // Clockwise from behind: azimuth (CCW from +x) goes 180°, 179.8°, ...
            let az = (180.0 - c as f64 * config.azimuth_step_deg).to_radians();
            for b in 0..beams {
                let el = if beams == 1 {
                    config.elevation_min_deg
                } else {
                    config.elevation_min_deg
                        + (config.elevation_max_deg - config.elevation_min_deg) * b as f64
                            / (beams - 1) as f64
                }
                .to_radians();
                dirs.push([(el.cos() * az.cos()) as f32, (el.cos() * az.sin()) as f32, el.sin() as f32]);
            }
        }
        Ok(Self {
            config: config.clone(),
            dirs,
            columns,
            mount: config.mount.isometry(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            hits: vec![[None; PACKET_LANES]; beams],
        })
    }

    /// The configuration.
    pub fn config(&self) -> &LidarConfig {
        &self.config
    }

    /// Azimuth columns per revolution (1800 for a VLP-16 at 0.2°).
    pub fn columns(&self) -> usize {
        self.columns
    }

    /// Rays per revolution.
    pub fn rays_per_revolution(&self) -> usize {
        self.dirs.len()
    }

    /// Duration of one revolution, s.
    pub fn period_s(&self) -> f64 {
        1.0 / self.config.rate_hz
    }

    /// Fires a whole revolution from one body pose into `out` (cleared first).
    pub fn scan(&mut self, field: &Field, body: &BodyPose, out: &mut ScanBuffer) {
        out.clear();
        self.cast_columns(field, body, 0, self.columns, out);
    }

    /// Fires columns `first..last` (clamped to the revolution) from `body` and appends their returns.
    ///
    /// Each laser's rays of up to 16 consecutive columns are cast together as one packet (they share
    /// the traversal of the field's bounding volume hierarchy and are tested against each box and
    /// primitive at once); the returns are exactly those of casting ray by ray, and they and their
    /// noise draws follow column by column, beam by beam, as before.
    pub fn cast_columns(
        &mut self,
        field: &Field,
        body: &BodyPose,
        first: usize,
        last: usize,
        out: &mut ScanBuffer,
    ) {
        let (origin, rot) = sensor_in_field(&(body.isometry() * self.mount));
        let beams = self.config.beams as usize;
        let returns = Returns::of(&self.config);
        let scene = field.scene();
        let last = last.min(self.columns);
        let Self { dirs, hits, rng, .. } = self;
        let rays = dirs.get(first * beams..last * beams).unwrap_or(&[]);
        for columns in rays.chunks(PACKET_LANES * beams) {
            let n = (columns.len() / beams.max(1)).min(PACKET_LANES);
            for (beam, found) in hits.iter_mut().enumerate() {
                // The beam's rays of these columns, rotated into the field frame as one packed array
                // per axis (per ray the same products and sums, in the same order, as `rot · d`).
                let mut sensor = [[0f32; PACKET_LANES]; 3];
                let [xs, ys, zs] = &mut sensor;
                let beam_rays = columns.iter().skip(beam).step_by(beams.max(1));
                for (((x, y), z), ds) in xs.iter_mut().zip(ys.iter_mut()).zip(zs.iter_mut()).zip(beam_rays) {
                    (*x, *y, *z) = (ds[0], ds[1], ds[2]);
                }
                let mut field_frame = [[0f32; PACKET_LANES]; 3];
                for (axis, row) in field_frame.iter_mut().zip(&rot) {
                    for k in 0..PACKET_LANES {
                        axis[k] = row[0] * sensor[0][k] + row[1] * sensor[1][k] + row[2] * sensor[2][k];
                    }
                }
                let mut world = [[0f32; 3]; PACKET_LANES];
                for (k, d) in world.iter_mut().enumerate() {
                    *d = [field_frame[0][k], field_frame[1][k], field_frame[2][k]];
                }
                scene.cast_packet(origin, &world[..n], returns.max_r, &mut found[..n]);
            }
            for (k, column) in columns.chunks(beams.max(1)).enumerate() {
                for (found, ds) in hits.iter().zip(column) {
                    if let Some(&Some(hit)) = found.get(k) {
                        returns.emit(rng, hit, *ds, out);
                    }
                }
            }
        }
    }
}

/// What turns a true hit into a return: the blind zone, dropout, range noise and the maximum range.
#[derive(Debug, Clone, Copy)]
struct Returns {
    min_r: f32,
    max_r: f32,
    sigma: f32,
    dropout: f64,
}

impl Returns {
    fn of(config: &LidarConfig) -> Self {
        Self {
            min_r: config.min_range_m as f32,
            max_r: config.max_range_m as f32,
            sigma: config.range_noise_m as f32,
            dropout: config.dropout_probability,
        }
    }

    /// Adds the noisy return of a ray along the sensor-frame direction `ds` whose true hit is `hit`, or
    /// nothing when the return falls in the blind zone, drops out or leaves the range.
    #[inline]
    fn emit(&self, rng: &mut ChaCha8Rng, (range, class): (f32, Class), ds: [f32; 3], out: &mut ScanBuffer) {
        if range < self.min_r {
            return;
        }
        if self.dropout > 0.0 && rng.random_bool(self.dropout) {
            return;
        }
        let noise: f32 = StandardNormal.sample(rng);
        let measured = range + self.sigma * noise;
        if !(measured >= self.min_r && measured <= self.max_r) {
            return;
        }
        out.points.push(Point3::new(measured * ds[0], measured * ds[1], measured * ds[2]));
        out.classes.push(class);
    }
}

/// The sensor's origin and rotation (sensor -> field) in `f32`.
fn sensor_in_field(sensor: &Isometry3<f64>) -> ([f32; 3], [[f32; 3]; 3]) {
    let m = sensor.rotation.to_rotation_matrix().into_inner();
    let rot = [
        [m[(0, 0)] as f32, m[(0, 1)] as f32, m[(0, 2)] as f32],
        [m[(1, 0)] as f32, m[(1, 1)] as f32, m[(1, 2)] as f32],
        [m[(2, 0)] as f32, m[(2, 1)] as f32, m[(2, 2)] as f32],
    ];
    let t = sensor.translation.vector;
    ([t.x as f32, t.y as f32, t.z as f32], rot)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Crop, FieldConfig, Stage};

    fn field(crop: Crop, stage: Stage) -> Field {
        Field::generate(&FieldConfig { crop, stage, length_m: 20.0, ..FieldConfig::default() }, 5).unwrap()
    }

    fn lane_pose(f: &Field, x: f64) -> BodyPose {
        BodyPose::planar(Pose2::new(x, f.lane_y(7, x), 0.0))
    }

    #[test]
    fn bare_ground_gives_the_analytic_ranges() {
        let f = Field::generate(
            &FieldConfig { rows: 1, length_m: 1.0, weeds_per_m2: 0.0, ..FieldConfig::default() },
            0,
        )
        .unwrap();
        let cfg = LidarConfig { range_noise_m: 0.0, ..LidarConfig::default() };
        let mut lidar = Lidar::new(&cfg, 0).unwrap();
        let mut scan = ScanBuffer::default();
        // Far from the single short row: only ground.
        lidar.scan(&f, &BodyPose::planar(Pose2::new(60.0, 30.0, 0.0)), &mut scan);
        let m = cfg.mount;
        for p in &scan.points {
            let b = m.to_base(*p);
            // Every noiseless return lies on the ground plane (f32 rounding at up to 100 m: 2 cm).
            assert!(b.z.abs() < 0.02, "{b:?}");
        }
        // Forward-looking beams hit the ground; the ones tilted above the horizon behind do not.
        assert!(scan.points.len() > 10_000 && scan.points.len() < 20_000, "{}", scan.points.len());
    }

    #[test]
    fn no_return_inside_the_blind_zone_and_all_points_finite() {
        let f = field(Crop::Corn, Stage::Grown);
        let mut lidar = Lidar::new(&LidarConfig::default(), 1).unwrap();
        let mut scan = ScanBuffer::default();
        lidar.scan(&f, &lane_pose(&f, 5.0), &mut scan);
        for p in &scan.points {
            let r = (p.x * p.x + p.y * p.y + p.z * p.z).sqrt();
            assert!(p.is_finite() && r >= 0.9, "{p:?}");
        }
        assert_eq!(scan.points.len(), scan.classes.len());
    }

    #[test]
    fn dropout_thins_the_scan() {
        let f = field(Crop::Corn, Stage::Young);
        let mut full = Lidar::new(&LidarConfig::default(), 1).unwrap();
        let mut thin =
            Lidar::new(&LidarConfig { dropout_probability: 0.5, ..LidarConfig::default() }, 1).unwrap();
        let (mut a, mut b) = (ScanBuffer::default(), ScanBuffer::default());
        full.scan(&f, &lane_pose(&f, 5.0), &mut a);
        thin.scan(&f, &lane_pose(&f, 5.0), &mut b);
        let ratio = b.points.len() as f64 / a.points.len() as f64;
        // Binomial with n ≈ 14k: ±2 % is over 4σ.
        assert!((ratio - 0.5).abs() < 0.02, "{ratio}");
    }

    #[test]
    fn a_sensor_below_ground_is_refused_by_name() {
        let cfg = LidarConfig { mount: Mount { z_m: -0.3, ..Mount::default() }, ..LidarConfig::default() };
        let e = Lidar::new(&cfg, 0).unwrap_err().to_string();
        assert!(e.contains("lidar.mount.z_m"), "{e}");
        let e = Lidar::new(&LidarConfig { min_range_m: 5.0, max_range_m: 1.0, ..LidarConfig::default() }, 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("lidar.max_range_m"), "{e}");
    }
}
