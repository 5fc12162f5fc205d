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

use croprow_core::{Point3, Pose2, Scan, Twist2};

use crate::driver::Driver;
use crate::field::Field;
use crate::lidar::{BodyPose, Lidar, ScanBuffer};
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

/// A completed LiDAR revolution, borrowed from the world until the next step.
#[derive(Debug, Clone, Copy)]
pub struct ScanView<'a> {
    /// Stamp: the time of the last firing of the sweep, s.
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
        Scan { stamp_s: self.stamp_s, points: self.points }
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
    /// Wheel odometry, when one was due.
    pub wheel: Option<WheelOdometry>,
    /// IMU sample, when one was due.
    pub imu: Option<ImuSample>,
    /// A LiDAR revolution, when one completed in this step.
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
}

impl World {
    /// Builds the scenario's world: generates the field and places the robot at its start pose.
    pub fn new(scenario: &Scenario) -> Result<Self, ScenarioError> {
        scenario.validate()?;
        let field = Field::generate(&scenario.field, scenario.seed)?;
        let lane = scenario.lane();
        let x = scenario.start.x_m;
        let th = field.row_heading(x);
        let off = scenario.start.lateral_offset_m;
        let start = Pose2::new(
            x - off * th.sin(),
            field.lane_y(lane, x) + off * th.cos(),
            th + scenario.start.heading_offset_deg.to_radians(),
        );
        let lidar = Lidar::new(&scenario.lidar, scenario.seed ^ SEED_LIDAR)?;
        let robot = Robot::new(&scenario.robot, start, scenario.seed ^ SEED_ROBOT)?;
        Self::from_parts(field, lidar, robot, scenario, lane)
    }

    fn from_parts(
        field: Field,
        lidar: Lidar,
        mut robot: Robot,
        scenario: &Scenario,
        lane: u32,
    ) -> Result<Self, ScenarioError> {
        let dt = scenario.world.dt_s;
        let sensors = Sensors::new(
            &scenario.sensors,
            scenario.robot.effective_track_m(),
            dt,
            scenario.seed ^ SEED_SENSORS,
        )?;
        robot.settle(&field);
        let mut damage = CropDamage::new(&field);
        damage.update(&field, robot.config(), &robot.pose());
        let per_scan = lidar.rays_per_revolution();
        Ok(Self {
            config: scenario.world.clone(),
            field,
            lidar,
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

    /// Advances the world by one time step under `cmd`. A non-finite command is refused and nothing moves.
    pub fn step(&mut self, cmd: Twist2) -> Result<Step<'_>, StepError> {
        let dt = self.config.dt_s;
        self.robot.step(cmd, dt, &self.field)?;
        self.steps += 1;
        let now = self.time_s();
        let wheel = self.sensors.wheel(now, &self.robot);
        let imu = self.sensors.imu(now, &self.robot);
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
            std::mem::swap(&mut self.filling, &mut self.done);
            self.filling.clear();
            self.fired = 0;
            self.sweep_start_s += period;
            completed = true;
        }
        let scan = completed.then(|| ScanView {
            stamp_s: now,
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
