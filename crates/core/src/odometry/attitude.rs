//! Roll and pitch of `base_link` against gravity, from the accelerometer, so that the detector can look
//! at the crop from a level frame.
//!
//! Why: on uneven ground the robot rolls with the slope under its wheels, and the LiDAR with it. Plants
//! grow along gravity, so in the rolled `base_link` a canopy `h` metres up appears `h·sin(roll)` to one
//! side of its stems: 3 cm for a 1 m canopy at 1.7°. The self-levelling of the scan cannot see it (the
//! ground under and ahead of the robot tilts with the robot), and as the roll changes along a row the
//! rows seem to move sideways. In the soak, fault-free seed 1390 (grown corn, 5 cm of relief) followed
//! 12.7 cm off the lane centre on average against 1.3 cm on flat ground, and stopped; with the truth's
//! roll and pitch it followed at 2.2 cm.
//!
//! How: an accelerometer at rest measures the specific force `-g` in body axes (REP-145: +9.81 m/s² on
//! z when level). While driving it adds the body's own acceleration, which the wheels tell: along x the
//! change of speed, along y the centripetal `v·ω`. The force is low-passed with
//! `attitude.time_constant_s` (the centripetal part taken out sample by sample), and the change of
//! speed is taken out of the low-passed force as the derivative of the same low-pass of the speed,
//! `(v - v̄)/τ`: the two low-passes match exactly, and the wheels' noise is not differentiated.
//! Roll is `atan2(f_y, f_z)`, pitch
//! `atan2(-f_x, hypot(f_y, f_z))` (REP-103: positive roll lifts the left, positive pitch the tail).
//! A sample whose specific force is far from gravity (a bump, a jolt) is skipped; an estimate beyond
//! `attitude.max_tilt_deg` is not reported, and one within `attitude.deadband_deg` of level (the
//! accelerometer's bias is of that order) is taken as level.
//!
//! ```
//! use croprow_core::odometry::{AttitudeConfig, AttitudeFilter};
//! use croprow_core::Twist2;
//! let mut filter = AttitudeFilter::new(AttitudeConfig::default()).unwrap();
//! // Standing on a slope that lifts the left side by 2°.
//! let roll = 2f64.to_radians();
//! for k in 0..200 {
//!     let f = [0.0, 9.81 * roll.sin(), 9.81 * roll.cos()];
//!     filter.update(k as f64 * 0.01, f, Twist2::new(0.0, 0.0)).unwrap();
//! }
//! // Reported less the 0.3° deadband (`attitude.deadband_deg`), which keeps the bias out.
//! let a = filter.attitude().unwrap();
//! assert!((a.roll_rad - 1.7f64.to_radians()).abs() < 1e-3 && a.pitch_rad == 0.0);
//! ```

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::error::{ConfigError, check_range};
use crate::geometry::{Attitude, Twist2};

/// Standard gravity, m/s².
const GRAVITY_M_S2: f64 = 9.80665;

/// Settings of the attitude filter (section `attitude`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AttitudeConfig {
    /// Put each scan upright by the accelerometer's roll and pitch; false takes `base_link` as level
    /// (the scans then carry no attitude). Default false, opt-in: it takes fault-free soak seed 1390
    /// (5 cm of relief) from 12.7 cm mean off the lane centre to 2.8 cm, and the soak's relief runs
    /// from 22 to 12 under 8 cm of a stem, but its 1000-run soaks ran over 10 plants in 3 runs and 29
    /// in 7 (the default: 3 in 1 and 2 in 2), most on flat fields, where the accelerometer's
    /// transients leave the deadband (docs/faults.md, session 46).
    pub enabled: bool,
    /// Time constant of the low-pass on the gravity direction, s. Default 0.5: at 100 Hz the
    /// accelerometer's 0.05 m/s² noise leaves about 0.03° on the estimate (computed: the low-pass
    /// keeps a hundredth of a sample's variance), and relief whose wavelength is 6 m or more (a
    /// period of 12 s at 0.5 m/s) is followed about one time constant late (0.25 m of driving).
    pub time_constant_s: f64,
    /// Largest roll or pitch reported, degrees; a larger estimate is not believed. Default 15.
    pub max_tilt_deg: f64,
    /// A roll or pitch within this of level is taken as level, and beyond it only the excess is
    /// reported, degrees. Default 0.3: an accelerometer's bias tilts the estimate by about as much
    /// (the simulated one's 0.02 m/s² by 0.12°), and 0.3° leans a 1 m canopy by 5 mm, under the row
    /// fit's own noise; on flat ground the scans are then left as they are.
    pub deadband_deg: f64,
    /// A sample whose specific force, after the body's acceleration is taken out, differs from
    /// gravity by more than this is skipped (a bump), m/s². Default 2.
    pub max_force_error_m_s2: f64,
    /// Longest time between samples before the filter starts over, s. Default 0.5.
    pub max_gap_s: f64,
}

impl Default for AttitudeConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            time_constant_s: 0.5,
            max_tilt_deg: 15.0,
            deadband_deg: 0.3,
            max_force_error_m_s2: 2.0,
            max_gap_s: 0.5,
        }
    }
}

impl AttitudeConfig {
    /// Checks every field, naming the first bad one (`attitude.time_constant_s`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("attitude.time_constant_s", self.time_constant_s, 0.01, 60.0)?;
        check_range("attitude.max_tilt_deg", self.max_tilt_deg, 0.1, 45.0)?;
        check_range("attitude.deadband_deg", self.deadband_deg, 0.0, 5.0)?;
        check_range("attitude.max_force_error_m_s2", self.max_force_error_m_s2, 0.1, 9.0)?;
        check_range("attitude.max_gap_s", self.max_gap_s, 0.001, 10.0)?;
        Ok(())
    }
}

/// Why a sample was refused; the filter's state is kept.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum AttitudeError {
    /// The stamp is before the previous sample's.
    #[error("time went backwards: accelerometer sample at {stamp_s} s, filter at {filter_s} s")]
    TimeBackwards {
        /// Stamp of the refused sample, s.
        stamp_s: f64,
        /// Stamp of the previous sample, s.
        filter_s: f64,
    },
    /// A stamp, a force or the twist is NaN or infinite.
    #[error("non-finite {what}")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
}

/// The low-passed state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct State {
    stamp_s: f64,
    /// Low-passed specific force with the centripetal acceleration taken out, base_link axes, m/s²;
    /// none until a sample is believed.
    force: Option<[f64; 3]>,
    /// Low-passed forward speed, m/s.
    speed_lp_m_s: f64,
    /// The latest forward speed, m/s.
    speed_m_s: f64,
    /// Time the low-pass has run since it started, s (the estimate is reported after one time constant).
    settled_s: f64,
}

impl State {
    /// The low-passed forward acceleration, m/s²: the low-pass of the speed's derivative is the
    /// derivative of the speed's low-pass, `(v - v̄)/τ`, so the wheels' noise is not differentiated
    /// and the force's low-pass is matched exactly.
    fn forward_m_s2(&self, time_constant_s: f64) -> f64 {
        (self.speed_m_s - self.speed_lp_m_s) / time_constant_s
    }
}

/// Roll and pitch of `base_link` from the accelerometer and the wheels' twist.
#[derive(Debug, Clone)]
pub struct AttitudeFilter {
    config: AttitudeConfig,
    state: Option<State>,
}

impl AttitudeFilter {
    /// A filter with no estimate yet.
    pub fn new(config: AttitudeConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self { config, state: None })
    }

    /// The configuration.
    pub fn config(&self) -> &AttitudeConfig {
        &self.config
    }

    /// Takes one accelerometer sample: the specific force in `base_link` axes (m/s², +9.81 on z when
    /// level and still, as ROS `sensor_msgs/Imu` gives it) and the body twist at its stamp (the
    /// odometry's). A gap longer than `max_gap_s` starts the filter over.
    pub fn update(&mut self, stamp_s: f64, force: [f64; 3], twist: Twist2) -> Result<(), AttitudeError> {
        if !stamp_s.is_finite() {
            return Err(AttitudeError::NonFinite { what: "accelerometer stamp" });
        }
        if !force.iter().all(|f| f.is_finite()) {
            return Err(AttitudeError::NonFinite { what: "specific force" });
        }
        if !(twist.v.is_finite() && twist.omega.is_finite()) {
            return Err(AttitudeError::NonFinite { what: "twist" });
        }
        let tau = self.config.time_constant_s;
        let fresh = State { stamp_s, force: None, speed_lp_m_s: twist.v, speed_m_s: twist.v, settled_s: 0.0 };
        let mut s = match self.state.filter(|s| stamp_s - s.stamp_s <= self.config.max_gap_s) {
            None => fresh,
            Some(s) if stamp_s < s.stamp_s => {
                return Err(AttitudeError::TimeBackwards { stamp_s, filter_s: s.stamp_s });
            }
            Some(s) => s,
        };
        let dt = stamp_s - s.stamp_s;
        let gain = if s.force.is_none() { 1.0 } else { 1.0 - (-dt / tau).exp() };
        s.speed_lp_m_s += gain * (twist.v - s.speed_lp_m_s);
        s.speed_m_s = twist.v;
        s.settled_s += dt;
        s.stamp_s = stamp_s;
        // The centripetal acceleration is known sample by sample; the forward one only low-passed.
        let sample = [force[0], force[1] - twist.v * twist.omega, force[2]];
        let gravity = [sample[0] - s.forward_m_s2(tau), sample[1], sample[2]];
        let norm = gravity.iter().map(|g| g * g).sum::<f64>().sqrt();
        if (norm - GRAVITY_M_S2).abs() <= self.config.max_force_error_m_s2 {
            match s.force.as_mut() {
                None => s.force = Some(sample),
                Some(f) => f.iter_mut().zip(sample).for_each(|(f, x)| *f += gain * (x - *f)),
            }
        }
        self.state = Some(s);
        Ok(())
    }

    /// Roll and pitch of `base_link`, once the filter has run for one time constant and while the
    /// estimate is within `max_tilt_deg`, each less `deadband_deg` towards level; none while both are
    /// within the deadband (level).
    pub fn attitude(&self) -> Option<Attitude> {
        let s = self.state?;
        if s.settled_s < self.config.time_constant_s {
            return None;
        }
        let [fx, fy, fz] = s.force?;
        let fx = fx - s.forward_m_s2(self.config.time_constant_s);
        let a = Attitude { roll_rad: fy.atan2(fz), pitch_rad: (-fx).atan2(fy.hypot(fz)) };
        let bound = self.config.max_tilt_deg.to_radians();
        if a.roll_rad.abs() > bound || a.pitch_rad.abs() > bound {
            return None;
        }
        let deadband = self.config.deadband_deg.to_radians();
        let excess = |t: f64| t - t.clamp(-deadband, deadband);
        let a = Attitude { roll_rad: excess(a.roll_rad), pitch_rad: excess(a.pitch_rad) };
        (a != Attitude::default()).then_some(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The specific force of a body at `roll`, `pitch` accelerating by `accel` (base_link x, y).
    fn force(roll: f64, pitch: f64, accel: [f64; 2]) -> [f64; 3] {
        let r = nalgebra::Rotation3::from_euler_angles(roll, pitch, 0.0);
        let level = nalgebra::Vector3::new(accel[0], accel[1], GRAVITY_M_S2);
        // Body axes of a force given in the heading-aligned level frame.
        let f = r.inverse() * level;
        [f.x, f.y, f.z]
    }

    fn settle(filter: &mut AttitudeFilter, f: [f64; 3], twist: Twist2, from_s: f64, seconds: f64) {
        for k in 0..(seconds * 100.0) as usize {
            filter.update(from_s + k as f64 * 0.01, f, twist).unwrap();
        }
    }

    /// A filter without a deadband, whose estimate is the accelerometer's own.
    fn exact() -> AttitudeFilter {
        AttitudeFilter::new(AttitudeConfig { deadband_deg: 0.0, ..AttitudeConfig::default() }).unwrap()
    }

    #[test]
    fn a_still_robot_on_a_slope_reads_its_roll_and_pitch() {
        let mut filter = exact();
        assert_eq!(filter.attitude(), None);
        let (roll, pitch) = (3f64.to_radians(), -2f64.to_radians());
        settle(&mut filter, force(roll, pitch, [0.0, 0.0]), Twist2::default(), 0.0, 3.0);
        let a = filter.attitude().unwrap();
        assert!((a.roll_rad - roll).abs() < 1e-6 && (a.pitch_rad - pitch).abs() < 1e-6, "{a:?}");
    }

    #[test]
    fn a_turn_and_a_speed_change_are_not_a_tilt() {
        let mut filter = exact();
        // On a 1° side slope, turning left at 0.5 m/s and 0.4 rad/s: 0.2 m/s² centripetal, which read
        // as gravity would add 1.2° of roll.
        let roll = 1f64.to_radians();
        let twist = Twist2::new(0.5, 0.4);
        settle(&mut filter, force(roll, 0.0, [0.0, 0.2]), twist, 0.0, 3.0);
        let a = filter.attitude().unwrap();
        assert!((a.roll_rad - roll).abs() < 1e-4 && a.pitch_rad.abs() < 1e-6, "{a:?}");
        // Speeding up at 0.5 m/s² for 2 s: an uncompensated pitch of 2.9°.
        for k in 0..200 {
            let t = 3.0 + k as f64 * 0.01;
            let v = 0.5 + 0.5 * k as f64 * 0.01;
            filter.update(t, force(roll, 0.0, [0.5, 0.0]), Twist2::new(v, 0.0)).unwrap();
        }
        let a = filter.attitude().unwrap();
        // The speed's low-passed derivative matches the force's low-pass: the acceleration cancels, up
        // to the discrete filters' difference (a·dt/2τ, 1 % of it at 100 Hz).
        assert!(a.pitch_rad.abs() < 0.05f64.to_radians() && (a.roll_rad - roll).abs() < 1e-4, "{a:?}");
    }

    #[test]
    fn a_jolt_is_skipped_and_a_tilt_beyond_the_bound_is_not_reported() {
        let mut filter = exact();
        settle(&mut filter, force(0.01, 0.0, [0.0, 0.0]), Twist2::default(), 0.0, 1.0);
        filter.update(1.0, [0.0, 0.0, 25.0], Twist2::default()).unwrap();
        assert!((filter.attitude().unwrap().roll_rad - 0.01).abs() < 1e-9);
        settle(&mut filter, force(0.5, 0.0, [0.0, 0.0]), Twist2::default(), 1.01, 5.0);
        assert_eq!(filter.attitude(), None);
    }

    #[test]
    fn bad_samples_are_refused_and_a_gap_starts_over() {
        let mut filter = exact();
        settle(&mut filter, force(0.02, 0.0, [0.0, 0.0]), Twist2::default(), 0.0, 1.0);
        let before = filter.attitude();
        let e = filter.update(0.5, [0.0, 0.0, 9.8], Twist2::default()).unwrap_err();
        assert!(matches!(e, AttitudeError::TimeBackwards { .. }), "{e}");
        let e = filter.update(1.0, [f64::NAN, 0.0, 9.8], Twist2::default()).unwrap_err();
        assert!(e.to_string().contains("non-finite specific force"), "{e}");
        assert!(filter.update(1.0, [0.0, 0.0, 9.8], Twist2::new(f64::INFINITY, 0.0)).is_err());
        assert_eq!(filter.attitude(), before);
        // A second of silence: the next sample starts over, and reports after one time constant.
        filter.update(2.0, force(0.0, 0.0, [0.0, 0.0]), Twist2::default()).unwrap();
        assert_eq!(filter.attitude(), None);
    }

    #[test]
    fn a_tilt_within_the_deadband_is_level_and_beyond_it_only_the_excess_counts() {
        let mut filter = AttitudeFilter::new(AttitudeConfig::default()).unwrap();
        settle(
            &mut filter,
            force(0.2f64.to_radians(), -0.25f64.to_radians(), [0.0, 0.0]),
            Twist2::default(),
            0.0,
            3.0,
        );
        assert_eq!(filter.attitude(), None);
        settle(
            &mut filter,
            force(2f64.to_radians(), -0.2f64.to_radians(), [0.0, 0.0]),
            Twist2::default(),
            3.0,
            5.0,
        );
        let a = filter.attitude().unwrap();
        assert!((a.roll_rad - 1.7f64.to_radians()).abs() < 1e-5 && a.pitch_rad == 0.0, "{a:?}");
    }

    #[test]
    fn absurd_settings_name_the_field() {
        let cfg = AttitudeConfig { time_constant_s: f64::NAN, ..AttitudeConfig::default() };
        let e = AttitudeFilter::new(cfg).unwrap_err().to_string();
        assert!(e.contains("attitude.time_constant_s"), "{e}");
    }
}
