//! The [`RowDetector`]: checks each step's input, runs the preprocessing and the pipeline of the
//! configured mode, and turns the result into a [`Detection`] with a status.
//!
//! ```
//! use croprow_core::{DetectorConfig, Mount, Pose2, RowDetector, RowStatus, Scan};
//! let mut detector = RowDetector::new(DetectorConfig::default()).unwrap();
//! let d = detector.detect(Scan { stamp_s: 0.0, points: &[], twist: None, attitude: None }, Pose2::default(), &Mount::default());
//! assert_eq!(d.status, RowStatus::InvalidInput); // an empty scan
//! ```

use crate::error::ConfigError;
use crate::geometry::{Mount, Pose2, Twist2, wrap_angle};

use super::config::{DetectorConfig, DetectorMode};
use super::deskew::Deskew;
use super::lanes::Lanes;
use super::map::CentroidMap;
use super::paper::Paper;
use super::preprocess::{PlaneRule, Preprocessor};
use super::register::Register;
use super::{Detection, RowEstimate, RowStatus, Scan, Tilt};

/// Points of a full VLP-16 revolution (16 rings × 1800 azimuths): the preprocessing buffers start at
/// this size so that a live sensor never makes them grow.
const VLP16_POINTS: usize = 28_800;
/// Position and heading slack added to the teleport test (odometry noise between two scans), m / rad.
const JUMP_SLACK_M: f64 = 0.1;
const JUMP_SLACK_RAD: f64 = 0.1;
/// Fastest plausible yaw rate of a field robot, rad/s.
const MAX_YAW_RATE_RPS: f64 = 3.0;
/// Support (full-weight centroids) at which a default-mode row reaches confidence 1.
const FULL_SUPPORT: f64 = 10.0;
/// Distance driven in a lane before its canopy is registered (see `perception::register`), m; a lane
/// found while the robot stood still is registered at once with `register_from_rest`.
const REGISTER_MIN_LANE_M: f64 = 1.0;
/// Odometry twist under which the robot stands still, m/s and rad/s: the wheel encoders' noise at
/// rest, far below a creep.
const REST_SPEED_MPS: f64 = 0.02;
const REST_YAW_RATE_RPS: f64 = 0.02;
/// Confidence of a row that has no support of its own and is placed by its neighbours and the spacing.
const INFERRED_CONFIDENCE: f64 = 0.25;

/// A stage of [`RowDetector::detect`], for the per-stage benchmark (not a stable API).
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Transform, crop, canopy split (both modes).
    Preprocess,
    /// Paper: K-means per depth bin into the map. Default: predict, bin per row, store in the map.
    Cluster,
    /// Paper: first rows and RANSAC. Default: the joint least-squares correction.
    Fit,
}

/// The crop-row detector. Built once from a validated [`DetectorConfig`]; every buffer is allocated in
/// [`RowDetector::new`] (the point buffers for a full VLP-16 scan, the centroid map for
/// `map_capacity` centroids), so [`RowDetector::detect`] does not allocate for scans up to that size.
#[derive(Debug, Clone)]
pub struct RowDetector {
    config: DetectorConfig,
    pre: Preprocessor,
    map: CentroidMap,
    paper: Paper,
    lanes: Lanes,
    /// Canopy registration (`register_enabled`): the lanes run in its `nav` frame.
    register: Register,
    /// The lane hypothesis last seen ([`Lanes::generation`]).
    lane_generation: u32,
    /// The slide watch (`register_rest_watch`): a second registration of a lane found at rest, from
    /// its first keyframe, whose slide feeds [`RowDetector::slide_per_m`] and whose correction is
    /// never applied.
    watch: Register,
    /// The configuration the watch registers with: `register_from_rest` set.
    watch_config: DetectorConfig,
    /// Whether the lane hypothesis last seen was found while the robot stood still: the watch
    /// registers it, and with `register_from_rest` registration does too, from its first keyframe.
    found_at_rest: bool,
    centroids: Vec<[f64; 2]>,
    last: Option<(f64, Pose2)>,
    /// A pose that jumped away from `last`: accepted as the new odometry origin if the next scan agrees.
    pending_jump: Option<(f64, Pose2)>,
    /// When rows were last reported, s (for `Lost`).
    last_rows_s: Option<f64>,
    /// Consecutive scans with too few canopy points (paper end-of-row rule).
    sparse_scans: usize,
}

impl RowDetector {
    /// A detector for `config`, refused when the config is invalid.
    pub fn new(config: DetectorConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            pre: Preprocessor::new(VLP16_POINTS, &config),
            map: CentroidMap::new(config.map_capacity),
            paper: Paper::new(&config),
            lanes: Lanes::new(&config),
            register: Register::new(),
            lane_generation: 0,
            watch: Register::new(),
            watch_config: DetectorConfig { register_from_rest: true, ..config.clone() },
            found_at_rest: false,
            centroids: Vec::with_capacity(config.map_capacity),
            last: None,
            pending_jump: None,
            last_rows_s: None,
            sparse_scans: 0,
            config,
        })
    }

    /// One step: `scan` points in the sensor frame, `odom` = pose of `base_link` in `odom` at
    /// `scan.stamp_s`, `mount` = `base_link -> sensor`. Never panics.
    ///
    /// Returns [`RowStatus::InvalidInput`] with the state untouched for: a non-finite stamp or pose, a
    /// stamp not after the previous one, an implausible mount or attitude (beyond ±0.5 rad, or not
    /// finite), a scan without a finite point, or an
    /// odometry jump faster than `max_speed_mps` (if the next scan confirms the jumped pose, the map is
    /// dropped and detection restarts from it). A gap longer than `max_gap_s` drops the map.
    pub fn detect(&mut self, scan: Scan<'_>, odom: Pose2, mount: &Mount) -> Detection {
        let t = scan.stamp_s;
        let invalid = Detection::empty(t, RowStatus::InvalidInput);
        let upright = scan.attitude.is_none_or(|a| a.is_plausible());
        if !t.is_finite() || !odom.is_finite() || mount.validate().is_err() || !upright {
            return invalid;
        }
        if let Some((last_t, last_pose)) = self.last {
            if t <= last_t {
                return invalid;
            }
            let dt = t - last_t;
            if dt > self.config.max_gap_s {
                self.forget_rows();
            } else if self.jumped(&last_pose, &odom, dt) {
                let confirmed =
                    self.pending_jump.is_some_and(|(pt, pp)| t > pt && !self.jumped(&pp, &odom, t - pt));
                if !confirmed {
                    self.pending_jump = Some((t, odom));
                    return invalid;
                }
                self.forget_rows();
            }
        }
        let deskew = Deskew::new(scan.twist, &self.config);
        if self.pre.run(&scan, mount, &self.config, self.plane_rule(), deskew) == 0 {
            return invalid;
        }
        self.last = Some((t, odom));
        self.pending_jump = None;
        match self.config.mode {
            DetectorMode::Paper => self.detect_paper(t, &odom, mount),
            DetectorMode::Default => self.detect_default(t, &odom, scan.twist, mount),
        }
    }

    /// Runs one stage alone on the buffers of the previous stage, for the per-stage benchmark (not a
    /// stable API; no input checks, no state update beyond the map). Returns a count that depends on the
    /// work done, so that the optimiser cannot drop it.
    #[doc(hidden)]
    pub fn run_stage(&mut self, stage: Stage, scan: Scan<'_>, odom: Pose2, mount: &Mount) -> usize {
        let c = &self.config;
        match (stage, c.mode) {
            (Stage::Preprocess, _) => {
                let deskew = Deskew::new(scan.twist, c);
                self.pre.run(&scan, mount, c, self.plane_rule(), deskew) + self.pre.canopy.len()
            }
            (Stage::Cluster, DetectorMode::Paper) => {
                self.paper.cluster_bins(&self.pre.canopy, mount.x_m, &odom, c, &mut self.map);
                self.map.points().len()
            }
            (Stage::Cluster, DetectorMode::Default) => {
                self.lanes.measure_stage(&self.pre.canopy, &self.pre.cropped, &odom, c, &mut self.map)
            }
            (Stage::Fit, DetectorMode::Paper) => {
                self.paper.fit_stage(&odom, c, &self.map, &mut self.centroids)
            }
            (Stage::Fit, DetectorMode::Default) => {
                self.lanes.correct_stage(&odom, c, &self.map, &mut self.centroids)
            }
        }
    }

    fn plane_rule(&self) -> PlaneRule {
        match self.config.mode {
            DetectorMode::Paper => PlaneRule::Centroid,
            DetectorMode::Default => PlaneRule::Percentile,
        }
    }

    fn jumped(&self, from: &Pose2, to: &Pose2, dt: f64) -> bool {
        let dist = (to.x - from.x).hypot(to.y - from.y);
        let turn = wrap_angle(to.yaw - from.yaw).abs();
        dist > self.config.max_speed_mps * dt + JUMP_SLACK_M || turn > MAX_YAW_RATE_RPS * dt + JUMP_SLACK_RAD
    }

    /// The status when no end of row applies. `rows_out`: rows are reported; `rows_seen`: this scan's
    /// own evidence supports them. Tracking while reported rows were seen within `lost_after_s`, lost
    /// once rows that were seen have not been for longer, searching otherwise.
    fn status_without_end(&mut self, t: f64, rows_out: bool, rows_seen: bool) -> RowStatus {
        if rows_seen {
            self.last_rows_s = Some(t);
        }
        match self.last_rows_s {
            Some(last) if t - last > self.config.lost_after_s => RowStatus::Lost,
            Some(_) if rows_out => RowStatus::Tracking,
            _ => RowStatus::Searching,
        }
    }

    fn detect_paper(&mut self, t: f64, odom: &Pose2, mount: &Mount) -> Detection {
        let rows = self.paper.step(
            &self.pre.canopy,
            mount.x_m,
            odom,
            &self.config,
            &mut self.map,
            &mut self.centroids,
        );
        if self.pre.canopy.len() < self.config.end_min_points {
            self.sparse_scans = self.sparse_scans.saturating_add(1);
        } else {
            self.sparse_scans = 0;
        }
        let has_rows = rows.left.is_some() || rows.right.is_some();
        let status = if self.sparse_scans >= self.config.end_scans {
            RowStatus::EndOfRow
        } else {
            self.status_without_end(t, has_rows, has_rows)
        };
        let spacing = match (rows.left, rows.right) {
            (Some(l), Some(r)) => {
                Some((l.offset_m - r.offset_m) * ((l.heading_rad + r.heading_rad) * 0.5).cos())
            }
            _ => None,
        };
        Detection {
            left: rows.left,
            right: rows.right,
            row_spacing_m: spacing,
            ..Detection::empty(t, status)
        }
    }

    fn detect_default(&mut self, t: f64, odom: &Pose2, twist: Option<Twist2>, mount: &Mount) -> Detection {
        let at_rest = twist.is_some_and(|w| w.v.abs() < REST_SPEED_MPS && w.omega.abs() < REST_YAW_RATE_RPS);
        let nav = if self.config.register_enabled {
            // Registered only against a lane that has held for a while: one found while entering it
            // after a turn may be a lattice that is not the crop's, and its frame jumps while the
            // robot settles onto it. With `register_from_rest`, one found from a standstill (the start
            // of a run) is registered at once: a slide from the first metre would otherwise run
            // unmeasured.
            let from_rest = self.found_at_rest && self.config.register_from_rest;
            let wait_m = if from_rest { 0.0 } else { REGISTER_MIN_LANE_M };
            let direction = self.lanes.row_direction().filter(|_| self.lanes.tracked_for_m() >= wait_m);
            // The returns are already deskewed when the detector deskews; otherwise registration
            // undoes the skew of the returns it registers.
            let skew = Deskew::of_twist(twist.filter(|_| !self.config.deskew), &self.config);
            let row_end = self.lanes.row_end().filter(|_| self.config.register_before_row_end);
            if self.config.register_rest_watch {
                // The watch registers a lane found at rest from its first keyframe, as
                // `register_from_rest` does, but only measures: the lanes keep running in the frame of
                // the registration that waits the metre.
                let watched = self.lanes.row_direction().filter(|_| self.found_at_rest);
                let skew = skew.map(|d| (d, mount));
                self.watch.step(&self.pre.cropped, odom, watched, row_end, skew, &self.watch_config);
            }
            self.register.step(
                &self.pre.cropped,
                odom,
                direction,
                row_end,
                skew.map(|d| (d, mount)),
                &self.config,
            )
        } else {
            *odom
        };
        let out = self.lanes.step(
            &self.pre.canopy,
            &self.pre.cropped,
            &self.pre.holes,
            &nav,
            t,
            &self.config,
            &mut self.map,
            &mut self.centroids,
        );
        let generation = self.lanes.generation();
        if generation != self.lane_generation {
            self.lane_generation = generation;
            self.found_at_rest = at_rest;
        }
        let at_end = out.row_end_ahead_m.is_some_and(|d| d <= self.config.end_trigger_m);
        let Some(lane) = out.lane else {
            let status = if at_end { RowStatus::EndOfRow } else { self.status_without_end(t, false, false) };
            return Detection { row_end_ahead_m: out.row_end_ahead_m, ..Detection::empty(t, status) };
        };
        let row = |k: usize, j: i32| -> RowEstimate {
            let support = out.support.get(k).copied().unwrap_or(0.0);
            let confidence = if support >= 1.0 { support / FULL_SUPPORT } else { INFERRED_CONFIDENCE };
            let far = out.far_x_m.get(k).copied().unwrap_or(0.0);
            lane.row(j, far, if out.updated { confidence } else { INFERRED_CONFIDENCE })
        };
        let (left, right) = (row(0, 0), row(1, -1));
        let status = if at_end { RowStatus::EndOfRow } else { self.status_without_end(t, true, out.updated) };
        let all_finite = left.line.iter().chain(&right.line).all(|v| v.is_finite());
        if status == RowStatus::Lost || !all_finite {
            // Lost means "do not guess": no rows; a non-finite row must never reach the controller.
            let status = if all_finite { status } else { self.status_without_end(t, false, false) };
            return Detection { row_end_ahead_m: out.row_end_ahead_m, ..Detection::empty(t, status) };
        }
        Detection {
            left: Some(left),
            right: Some(right),
            row_spacing_m: Some(lane.spacing_m()),
            row_end_ahead_m: out.row_end_ahead_m,
            ..Detection::empty(t, status)
        }
    }

    fn forget_rows(&mut self) {
        self.map.clear();
        self.lanes.reset();
        self.register.reset();
        self.watch.reset();
        self.centroids.clear();
        self.sparse_scans = 0;
    }

    /// Forgets all rows (e.g. when entering a new lane) and the odometry history; the configuration and
    /// the buffers are kept.
    pub fn reset(&mut self) {
        self.forget_rows();
        self.last = None;
        self.pending_jump = None;
        self.last_rows_s = None;
    }

    /// The configuration this detector runs with.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// The tilt of the surface below the sensor after the last scan (default mode; the paper mode is
    /// never levelled and reports [`LevelStatus::Off`](super::LevelStatus::Off)). Kept
    /// across [`RowDetector::reset`]: it belongs to the mount, not to a lane.
    pub fn tilt(&self) -> Tilt {
        self.pre.level.tilt()
    }

    /// Row centroids of the map in `base_link` at the last scan, m (for markers and plots).
    pub fn centroids(&self) -> &[[f64; 2]] {
        &self.centroids
    }

    /// The sideways slide found at the last scan, m per metre driven, positive when the robot slides to
    /// its left (`base_link` y) unseen by the odometry: canopy registration's while its drift is
    /// significant (with `register_rest_watch`, the larger of it and the slide watch's), else the
    /// slide test's (opt-in, `shear_window_m`); `None` when none found one (or in the paper mode).
    /// See `perception::register` and `perception::lanes`, the slide test.
    pub fn slide_per_m(&self) -> Option<f64> {
        if self.config.register_enabled {
            let watched = self.watch.drift().slide_per_m.filter(|_| self.config.register_rest_watch);
            let measured = match (self.register.drift().slide_per_m, watched) {
                (Some(k), Some(w)) => Some(if w.abs() > k.abs() { w } else { k }),
                (k, w) => k.or(w),
            };
            if measured.is_some() {
                return measured;
            }
        }
        self.lanes.slide_per_m()
    }

    /// The slide the slide watch finds (`register_rest_watch`), m per metre driven as
    /// [`RowDetector::slide_per_m`], with how far the lanes lag it, m: the watch's correction ahead
    /// of the one the lanes run on, across the rows, positive when the lanes trail the slide.
    /// `None` while the watch holds no significant slide (or is off, or no lane is tracked).
    pub fn watched_slide_lag(&self) -> Option<(f64, f64)> {
        if !(self.config.register_enabled && self.config.register_rest_watch) {
            return None;
        }
        let slide = self.watch.drift().slide_per_m.filter(|k| k.is_finite())?;
        let (s, c) = self.lanes.row_direction()?.sin_cos();
        let [wx, wy] = self.watch.drift().correction;
        let [rx, ry] = self.register.drift().correction;
        let lead_left = -s * (wx - rx) + c * (wy - ry);
        Some((slide, lead_left * slide.signum()))
    }
}
