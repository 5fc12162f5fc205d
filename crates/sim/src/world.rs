//! The world: a field, a LiDAR, a robot and its sensors, stepped together with a fixed time step.
//! Each [`World::step`] takes a velocity command and returns what happened in that step as stamped
//! data: the true pose (always), wheel odometry and IMU samples when due, and a LiDAR scan when a
//! revolution completes, plus the crop contacts of the step.
//!
//! A detection run (Table I) drives with the [`Driver`] and scores each scan with
//! [`crate::metrics::score_detection`]; a closed loop feeds the controller's command back instead.
//!
//! ```
//! use croprow_sim::{Scenario, World};
//! let mut scenario = Scenario::builtin("young-corn").unwrap();
//! scenario.field.length_m = 12.0;
//! let mut world = World::new(&scenario).unwrap();
//! let mut driver = world.driver().unwrap();
//! let mut scans = 0;
//! while world.time_s() < 1.0 {
//!     let cmd = driver.command(world.time_s(), &world.robot().pose(), world.field());
//!     let step = world.step(cmd).unwrap();
//!     if let Some(scan) = step.scan {
//!         // scan.as_scan() is what a detector takes; scan.truth is the true pose at its stamp.
//!         assert!(!scan.points.is_empty());
//!         scans += 1;
//!     }
//! }
//! assert_eq!(scans, 10);
//! ```

use croprow_core::geometry::wrap_angle;
use croprow_core::{Mount, Point3, Pose2, Scan, Twist2};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::driver::Driver;
use crate::faults::{FaultConfig, MountError};
use crate::field::Field;
use crate::lidar::{BodyPose, Lidar, LidarConfig, ScanBuffer};
use crate::metrics::CropDamage;
use crate::robot::{Robot, StepError, terrain_body};
use crate::scenario::{Scenario, ScenarioError, WorldConfig};
use crate::scene::Class;
use crate::sensors::{ImuSample, Sensors, WheelOdometry};

/// Seed offsets so that each random process has its own stream derived from the scenario seed.
const SEED_LIDAR: u64 = 0x11;
const SEED_ROBOT: u64 = 0x22;
const SEED_SENSORS: u64 = 0x33;
const SEED_DRIVER: u64 = 0x44;
const SEED_FAULTS: u64 = 0x55;
const SEED_KNOCKED_LIDAR: u64 = 0x66;

/// A completed LiDAR revolution, borrowed from the world until the next step.
#[derive(Debug, Clone, Copy)]
pub struct ScanView<'a> {
    /// Stamp: the time of the last firing of the sweep, s (off by `faults.scan_stamp.offset_s` in
    /// that fault's stretch).
    pub stamp_s: f64,
    /// Points in the sensor frame (each at its own firing time when motion skew is on), m.
    pub points: &'a [Point3],
    /// True class of each point (evaluation only).
    pub classes: &'a [Class],
    /// True pose of `base_link` at the stamp.
    pub truth: BodyPose,
}

impl<'a> ScanView<'a> {
    /// The scan as the detector takes it.
    pub fn as_scan(&self) -> Scan<'a> {
        Scan { stamp_s: self.stamp_s, points: self.points, twist: None, attitude: None }
    }
}

/// What one step produced.
#[derive(Debug, Clone, Copy)]
pub struct Step<'a> {
    /// Time at the end of the step, s.
    pub stamp_s: f64,
    /// True 3-D pose of `base_link` at `stamp_s`.
    pub truth: BodyPose,
    /// True body twist over the step.
    pub true_twist: Twist2,
    /// Wheel odometry, when one was due (with `faults.odometry_timing`: jittered stamps, and now and
    /// then an older message delivered after a newer one).
    pub wheel: Option<WheelOdometry>,
    /// IMU sample, when one was due.
    pub imu: Option<ImuSample>,
    /// A LiDAR revolution, when one completed in this step (none during a `faults.lidar_dropout`).
    pub scan: Option<ScanView<'a>>,
    /// Plants run over for the first time in this step.
    pub new_contacts: usize,
}

/// The simulated world.
#[derive(Debug, Clone)]
pub struct World {
    config: WorldConfig,
    field: Field,
    lidar: Lidar,
    robot: Robot,
    sensors: Sensors,
    damage: CropDamage,
    lane: u32,
    seed: u64,
    driver_config: crate::driver::DriverConfig,
    steps: u64,
    /// Start of the current sweep, s, and columns fired in it.
    sweep_start_s: f64,
    fired: usize,
    filling: ScanBuffer,
    done: ScanBuffer,
    /// Stamp and true pose of the revolution in `done`.
    last_scan_stamp_s: f64,
    last_scan_truth: BodyPose,
    /// A revolution has been delivered (`done` holds one).
    delivered: bool,
    faults: Injector,
}

/// The world's share of fault injection (`faults.*` of the scenario): what happens to scans and
/// odometry messages between the sensors and their consumer, and the knock on the LiDAR mount.
#[derive(Debug, Clone)]
struct Injector {
    config: FaultConfig,
    rng: ChaCha8Rng,
    /// The LiDAR on its knocked mount, until the knock has happened.
    knocked_lidar: Option<Lidar>,
    /// x at which the next LiDAR dropout starts, and the time the current one ends.
    next_dropout_x_m: f64,
    dropout_until_s: f64,
    /// A wheel odometry message held back to be delivered after a newer one, and whether a newer one
    /// has gone out since.
    held_wheel: Option<WheelOdometry>,
    newer_wheel_sent: bool,
    /// `base_link -> sensor` of the TRUE mount (for spurious returns).
    true_mount: Mount,
}

impl World {
    /// Builds the scenario's world: generates the field and places the robot at its start pose.
    pub fn new(scenario: &Scenario) -> Result<Self, ScenarioError> {
        scenario.validate()?;
        let field = Field::generate_with_faults(&scenario.field, &scenario.faults, scenario.seed)?;
        let lane = scenario.lane();
        let x = scenario.start.x_m;
        let th = field.row_heading(x);
        let off = scenario.start.lateral_offset_m;
        let start = Pose2::new(
            x - off * th.sin(),
            field.lane_y(lane, x) + off * th.cos(),
            th + scenario.start.heading_offset_deg.to_radians(),
        );
        let me = &scenario.faults.mount_error;
        let knocked = me.enabled.then(|| knocked_lidar(&scenario.lidar, me)).transpose()?;
        // Mounted wrong from the start, or knocked on the way.
        let (from_start, later) = match knocked {
            Some(k) if me.at_x_m <= start.x => (Some(k), None),
            other => (None, other),
        };
        let lidar = Lidar::new(from_start.as_ref().unwrap_or(&scenario.lidar), scenario.seed ^ SEED_LIDAR)?;
        let mut robot = Robot::new(&scenario.robot, start, scenario.seed ^ SEED_ROBOT)?;
        robot.set_slip_patch(scenario.faults.slip_patch.clone());
        let later = later.map(|cfg| Lidar::new(&cfg, scenario.seed ^ SEED_KNOCKED_LIDAR)).transpose()?;
        let mut world = Self::from_parts(field, lidar, robot, scenario, lane)?;
        world.faults.knocked_lidar = later;
        Ok(world)
    }

    fn from_parts(
        field: Field,
        lidar: Lidar,
        mut robot: Robot,
        scenario: &Scenario,
        lane: u32,
    ) -> Result<Self, ScenarioError> {
        let dt = scenario.world.dt_s;
        let mut sensors = Sensors::new(
            &scenario.sensors,
            scenario.robot.effective_track_m(),
            dt,
            scenario.seed ^ SEED_SENSORS,
        )?;
        sensors.set_gyro_bias_step(scenario.faults.gyro_bias_step.clone());
        let dropout = &scenario.faults.lidar_dropout;
        robot.settle(&field);
        let mut damage = CropDamage::new(&field);
        damage.update(&field, robot.config(), &robot.pose());
        let per_scan = lidar.rays_per_revolution();
        Ok(Self {
            config: scenario.world.clone(),
            field,
            robot,
            sensors,
            damage,
            lane,
            seed: scenario.seed,
            driver_config: scenario.driver.clone(),
            steps: 0,
            sweep_start_s: 0.0,
            fired: 0,
            filling: ScanBuffer {
                points: Vec::with_capacity(per_scan),
                classes: Vec::with_capacity(per_scan),
            },
            done: ScanBuffer { points: Vec::with_capacity(per_scan), classes: Vec::with_capacity(per_scan) },
            last_scan_stamp_s: 0.0,
            last_scan_truth: BodyPose::default(),
            delivered: false,
            faults: Injector {
                config: scenario.faults.clone(),
                rng: ChaCha8Rng::seed_from_u64(scenario.seed ^ SEED_FAULTS),
                knocked_lidar: None,
                next_dropout_x_m: if dropout.enabled { dropout.from_x_m } else { f64::INFINITY },
                dropout_until_s: f64::NEG_INFINITY,
                held_wheel: None,
                newer_wheel_sent: false,
                true_mount: lidar_mount(&lidar),
            },
            lidar,
        })
    }

    /// The scenario's human-like driver for this world's lane (seeded from the scenario).
    pub fn driver(&self) -> Result<Driver, ScenarioError> {
        Ok(Driver::new(&self.driver_config, self.lane, self.seed ^ SEED_DRIVER)?)
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * self.config.dt_s
    }

    /// The field.
    pub fn field(&self) -> &Field {
        &self.field
    }

    /// The robot (true state).
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The LiDAR.
    pub fn lidar(&self) -> &Lidar {
        &self.lidar
    }

    /// The lane the robot started in.
    pub fn lane(&self) -> u32 {
        self.lane
    }

    /// Plants run over since the start.
    pub fn crop_contacts(&self) -> usize {
        self.damage.count()
    }

    /// The least clearance from a tyre's side to a stem beside it since the start, m (see
    /// [`CropDamage::least_clearance_m`]).
    pub fn least_stem_clearance_m(&self) -> Option<f64> {
        self.damage.least_clearance_m()
    }

    /// The last completed LiDAR revolution (`None` before the first): the scan a [`Step`] returned,
    /// still readable after the step's borrow ended (e.g. to score it against the field first).
    pub fn last_scan(&self) -> Option<ScanView<'_>> {
        self.delivered.then(|| ScanView {
            stamp_s: self.last_scan_stamp_s,
            points: &self.done.points,
            classes: &self.done.classes,
            truth: self.last_scan_truth,
        })
    }

    /// Advances the world by one time step under `cmd`. A non-finite command is refused and nothing moves.
    pub fn step(&mut self, cmd: Twist2) -> Result<Step<'_>, StepError> {
        let dt = self.config.dt_s;
        self.robot.step(cmd, dt, &self.field)?;
        self.steps += 1;
        let now = self.time_s();
        let wheel = self.sensors.wheel(now, &self.robot);
        let imu = self.sensors.imu(now, &self.robot);
        let (wheel, imu) = self.faults.transport(now, wheel, imu);
        let new_contacts = self.damage.update(&self.field, self.robot.config(), &self.robot.pose());
        let body = self.robot.body();

        // Fire the columns whose firing times fall in this step.
        let period = self.lidar.period_s();
        let columns = self.lidar.columns();
        let due =
            (((now - self.sweep_start_s) / period * columns as f64 + 1e-6).floor() as usize).min(columns);
        if self.config.motion_skew && due > self.fired {
            self.lidar.cast_columns(&self.field, &body, self.fired, due, &mut self.filling);
            self.fired = due;
        }
        let mut completed = false;
        if due >= columns {
            if !self.config.motion_skew {
                self.lidar.scan(&self.field, &body, &mut self.filling);
            }
            self.fired = 0;
            self.sweep_start_s += period;
            let x = body.pose.x;
            if self.faults.scan_lost(now, x) {
                self.filling.clear();
            } else {
                self.faults.damage_scan(x, &mut self.filling);
                std::mem::swap(&mut self.filling, &mut self.done);
                self.filling.clear();
                self.last_scan_stamp_s = now + self.faults.stamp_error_s(x);
                self.last_scan_truth = body;
                self.delivered = true;
                completed = true;
            }
            // A knock lands between revolutions, so that no revolution mixes two mounts.
            let knock_x = self.faults.config.mount_error.at_x_m;
            if let Some(knocked) = self.faults.knocked_lidar.take_if(|_| x >= knock_x) {
                self.lidar = knocked;
                self.faults.true_mount = lidar_mount(&self.lidar);
            }
        }
        let scan = completed.then(|| ScanView {
            stamp_s: self.last_scan_stamp_s,
            points: &self.done.points,
            classes: &self.done.classes,
            truth: body,
        });
        Ok(Step { stamp_s: now, truth: body, true_twist: self.robot.twist(), wheel, imu, scan, new_contacts })
    }

    /// The true pose on the terrain of a planar pose in this field (for callers that place things).
    pub fn body_at(&self, pose: Pose2) -> BodyPose {
        terrain_body(&self.field, pose)
    }
}

/// The LiDAR configuration with the mount error added to the nominal mount's angles.
fn knocked_lidar(nominal: &LidarConfig, e: &MountError) -> Result<LidarConfig, ScenarioError> {
    let m = nominal.mount;
    let mount = Mount {
        roll_rad: m.roll_rad + e.roll_deg.to_radians(),
        pitch_rad: m.pitch_rad + e.pitch_deg.to_radians(),
        yaw_rad: wrap_angle(m.yaw_rad + e.yaw_deg.to_radians()),
        ..m
    };
    let cfg = LidarConfig { mount, ..nominal.clone() };
    cfg.validate().map_err(|e| match e {
        croprow_core::ConfigError::Invalid { field, reason } => croprow_core::ConfigError::invalid(
            "faults.mount_error",
            format!("the knocked mount is impossible: {field}: {reason}"),
        ),
        other => other,
    })?;
    Ok(cfg)
}

/// The mount a LiDAR casts from.
fn lidar_mount(lidar: &Lidar) -> Mount {
    lidar.config().mount
}

impl Injector {
    /// True when the revolution completed now, with the robot at true x `x_m`, is lost to a dropout.
    fn scan_lost(&mut self, now_s: f64, x_m: f64) -> bool {
        let d = &self.config.lidar_dropout;
        if x_m >= self.next_dropout_x_m {
            self.dropout_until_s = now_s + d.duration_s;
            self.next_dropout_x_m = if d.repeat_every_m > 0.0 {
                // Skip the repeats already passed (a fast robot, a short spacing).
                let k = ((x_m - self.next_dropout_x_m) / d.repeat_every_m).floor() + 1.0;
                self.next_dropout_x_m + k * d.repeat_every_m
            } else {
                f64::INFINITY
            };
        }
        now_s < self.dropout_until_s
    }

    /// The stamp error of a revolution completed with the robot at true x `x_m`, s.
    fn stamp_error_s(&self, x_m: f64) -> f64 {
        let f = &self.config.scan_stamp;
        if f.enabled && x_m >= f.from_x_m && x_m <= f.to_x_m { f.offset_s } else { 0.0 }
    }

    /// Removes the blocked sector and adds spurious returns to a revolution completed at true x `x_m`.
    fn damage_scan(&mut self, x_m: f64, scan: &mut ScanBuffer) {
        let p = &self.config.partial_scan;
        if p.enabled && x_m >= p.from_x_m && x_m <= p.to_x_m {
            let centre = p.sector_centre_deg.to_radians();
            let half = 0.5 * p.sector_width_deg.to_radians();
            let mut kept = 0;
            for i in 0..scan.points.len().min(scan.classes.len()) {
                let q = scan.points[i];
                let az = f64::from(q.y).atan2(f64::from(q.x));
                if wrap_angle(az - centre).abs() > half {
                    scan.points.swap(kept, i);
                    scan.classes.swap(kept, i);
                    kept += 1;
                }
            }
            scan.points.truncate(kept);
            scan.classes.truncate(kept);
        }
        let s = &self.config.spurious_returns;
        if s.enabled && x_m >= s.from_x_m && x_m <= s.to_x_m {
            let to_sensor = self.true_mount.isometry().inverse();
            for _ in 0..s.points_per_scan {
                let b = nalgebra::Point3::new(
                    self.rng.random_range(0.0..=s.ahead_m),
                    self.rng.random_range(-s.half_width_m..=s.half_width_m),
                    self.rng.random_range(s.min_height_m..=s.max_height_m),
                );
                let q = to_sensor.transform_point(&b);
                // Nothing inside the sensor's blind zone comes back.
                if q.coords.norm() < MIN_SPURIOUS_RANGE_M {
                    continue;
                }
                scan.points.push(Point3::new(q.x as f32, q.y as f32, q.z as f32));
                // Not crop, not ground: the scene has no class of its own for clutter.
                scan.classes.push(Class::Weed);
            }
        }
    }

    /// Odometry transport: stamp jitter on both streams, and a wheel message now and then held back
    /// and delivered after a newer one (in a step with no fresh wheel message).
    fn transport(
        &mut self,
        now_s: f64,
        wheel: Option<WheelOdometry>,
        imu: Option<ImuSample>,
    ) -> (Option<WheelOdometry>, Option<ImuSample>) {
        let t = &self.config.odometry_timing;
        if !t.enabled {
            return (wheel, imu);
        }
        let (jitter, p) = (t.jitter_s, t.out_of_order_probability);
        let mut jittered = |stamp: f64| (stamp + self.rng.random_range(-jitter..=jitter)).min(now_s);
        let imu = imu.map(|m| ImuSample { stamp_s: jittered(m.stamp_s), ..m });
        let wheel = wheel.map(|m| WheelOdometry { stamp_s: jittered(m.stamp_s), ..m });
        match wheel {
            Some(m) if self.held_wheel.is_none() && p > 0.0 && self.rng.random_bool(p) => {
                self.held_wheel = Some(m);
                self.newer_wheel_sent = false;
                (None, imu)
            }
            Some(m) => {
                self.newer_wheel_sent = true;
                (Some(m), imu)
            }
            None if self.newer_wheel_sent => (self.held_wheel.take(), imu),
            None => (None, imu),
        }
    }
}

/// Spurious returns closer to the sensor than this are not produced (VLP-16 blind zone), m.
const MIN_SPURIOUS_RANGE_M: f64 = 0.9;

#[cfg(test)]
mod tests {
    use super::*;

    fn short(name: &str, length_m: f64) -> Scenario {
        let mut s = Scenario::builtin(name).unwrap();
        s.field.length_m = length_m;
        s
    }

    #[test]
    fn scans_arrive_at_ten_hertz_stamped_at_the_end_of_the_sweep() {
        let mut w = World::new(&short("young-corn", 8.0)).unwrap();
        let mut stamps = Vec::new();
        for _ in 0..100 {
            if let Some(s) = w.step(Twist2::new(0.5, 0.0)).unwrap().scan {
                stamps.push(s.stamp_s);
                assert_eq!(s.points.len(), s.classes.len());
            }
        }
        assert_eq!(stamps.len(), 10);
        for (k, t) in stamps.iter().enumerate() {
            assert!((t - 0.1 * (k + 1) as f64).abs() < 1e-9, "{t}");
        }
    }

    #[test]
    fn a_non_finite_command_moves_nothing() {
        let mut w = World::new(&short("young-corn", 8.0)).unwrap();
        let before = (w.time_s(), w.robot().pose());
        assert!(w.step(Twist2::new(f64::INFINITY, 0.0)).is_err());
        assert_eq!((w.time_s(), w.robot().pose()), before);
    }

    /// Drives `scenario` straight at 1 m/s for `seconds`, returning (true x, stamp, points) per scan.
    fn scans(scenario: &Scenario, seconds: f64) -> Vec<(f64, f64, Vec<Point3>)> {
        let mut w = World::new(scenario).unwrap();
        let mut out = Vec::new();
        while w.time_s() < seconds {
            if let Some(s) = w.step(Twist2::new(1.0, 0.0)).unwrap().scan {
                out.push((s.truth.pose.x, s.stamp_s, s.points.to_vec()));
            }
        }
        out
    }

    #[test]
    fn a_lidar_dropout_withholds_every_scan_for_its_duration() {
        let mut s = short("young-corn", 12.0);
        s.faults.lidar_dropout = crate::faults::LidarDropout {
            enabled: true,
            from_x_m: 4.0,
            duration_s: 2.0,
            repeat_every_m: 0.0,
        };
        let got = scans(&s, 10.0);
        // 100 revolutions in 10 s; the first one completed past x = 4 m starts 2 s (20 scans) of silence.
        assert_eq!(got.len(), 80);
        let gap = got.windows(2).map(|p| p[1].1 - p[0].1).fold(0.0, f64::max);
        assert!((gap - 2.1).abs() < 1e-6, "{gap}");
        let before_gap = got.windows(2).find(|p| p[1].1 - p[0].1 > 0.15).map(|p| p[0].0);
        assert!(before_gap.is_some_and(|x| x < 4.0), "{before_gap:?}");
    }

    #[test]
    fn a_partial_scan_loses_its_sector_and_spurious_returns_float_above_the_canopy() {
        let mut s = short("young-corn", 12.0);
        s.faults.partial_scan =
            crate::faults::PartialScan { enabled: true, from_x_m: 3.0, to_x_m: 6.0, ..Default::default() };
        s.faults.spurious_returns = crate::faults::SpuriousReturns {
            enabled: true,
            from_x_m: 3.0,
            to_x_m: 6.0,
            ..Default::default()
        };
        let clean = scans(&short("young-corn", 12.0), 5.0);
        let got = scans(&s, 5.0);
        let mount = s.lidar.mount;
        for ((x, _, pts), (_, _, clean_pts)) in got.iter().zip(&clean) {
            let in_sector =
                |p: &&Point3| (0.0..=90.0).contains(&f64::from(p.y).atan2(f64::from(p.x)).to_degrees());
            // Spurious returns: base_link height 0.8-1.4 m, the crop is at most 0.4 m (young corn).
            let high = pts.iter().filter(|p| mount.to_base(**p).z > 0.7).count();
            if (3.0..=6.0).contains(x) {
                // Spurious points may land in the sector; the sensor's own returns may not.
                assert!(pts.iter().filter(in_sector).all(|p| mount.to_base(*p).z > 0.7), "x = {x}");
                assert!(high > 250 && high <= 300, "x = {x}: {high}");
            } else {
                assert_eq!(pts, clean_pts, "x = {x}");
                assert!(clean_pts.iter().filter(in_sector).count() > 1000 && high == 0, "x = {x}: {high}");
            }
        }
    }

    #[test]
    fn a_scan_stamp_error_moves_only_the_stamps_in_its_stretch() {
        let mut s = short("young-corn", 12.0);
        s.faults.scan_stamp =
            crate::faults::ScanStamp { enabled: true, from_x_m: 3.0, to_x_m: 4.0, offset_s: -0.7 };
        for (k, (x, stamp, _)) in scans(&s, 6.0).into_iter().enumerate() {
            let offset = if (3.0..=4.0).contains(&x) { -0.7 } else { 0.0 };
            // Tolerance 1e-9 s: stamp arithmetic only.
            assert!((stamp - (0.1 * (k + 1) as f64 + offset)).abs() < 1e-9, "x = {x}: {stamp}");
        }
    }

    #[test]
    fn a_knocked_mount_changes_the_scans_from_the_knock_on() {
        let mut s = short("young-corn", 12.0);
        s.faults.mount_error =
            crate::faults::MountError { enabled: true, at_x_m: 4.0, pitch_deg: 3.0, ..Default::default() };
        let clean = scans(&short("young-corn", 12.0), 6.0);
        let got = scans(&s, 6.0);
        let mount = s.lidar.mount;
        // Ground returns seen with the nominal mount: a 3° steeper sensor puts them below the ground.
        let ground_z = |pts: &[Point3]| {
            let mut z: Vec<f64> = pts.iter().map(|p| mount.to_base(*p).z).collect();
            z.sort_by(f64::total_cmp);
            z.get(z.len() / 20).copied().unwrap_or(f64::NAN)
        };
        for ((x, _, pts), (_, _, clean_pts)) in got.iter().zip(&clean) {
            if *x < 4.0 {
                assert_eq!(pts, clean_pts, "x = {x}");
            } else if *x > 4.2 {
                // The 5th height percentile (mostly ground 1.5-4 m ahead) drops by decimetres.
                assert!(ground_z(pts) < ground_z(clean_pts) - 0.05, "x = {x}");
            }
        }
    }

    #[test]
    fn odometry_timing_jitters_stamps_and_delivers_some_wheel_messages_late() {
        let mut s = short("young-corn", 12.0);
        s.faults.odometry_timing =
            crate::faults::OdometryTiming { enabled: true, jitter_s: 0.004, out_of_order_probability: 0.1 };
        let mut w = World::new(&s).unwrap();
        let (mut wheel, mut late, mut jittered) = (0, 0, 0);
        let mut newest = f64::NEG_INFINITY;
        while w.time_s() < 20.0 {
            let step = w.step(Twist2::new(0.5, 0.0)).unwrap();
            if let Some(m) = step.wheel {
                wheel += 1;
                late += usize::from(m.stamp_s < newest);
                newest = newest.max(m.stamp_s);
                assert!(m.stamp_s <= step.stamp_s && m.stamp_s > step.stamp_s - 0.05, "{m:?}");
            }
            if let Some(m) = step.imu {
                jittered += usize::from(m.stamp_s != step.stamp_s);
                assert!(m.stamp_s <= step.stamp_s && m.stamp_s >= step.stamp_s - 0.004 - 1e-9);
            }
        }
        // 1000 wheel messages at 50 Hz, about 10 % held back (binomial σ ≈ 9.5): none lost.
        assert_eq!(wheel, 1000);
        assert!((60..=140).contains(&late), "{late}");
        // Half the jitter draws are in the future and are clamped to the delivery time.
        assert!(jittered > 800, "{jittered}");
    }

    #[test]
    fn recovery_starts_off_the_centre_line() {
        let w = World::new(&short("recovery", 10.0)).unwrap();
        let ct = crate::metrics::cross_track(w.field(), w.lane(), &w.robot().pose()).unwrap();
        // 0.3 m and 8° (tolerance 1e-6: placement arithmetic only).
        assert!(
            (ct.lateral_m - 0.3).abs() < 1e-6 && (ct.heading_rad.to_degrees() - 8.0).abs() < 1e-6,
            "{ct:?}"
        );
    }
}
