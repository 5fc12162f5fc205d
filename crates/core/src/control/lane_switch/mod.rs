//! Lane switching: the mission state machine that follows a lane, clears the row end, turns in the
//! headland onto the next lane, confirms it with the detector and follows it, until the requested
//! number of lanes is done.
//!
//! Where it sits: between the detector and the MPC. Each control step it takes the `odom` pose and,
//! when a scan came in, its [`Detection`]; it returns a [`Guidance`] (mode, speed, whether the
//! detector must be reset) and exposes the [`Path`] the MPC must track.
//!
//! ```text
//! Acquiring ─rows─► Following ─row end reached─► ClearingRowEnd ─wheels clear─► Turning ─turn done─► Entering
//!                       ▲                               │ last lane                                   │
//!                       └──────────── new lane confirmed by the detector, robot aligned ──────────────┘
//!                                                       ▼
//!                                                      Done
//! Following: rows Lost, or no row for `max_blind_distance_m`, farther than `end_approach_m`
//!            from a row end the detector has seen ─► Stopped { RowsLost | NoRows }
//!            ─► `resume_confirmations` consecutive detections of the lane followed before ─► Following
//! Always:    rows at a spacing over `spacing_tolerance` off `row_spacing_m` are not believed (no row)
//! Following: a centre line over `max_line_jump_m` from the one followed is not believed (no row)
//! ClearingRowEnd: the rows turned in `odom` ─► stand still for `bias_dwell_s` first (gyro bias)
//! Following: the rows turned in `odom` ─► stand still for `bias_dwell_s` (`row_bias_stands` per
//!            lane, opt-in)
//! Following, Stopped: rows over `following_spacing_tolerance` off `row_spacing_m` are not believed
//! Entering:  rows disagree with the planned lane ─► Stopped { WrongLane };
//!            too deep into the field unconfirmed ─► Stopped { ReentryNotConfirmed }
//! Following, ClearingRowEnd: crop past the row end beyond an empty stretch ─► Following (a gap; opt-in)
//! Turning, at the first pivot: crop past the row end ─► Stopped { CropPastRowEnd }
//! Following, ClearingRowEnd: the row end recedes with the robot ─► Stopped { RowEndReceding }
//! Following: the MPC plans no forward motion for 2 s ─► Stopped { NoSafeMotion } (the navigator)
//! Following: the detector measures `odom` sliding `max_slide_per_m` or more ─► Stopped { Sliding } (the navigator)
//! ```
//!
//! # The headland turn and what is bounded
//! Beyond the paper's open-loop PID turns (Sec. III-B), the turn is a path in `odom` tracked by the
//! same MPC. With `r = 0` (the default: a skid-steer turns on the spot) the robot brakes to a stop at
//! the first pivot on the lane's centre line, turns in place until it heads along the straight to the
//! second pivot on the next lane's centre line, `shift = 2 · spacing · lane_step` to the side, stops
//! and pivots again into the next lane. A pivot is a corner of the path; the MPC tracks the leg after
//! it with zero cruise speed, so it turns on the spot under the same bounds on ω and ω̇. The spacing
//! is the planted one, `row_spacing_m` (see [`LaneSwitcher::spacing_m`]). With `r > 0` the pivots
//! become quarter arcs of radius `r` on a square headland.
//!
//! Where the pivots stand comes from the measured geometry ([`crate::control::headland`]): while
//! following, the detector's mapped row centroids are sorted into rows about the centre line and the
//! farthest of each row is kept; each row is taken to end `row_end_allowance_m` past it (rows the
//! detector did not map follow the line through the measured ends). Each pivot stands where the
//! circle its farthest tyre-patch corner sweeps (`ρ = √((wheel_x + l/2)² + (wheel_y + w/2)²)`) misses
//! every row end by `clearance_margin_m` plus the odometry drift (`odometry_drift_fraction` of the
//! blind distance from where the plants were last seen, `default_row_end_ahead_m` ahead), the
//! second also allowing that drift sideways over the shift. The two pivots may stand at different
//! distances (rows ending on a skewed or ragged line); the straight between them keeps its patches
//! past the rows it crosses. A pivot turn never starts nearer than on a square headland
//! ([`LaneSwitchConfig::turn_start_m`]: 1.34 m with the Amiga-like defaults, the second pivot
//! binding); when the measured ends need more than `max_headland_excursion_m`, the robot stops
//! (`no_room_to_turn`) instead. The planned maximum of `d`, the along-row distance of `base_link`
//! past the row end, is checked at construction for the square headland.
//!
//! A gyro bias error the EKF has not learnt turns `odom` while the robot follows the rows, and the
//! pivots, driven blind for 10-15 s, would turn by it too. The rows show it: their direction in
//! `odom` turns (`bias_suspect_rad_per_m`, over the latest 2 m). Then the robot brakes where it starts
//! to clear the row end and stands still for `bias_dwell_s`, the command held at zero
//! ([`Guidance::hold`]), so that the EKF finds the bias at rest (`ekf.bias_check_rest_s`). The stand
//! is timed with the stamps given by [`LaneSwitcher::set_time`].
//!
//! After the turn the detector is reset and must confirm the new lane: until one detection agrees
//! with the plan, the robot drives on odometry alone, and its front tyres stop `clearance_margin_m`
//! short of the new lane's row ends (`reentry_not_confirmed`).
//!
//! The row end comes from the detector: where the canopy of the lane ends, to the resolution of its
//! map bins, which places it up to a bin plus the leaves' overhang past the last plant. When the
//! farthest centroid of the lane's rows lies within `row_end_window_m` before that edge, the row end
//! is put at that centroid instead: the centre of the last plants' canopy, a better estimate of where
//! the stems end.
//!
//! # A row end is not final until the headland past it is seen empty
//! A stretch missing from every row (or rows hidden by a missing scan sector) looks like the row end
//! from afar. The detector's map keeps mapping the lane's rows as the robot drives on; with the gap
//! rule on (`gap_confirmations` > 0; 3 by default, see that field), when on `gap_confirmations`
//! scans in a row crop stands on `gap_rows` of the lane's rows and their outer neighbours more than
//! `gap_margin_m` past the end's canopy, beyond an empty stretch, and stays where it is while the
//! robot drives 0.5 m towards it, and the detector tracks the rows and does not confirm the end, the
//! end was a gap:
//! * while following or clearing the row end, it is dropped and the robot follows on across the
//!   gap on the lane's rows (which the detector still tracks: that is part of the evidence);
//! * once the first pivot has begun (heading still within 0.5 rad of the lane, the scan looking past
//!   the end), the robot stops, `crop_past_row_end`: it stands in the gap off the lane's heading, and
//!   the lane is not counted as done. Later in the turn the scan looks across the headland, and the
//!   robot has left the lane.
//!
//! The scan reaches about 4.3 m ahead of `base_link` (the detector's 4 m range from a sensor 1.5 m
//! up), so from the first pivot, 1.3-1.5 m past the end, it sees 5.6-5.8 m past it: a gap longer
//! than that is indistinguishable from the headland, and the robot turns (or ends the mission) in it.
//!
//! A row end is a place. The first end reported on a lane anchors it; an end reported more than
//! `max_end_recession_m` past the anchor is not taken, and `end_recession_scans` of those stop the
//! robot (`row_end_receding`): an end that keeps its distance ahead of the robot is canopy seen
//! everywhere (a tilted LiDAR reading the ground as crop past the rows), and the rows followed there
//! are not rows. A gap (above) starts the anchor over.

use std::f64::consts::{FRAC_PI_2, PI};

use serde::{Deserialize, Serialize};

use crate::control::headland::{PivotPlan, RowEnds, rows_past_end};
use crate::control::path::{Path, Segment};
use crate::control::reference::{Reference, ReferenceConfig};
use crate::error::ConfigError;
use crate::geometry::{Pose2, wrap_angle};
use crate::perception::{Detection, RowStatus};

mod config;

pub use config::{LaneSwitchConfig, TurnDirection};

/// How far ahead of the robot a new centre line is checked against the one followed, m (see
/// `LaneSwitchConfig::max_line_jump_m`): about where the MPC's 2 s horizon at cruise speed ends.
const LINE_CHECK_AHEAD_M: f64 = 1.5;
/// Length of the detector's map bins, m: a centroid up to one bin past the reported canopy end still
/// belongs to the last plants.
const ROW_END_BIN_M: f64 = 0.25;
/// The rows whose crop past a row end makes it a gap: the lane's two and their outer neighbours, the
/// rows the detector ends a lane on (`q` as in [`RowEnds`]).
const GAP_ROWS: std::ops::RangeInclusive<i32> = -2..=1;
/// Distance the robot must drive towards crop past a row end, which must stay where it is meanwhile,
/// before the end is taken for a gap, m: two map bins. A pitched LiDAR's phantom canopy at the scan's
/// far edge moves out as far as the robot drives.
const GAP_TRAVEL_M: f64 = 0.5;
/// Largest heading change at the first pivot, rad, up to which crop past the row end still stops the
/// turn: beyond it the scan looks across the headland, not along the lane.
const GAP_PIVOT_RAD: f64 = 0.5;
/// Weight of each scan's row spacing in the running mean the turns use: about the last 20 scans
/// (2 m at cruise speed).
const SPACING_GAIN: f64 = 0.05;

/// Why the robot stopped. A stop whose cause can clear by itself ([`StopReason::clears_by_itself`]:
/// rows lost, no rows) ends when the detector tracks the same lane again for
/// `lane_switch.resume_confirmations` scans; every other stop is latched until [`LaneSwitcher::resume`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The detector reported the rows lost in the middle of a lane.
    RowsLost,
    /// No row was seen for `max_blind_distance_m` while following.
    NoRows,
    /// The new lane was not confirmed before `base_link` went `max_unconfirmed_entry_m` into the field.
    ReentryNotConfirmed,
    /// The rows seen when entering are not the planned lane: a lane would be skipped or repeated; or,
    /// while following, the rows turned off the lane's direction faster than crop rows bend
    /// (`entry_heading_watch_m`, `max_row_turn_rad`).
    WrongLane,
    /// The odometry pose was not finite.
    InvalidOdometry,
    /// The MPC failed (non-finite numbers or solver error); set by the caller.
    SolverFailed,
    /// The measured row ends leave no room for a contact-free turn within
    /// `max_headland_excursion_m`.
    NoRoomToTurn,
    /// Crop appeared past the row end once the robot had started to pivot there: the end was a gap in
    /// the rows. The robot stands in the gap, off the lane's heading; a person decides (the same lane
    /// again after [`LaneSwitcher::resume`], or the turn).
    CropPastRowEnd,
    /// The row end the detector reports kept moving away ahead of the robot, more than
    /// `max_end_recession_m` past where it was first seen: the canopy it sees does not end (a tilted
    /// LiDAR reading the ground as crop), so neither the row end nor the rows can be trusted.
    RowEndReceding,
    /// While following, the MPC planned no forward motion for 2 s: every way on puts a tyre over a row
    /// (a sideways slide the body must crab against in a narrow lane); set by the caller. A person
    /// decides.
    NoSafeMotion,
    /// While following, the detector measured `odom` drifting sideways against the canopy by
    /// `max_slide_per_m` or more (a wheel slide, or an unlearnt gyro bias): the row map carried by the
    /// odometry lags such a drift; set by the caller. A person decides.
    Sliding,
}

impl StopReason {
    /// True for the stops that end by themselves once the rows are tracked again (`RowsLost`,
    /// `NoRows`: a sensor dropout, clutter, a gap in the rows). A wrong lane, an unconfirmed re-entry,
    /// bad odometry and a solver failure need a person (or [`LaneSwitcher::resume`]).
    pub fn clears_by_itself(&self) -> bool {
        matches!(self, StopReason::RowsLost | StopReason::NoRows)
    }

    /// Stable lower-case name.
    pub fn as_str(&self) -> &'static str {
        match self {
            StopReason::RowsLost => "rows_lost",
            StopReason::NoRows => "no_rows",
            StopReason::ReentryNotConfirmed => "reentry_not_confirmed",
            StopReason::WrongLane => "wrong_lane",
            StopReason::InvalidOdometry => "invalid_odometry",
            StopReason::SolverFailed => "solver_failed",
            StopReason::NoRoomToTurn => "no_room_to_turn",
            StopReason::CropPastRowEnd => "crop_past_row_end",
            StopReason::RowEndReceding => "row_end_receding",
            StopReason::NoSafeMotion => "no_safe_motion",
            StopReason::Sliding => "sliding",
        }
    }
}

/// What the robot is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "mode")]
pub enum Mode {
    /// Waiting (stopped) for the detector's first rows.
    Acquiring,
    /// Following the centre line of the detected rows.
    Following,
    /// The row end is reached: driving straight on until every wheel is past it.
    ClearingRowEnd,
    /// Tracking the headland turn towards the next lane.
    Turning,
    /// On the straight into the next lane, waiting for the detector to confirm it.
    Entering,
    /// Every requested lane is driven: stopped.
    Done,
    /// Stopped for safety.
    Stopped {
        /// Why.
        reason: StopReason,
    },
}

impl Mode {
    /// Stable lower-case name.
    pub fn as_str(&self) -> &'static str {
        match self {
            Mode::Acquiring => "acquiring",
            Mode::Following => "following",
            Mode::ClearingRowEnd => "clearing_row_end",
            Mode::Turning => "turning",
            Mode::Entering => "entering",
            Mode::Done => "done",
            Mode::Stopped { .. } => "stopped",
        }
    }

    /// True when the robot must not move (zero command).
    pub fn is_stopped(&self) -> bool {
        matches!(self, Mode::Acquiring | Mode::Done | Mode::Stopped { .. })
    }
}

/// The state machine's answer for one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Guidance {
    /// Current mode.
    pub mode: Mode,
    /// Cruise speed for the MPC along [`LaneSwitcher::path`], m/s; 0 when stopped or pivoting, and
    /// braking (at `stop_decel_mps2`) towards a pivot or the end of the mission.
    pub speed_mps: f64,
    /// True on the step the caller must reset the detector (its row memory belongs to the old lane).
    pub reset_detector: bool,
    /// Lanes whose row end has been cleared.
    pub lanes_completed: u32,
    /// Index of the current lane (see [`LaneSwitchConfig::start_lane`]).
    pub lane: u32,
    /// True while the robot must stand still (zero command) without being stopped: the dwell at a row
    /// end that lets the odometry learn a gyro bias at rest (`bias_dwell_s`).
    pub hold: bool,
}

/// The stand at a row end for the gyro bias (see `LaneSwitchConfig::bias_dwell_s`).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Dwell {
    /// No stand due.
    Off,
    /// Braking to a stop.
    Braking,
    /// Standing still since this stamp, s.
    Holding(f64),
}

/// The lane-switching state machine. Its paths are allocated once, in [`LaneSwitcher::new`].
#[derive(Debug, Clone)]
pub struct LaneSwitcher {
    cfg: LaneSwitchConfig,
    reference: Reference,
    turn: Path,
    mode: Mode,
    s_hint_m: f64,
    /// A pose on the centre line at the row end of the current lane, heading along the row (`odom`).
    row_end: Option<Pose2>,
    /// The row end being turned at (`odom`), from the start of the turn until the next lane is confirmed.
    exit_line: Option<Pose2>,
    last_pose: Option<Pose2>,
    blind_m: f64,
    turn_index: u32,
    lanes_completed: u32,
    lane: u32,
    agree: u32,
    disagree: u32,
    /// Consecutive detections of the stopped-at lane, towards an automatic resume.
    resume_agree: u32,
    /// Stamp since which the robot has stood still in a stop that clears by itself, s.
    stop_rest_since_s: Option<f64>,
    max_excursion_m: f64,
    /// Turning on the spot at the start of the turn path's first leg.
    pivoting: bool,
    /// How far the row end lies before the detector's canopy end (see `row_end_window_m`), m.
    end_trim_m: f64,
    /// The farthest canopy seen on each row of the current lane (`odom`).
    row_ends: RowEnds,
    /// Row spacing measured by the detector along the lanes so far (a running mean), m.
    measured_spacing_m: Option<f64>,
    /// The pivots planned at the current row end, once it is known (pivot turns only).
    pivots: Option<PivotPlan>,
    /// Along-row distance past the exit line of the new lane's row ends, m (for the entry stop).
    entry_row_end_m: f64,
    /// True once a detection agreed with the planned lane and the entry follows the rows seen.
    entry_anchored: bool,
    /// The planned direction of the new lane's rows (`odom`, rad: the turned-at lane's, reversed) and,
    /// once it is followed, the odometer reading where that began: see `entry_heading_watch_m`.
    entry_heading: Option<(f64, Option<f64>)>,
    /// Consecutive scans that showed crop past the row end (see `gap_confirmations`).
    crop_past_end: u32,
    /// The near edge of that crop past the end and where the robot was, m along past the end, at the
    /// first of those scans.
    gap_seen_from: Option<(f64, f64)>,
    /// Where the current row end was first seen (`odom`): the end is a place.
    end_anchor: Option<Pose2>,
    /// Row ends reported past `max_end_recession_m` from the anchor.
    receding: u32,
    /// The latest stamp given by [`LaneSwitcher::set_time`], s.
    now_s: Option<f64>,
    /// Distance driven while following, m, and the followed rows' direction in `odom` (rad) every
    /// `ROW_HEADING_STEP_M` of it, newest first; `row_headings_len` of them are valid.
    odometer_m: f64,
    row_headings: [(f64, f64); ROW_HEADINGS],
    row_headings_len: usize,
    /// The rows turned in `odom` over the latest 2 m followed faster than `bias_suspect_rad_per_m`.
    bias_suspect: bool,
    /// Odometer reading where the current run of `bias_suspect` began, m.
    bias_suspect_since_m: Option<f64>,
    /// `bias_suspect` held for `BIAS_HOLD_M` on end at some point since the lane was entered or the
    /// last stand: it also decides the stand at the row end. A bias error stays until the robot stands
    /// still, but the rows' turn in `odom` need not: a fit that takes part of it for a sideways slide
    /// (the slide test) straightens them again (soak seed 699: suspected over 5 m in mid-lane, not at
    /// its end). Short runs of suspicion (a fit's wobble, 0.5-1.5 m on fault-free seed 765) do not count.
    bias_suspected_in_lane: bool,
    /// Stands for a suspected bias left in this lane (`row_bias_stands`).
    bias_stands_left: u32,
    /// Consecutive row-direction measurements (one per [`ROW_HEADING_STEP_M`]) whose turn over
    /// [`ROW_TURN_WINDOW_M`] exceeded `max_row_turn_rad`, signed by the turn's direction.
    rows_turning: i32,
    dwell: Dwell,
}

/// Distance over which the followed rows' turn in `odom` is measured for the bias suspicion, m: a
/// fit's heading wobbles by about 0.01 rad, so over 2 m the rate is good to 0.005-0.007 rad/m.
const BIAS_SUSPECT_WINDOW_M: f64 = 2.0;
/// Distance over which the followed rows' turn in `odom` is held to `max_row_turn_rad`, m: a fit that
/// took up weeds turned 0.14-0.15 rad within it (soak seeds 324 and 680), while a fit's heading wobbles
/// by about 0.01 rad.
const ROW_TURN_WINDOW_M: f64 = 1.0;
/// Consecutive measurements past `max_row_turn_rad`, the same way round, that stop the robot.
const ROW_TURN_SAMPLES: i32 = 2;
/// Shortest stretch of rows, m, over which their turn in `odom` before a stop counts for the rest
/// at the stop (`resume_rest_s`): half the suspicion's window.
const SHORT_SUSPECT_WINDOW_M: f64 = 1.0;
/// Distance a bias suspicion must hold without a break to count at the row end after it lapsed, m.
const BIAS_HOLD_M: f64 = 2.5;
/// Spacing of the row directions kept for it, m, and how many are kept (the window and one more).
const ROW_HEADING_STEP_M: f64 = 0.25;
const ROW_HEADINGS: usize = 9;
/// Largest distance per update that counts as standing still, m (1 cm/s at 10 Hz).
const REST_STEP_M: f64 = 1e-3;

impl LaneSwitcher {
    /// Validates both configurations.
    pub fn new(cfg: LaneSwitchConfig, reference: ReferenceConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(Self {
            reference: Reference::new(reference)?,
            turn: Path::with_capacity(4),
            mode: Mode::Acquiring,
            s_hint_m: 0.0,
            row_end: None,
            exit_line: None,
            last_pose: None,
            blind_m: 0.0,
            turn_index: 0,
            lanes_completed: 0,
            lane: cfg.start_lane,
            agree: 0,
            disagree: 0,
            resume_agree: 0,
            stop_rest_since_s: None,
            max_excursion_m: 0.0,
            pivoting: false,
            end_trim_m: 0.0,
            row_ends: RowEnds::default(),
            measured_spacing_m: None,
            pivots: None,
            entry_row_end_m: 0.0,
            entry_anchored: false,
            entry_heading: None,
            crop_past_end: 0,
            gap_seen_from: None,
            end_anchor: None,
            receding: 0,
            now_s: None,
            odometer_m: 0.0,
            row_headings: [(0.0, 0.0); ROW_HEADINGS],
            row_headings_len: 0,
            bias_suspect: false,
            bias_suspect_since_m: None,
            bias_suspected_in_lane: false,
            bias_stands_left: 0,
            rows_turning: 0,
            dwell: Dwell::Off,
            cfg,
        })
    }

    /// Gives the stamp of the next [`LaneSwitcher::update`], s: the dwell at a row end is timed with
    /// it. Without stamps (never called, or a non-finite one) the robot never stands there.
    pub fn set_time(&mut self, stamp_s: f64) {
        self.now_s = Some(stamp_s).filter(|t| t.is_finite());
    }

    /// True when the rows turned in `odom` over the latest 2 m followed (see
    /// `LaneSwitchConfig::bias_suspect_rad_per_m`).
    pub fn bias_suspected(&self) -> bool {
        self.bias_suspect
    }

    /// The configuration.
    pub fn config(&self) -> &LaneSwitchConfig {
        &self.cfg
    }

    /// Current mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The path the MPC must track in the current mode (`odom`), or `None` when stopped.
    pub fn path(&self) -> Option<&Path> {
        match self.mode {
            Mode::Following | Mode::ClearingRowEnd => self.reference.path(),
            Mode::Turning | Mode::Entering => Some(&self.turn),
            _ => None,
        }
    }

    /// Progress along [`LaneSwitcher::path`] at the last step, m: the projection hint.
    pub fn progress_m(&self) -> f64 {
        self.s_hint_m
    }

    /// Lanes whose row end has been cleared.
    pub fn lanes_completed(&self) -> u32 {
        self.lanes_completed
    }

    /// Index of the current lane (see [`LaneSwitchConfig::start_lane`]).
    pub fn lane(&self) -> u32 {
        self.lane
    }

    /// Largest distance `base_link` went past a row-end line so far, m.
    pub fn max_excursion_m(&self) -> f64 {
        self.max_excursion_m
    }

    /// The row-end pose of the current lane in `odom`, once known; during a turn, the row end
    /// being turned at.
    pub fn row_end(&self) -> Option<Pose2> {
        match self.mode {
            Mode::Turning | Mode::Entering => self.exit_line,
            _ => self.row_end,
        }
    }

    /// Feeds the row centroids the detector mapped at this scan (`base_link` at `odom`, m; e.g.
    /// [`crate::perception::RowDetector::centroids`]) with the scan's detection. While a lane is
    /// followed, the farthest one of each row tells where that row ends, and the headland turn is
    /// planned against those ends (see [`crate::control::headland`]); without them every row is taken
    /// to end at the lane's row end. Only scans that see the canopy end count (the last plants are
    /// in view from about 3 m before it), and only centroids up to one `ROW_END_BIN_M` past that end:
    /// beyond it they are not plants of the lane's rows (ground seen through a mis-pitched sensor,
    /// clutter in the headland).
    ///
    /// Before the turn and at the start of its first pivot, the same centroids tell whether crop stands
    /// past the row end being driven to (see `gap_confirmations` and the module docs).
    pub fn observe_canopy(&mut self, odom: &Pose2, detection: &Detection, centroids: &[[f64; 2]]) {
        if !odom.is_finite() {
            return;
        }
        self.observe_past_end(odom, detection, centroids);
        if self.mode != Mode::Following {
            return;
        }
        let Some(reach) = detection.row_end_ahead_m.filter(|a| a.is_finite()).map(|a| a + ROW_END_BIN_M)
        else {
            return;
        };
        let spacing = self.spacing_m();
        let hint = self.s_hint_m;
        let Some(path) = self.reference.path() else { return };
        let points = centroids.iter().filter(|c| c[0] <= reach).map(|c| odom.transform_point(c[0], c[1]));
        self.row_ends.observe(spacing, points, |x, y| {
            let f = path.project(&Pose2::new(x, y, 0.0), hint);
            (f.s_m, f.lateral_m)
        });
    }

    /// Counts the consecutive scans that show crop past the row end being driven to, or pivoted at:
    /// the detector tracks the rows, its own row end (if any) lies past that end too, and the mapped
    /// centroids stand on `gap_rows` of the lane's rows and their outer neighbours more than
    /// `gap_margin_m` past the canopy end. Any other scan restarts the count.
    fn observe_past_end(&mut self, odom: &Pose2, detection: &Detection, centroids: &[[f64; 2]]) {
        let end = match self.mode {
            Mode::Following | Mode::ClearingRowEnd => self.row_end,
            Mode::Turning if self.at_first_pivot(odom) => self.exit_line,
            _ => None,
        };
        let Some(end) = end.filter(|_| detection.status == RowStatus::Tracking) else {
            self.crop_past_end = 0;
            return;
        };
        // The row end was moved back from the detector's canopy end by `end_trim_m`. The last plants'
        // centroids may lie up to a map bin past that canopy end; the detector saw the ground empty for
        // `gap_margin_m` past it to call the end, so crop appearing there now is not believed (a
        // tilted LiDAR reads the ground there as canopy once the robot nears it).
        let clear_m = self.end_trim_m + ROW_END_BIN_M;
        let past_m = self.end_trim_m + self.cfg.gap_margin_m;
        let confirmed = detection
            .row_end_ahead_m
            .filter(|a| a.is_finite())
            .is_some_and(|a| along(&end, &self.end_from(odom, a)) <= past_m);
        let points = centroids.iter().map(|c| odom.transform_point(c[0], c[1]));
        let (rows, near_m) = rows_past_end(self.spacing_m(), &end, clear_m, past_m, GAP_ROWS, points);
        let at_m = along(&end, odom);
        if confirmed || rows < self.cfg.gap_rows {
            self.crop_past_end = 0;
            return;
        }
        // Crop that keeps its distance ahead of the robot is no place (the ground at the scan's far
        // edge read as canopy by a pitched LiDAR): the count starts over whenever the crop's near edge
        // moved out by more than a map bin since the first scan that showed it.
        match self.gap_seen_from {
            Some((first_near_m, _)) if self.crop_past_end > 0 && near_m <= first_near_m + ROW_END_BIN_M => {
                self.crop_past_end = self.crop_past_end.saturating_add(1);
            }
            _ => {
                self.gap_seen_from = Some((near_m, at_m));
                self.crop_past_end = 1;
            }
        }
    }

    /// True once `gap_confirmations` scans in a row showed crop past the row end, standing still
    /// while the robot drove `GAP_TRAVEL_M` towards it (at the first pivot, where it stands, the
    /// scans alone).
    fn gap_seen(&self) -> bool {
        let travelled = |odom: &Pose2| {
            self.gap_seen_from
                .zip(self.row_end.or(self.exit_line))
                .is_some_and(|((_, from_m), end)| along(&end, odom) - from_m >= GAP_TRAVEL_M)
        };
        self.cfg.gap_confirmations > 0
            && self.crop_past_end >= self.cfg.gap_confirmations
            && (self.mode == Mode::Turning || self.last_pose.as_ref().is_some_and(travelled))
    }

    /// True while the robot stands at the first pivot of a pivot turn, still heading within
    /// `GAP_PIVOT_RAD` of the lane: the scan still looks along it, past the row end.
    fn at_first_pivot(&self, odom: &Pose2) -> bool {
        self.cfg.pivots()
            && self.pivoting
            && self.turn.segments().len() == 2
            && self.exit_line.is_some_and(|end| wrap_angle(odom.yaw - end.yaw).abs() <= GAP_PIVOT_RAD)
    }

    /// The row end was a gap in the rows: forgets it, the pivots planned at it and the rows' ends
    /// measured before it (they run on past the gap).
    fn forget_end(&mut self) {
        self.row_end = None;
        self.end_trim_m = 0.0;
        self.pivots = None;
        self.row_ends.clear();
        self.crop_past_end = 0;
        self.end_anchor = None;
        self.receding = 0;
    }

    /// Takes a row end the detector reports (`odom`). The first of a lane anchors it; one more than
    /// `max_end_recession_m` past the anchor is not taken, and `end_recession_scans` of those stop
    /// the robot (`row_end_receding`): a row end is a place, and one that moves away with the robot is
    /// canopy seen everywhere.
    fn take_end(&mut self, end: Pose2) {
        let anchor = *self.end_anchor.get_or_insert(end);
        if along(&anchor, &end) <= self.cfg.max_end_recession_m {
            self.row_end = Some(end);
            return;
        }
        self.receding = self.receding.saturating_add(1);
        if self.receding >= self.cfg.end_recession_scans {
            self.mode = Mode::Stopped { reason: StopReason::RowEndReceding };
        }
    }

    /// The row spacing the turns use, m: `row_spacing_m`, the planted spacing. The detector's running
    /// mean ([`LaneSwitcher::measured_spacing_m`]) is not used for the shift: on grown canopies it
    /// reads a few percent low (0.734 m for 0.78 m rows on soak seed 17), which over a two-lane
    /// shift put the robot 0.18 m off the next lane, while the planted spacing is known exactly.
    pub fn spacing_m(&self) -> f64 {
        self.cfg.row_spacing_m
    }

    /// The row spacing the detector measured along the lanes driven so far (a running mean), m.
    pub fn measured_spacing_m(&self) -> Option<f64> {
        self.measured_spacing_m
    }

    /// The pivots planned at the current row end (pivot turns, once the row end is known), m past it.
    pub fn pivots(&self) -> Option<PivotPlan> {
        self.pivots
    }

    /// Latches a stop decided by the caller (e.g. the MPC failed).
    pub fn stop(&mut self, reason: StopReason) {
        self.mode = Mode::Stopped { reason };
    }

    /// Leaves a stop: forgets the rows and waits for the detector again (lane count kept).
    pub fn resume(&mut self) {
        if matches!(self.mode, Mode::Stopped { .. }) {
            self.reference.reset();
            self.blind_m = 0.0;
            // A person decided: the lane is theirs, whatever its direction.
            self.entry_heading = None;
            self.mode = Mode::Acquiring;
        }
    }

    /// One step: the `odom` pose now and, if a scan arrived, its detection (made at this pose).
    pub fn update(&mut self, odom: &Pose2, detection: Option<&Detection>) -> Guidance {
        let mut reset_detector = false;
        if !odom.is_finite() {
            self.mode = Mode::Stopped { reason: StopReason::InvalidOdometry };
            return self.guidance(false, odom);
        }
        let travelled = self.last_pose.map_or(0.0, |p| (odom.x - p.x).hypot(odom.y - p.y));
        self.last_pose = Some(*odom);
        let line = match self.mode {
            Mode::Turning | Mode::Entering => self.exit_line,
            _ => self.row_end,
        };
        if let Some(end) = line {
            self.max_excursion_m = self.max_excursion_m.max(along(&end, odom));
        }
        // InvalidInput detections carry nothing; they count as no detection.
        let detection = detection.filter(|d| d.status != RowStatus::InvalidInput);
        // Rows at a spacing this field does not have belong to no lane of it: not believed.
        let raw_disagrees =
            detection.is_some_and(|d| d.status == RowStatus::Tracking && !self.spacing_agrees(d));
        let believed = detection
            .map(|d| if self.spacing_agrees(d) { *d } else { Detection { left: None, right: None, ..*d } });
        let detection = believed.as_ref();
        match self.mode {
            Mode::Acquiring => {
                let along_robot = detection.is_none_or(|d| {
                    self.reference
                        .centre_line(d)
                        .is_none_or(|line| line.heading_rad.abs() <= self.cfg.max_start_heading_rad)
                });
                if let Some(d) = detection
                    && d.status == RowStatus::Tracking
                    && along_robot
                    && self.reference.update(d, odom)
                {
                    self.enter_following(odom);
                } else if raw_disagrees || !along_robot {
                    // A wrong lattice is not tracked until it drifts into agreement: search afresh.
                    reset_detector = true;
                }
            }
            Mode::Following => {
                if self.dwell != Dwell::Off && !self.dwelling(travelled) {
                    // The stand for a suspected bias is over: what the rows did in `odom` before it
                    // says nothing about the bias the EKF has now.
                    self.row_headings_len = 0;
                    self.bias_suspect = false;
                    self.bias_suspect_since_m = None;
                    self.bias_suspected_in_lane = false;
                }
                if matches!(self.dwell, Dwell::Holding(_)) {
                    return self.guidance(reset_detector, odom);
                }
                self.follow(odom, detection, travelled);
            }
            Mode::ClearingRowEnd if self.gap_seen() => {
                // Crop past the end: it was a gap. Follow on across it on the lane's rows, which the
                // detector still tracks (that is part of the evidence).
                self.mode = Mode::Following;
                self.follow(odom, detection, travelled);
            }
            Mode::ClearingRowEnd => {
                if self.dwelling(travelled) {
                    return self.guidance(reset_detector, odom);
                }
                if let (Some(d), Some(end)) = (detection, self.row_end)
                    && let Some(ahead) = self.end_ahead(d)
                {
                    // A closer look refines the row end; only small corrections are believed.
                    let refined = self.end_from(odom, ahead);
                    if along(&end, &refined).abs() < 1.0 {
                        self.take_end(refined);
                    }
                }
                if self.mode.is_stopped() {
                    return self.guidance(reset_detector, odom);
                }
                self.replan();
                let tolerance = if self.stops_at_turn_start() { STOP_TOLERANCE_M } else { 0.0 };
                if self.pivots.is_some_and(|p| p.excursion_m() > self.cfg.max_headland_excursion_m)
                    && !self.is_last_lane()
                {
                    self.mode = Mode::Stopped { reason: StopReason::NoRoomToTurn };
                } else if let Some(end) = self.row_end
                    && along(&end, odom) >= self.exit_start_m() - tolerance
                {
                    self.lanes_completed = self.lanes_completed.saturating_add(1);
                    if self.lanes_completed >= self.cfg.lane_count() {
                        self.mode = Mode::Done;
                    } else {
                        self.plan_turn(odom, &end);
                        self.mode = Mode::Turning;
                        reset_detector = true;
                    }
                }
            }
            Mode::Turning if self.gap_seen() => {
                // Crop past the end once the first pivot began: the robot stands in the gap, heading off
                // the lane. The turn did not happen: the lane is not done, and the next turn goes the
                // same way.
                self.lanes_completed = self.lanes_completed.saturating_sub(1);
                self.turn_index = self.turn_index.wrapping_sub(1);
                self.crop_past_end = 0;
                self.mode = Mode::Stopped { reason: StopReason::CropPastRowEnd };
            }
            Mode::Turning => {
                if self.advance_turn(odom) {
                    self.mode = Mode::Entering;
                    self.agree = 0;
                    self.disagree = 0;
                    reset_detector = true;
                }
            }
            Mode::Entering => reset_detector = self.enter(odom, detection),
            Mode::Stopped { reason } if reason.clears_by_itself() && self.cfg.resume_confirmations > 0 => {
                self.recover(odom, detection, travelled);
            }
            Mode::Done | Mode::Stopped { .. } => {}
        }
        self.guidance(reset_detector, odom)
    }

    /// True when the robot must stand still where the turn starts: it pivots there, or the mission
    /// ends there.
    fn stops_at_turn_start(&self) -> bool {
        self.cfg.pivots() || self.is_last_lane()
    }

    /// True while driving the last lane of the mission.
    fn is_last_lane(&self) -> bool {
        self.lanes_completed.saturating_add(1) >= self.cfg.lane_count()
    }

    /// Which way the next turn goes: +1 left, −1 right (turns alternate from `first_turn`).
    fn next_side(&self) -> f64 {
        if self.turn_index.is_multiple_of(2) {
            self.cfg.first_turn.sign()
        } else {
            -self.cfg.first_turn.sign()
        }
    }

    /// Where past the row end the robot stops to turn (or to end the mission), m.
    fn exit_start_m(&self) -> f64 {
        match self.pivots {
            Some(p) if !self.is_last_lane() => p.first_m,
            _ => self.cfg.turn_start_m(),
        }
    }

    /// Plans the pivots against the measured row ends of the lane (pivot turns only), never nearer
    /// than the square-headland plan.
    fn replan(&mut self) {
        let Some(end) = self.row_end.filter(|_| self.cfg.pivots()) else {
            self.pivots = None;
            return;
        };
        let spacing = self.spacing_m();
        let nominal = self.cfg.turn_start_m();
        let ends = &self.row_ends;
        // Centroids stored before the end came into view may lie in the headland: no row is believed to
        // run on more than `row_end_window_m` past the lane's end.
        let window = self.cfg.row_end_window_m;
        let plan = self
            .cfg
            .pivot_plan(spacing, self.next_side(), |q| ends.end_or_fit_m(q, &end, spacing).min(window));
        self.pivots =
            Some(PivotPlan { first_m: plan.first_m.max(nominal), second_m: plan.second_m.max(nominal) });
    }

    /// The highest speed from which the robot stops within `remaining_m` at `stop_decel_mps2`, m/s.
    fn braking_speed(&self, remaining_m: f64) -> f64 {
        (2.0 * self.cfg.stop_decel_mps2 * remaining_m.max(0.0)).sqrt()
    }

    /// Follows the turn path leg by leg: drops the legs that are done and, at a corner, pivots until
    /// the robot heads along the next leg. True once only the entry straight is left.
    fn advance_turn(&mut self, odom: &Pose2) -> bool {
        let mut f = self.turn.project(odom, self.s_hint_m);
        if self.pivoting && f.heading_rad.abs() <= self.cfg.pivot_tolerance_rad {
            self.pivoting = false;
        }
        while !self.pivoting {
            let (Some(leg), Some(next)) = (self.turn.segments().first(), self.turn.segments().get(1)) else {
                break;
            };
            let corner = is_corner(leg, next);
            let tolerance = if corner { STOP_TOLERANCE_M } else { 0.0 };
            if f.s_m < leg.length_m - tolerance {
                break;
            }
            self.turn.pop_front();
            self.pivoting = corner;
            f = self.turn.project(odom, 0.0);
        }
        self.s_hint_m = f.s_m;
        !self.pivoting && self.turn.segments().len() <= 1
    }

    /// True unless the detection reports a row spacing too far from `row_spacing_m`.
    /// Following the lane or stopped in it, `following_spacing_tolerance` applies if it is tighter.
    fn spacing_agrees(&self, d: &Detection) -> bool {
        let tolerance = match self.mode {
            Mode::Following | Mode::Stopped { .. } => {
                self.cfg.spacing_tolerance.min(self.cfg.following_spacing_tolerance)
            }
            _ => self.cfg.spacing_tolerance,
        };
        d.row_spacing_m
            .is_none_or(|s| (s - self.cfg.row_spacing_m).abs() <= tolerance * self.cfg.row_spacing_m)
    }

    /// The cruise speed for the MPC in the current mode, braking to a stop where the robot must stand.
    fn speed_mps(&self, odom: &Pose2) -> f64 {
        match self.mode {
            Mode::Following | Mode::ClearingRowEnd if self.dwell != Dwell::Off => 0.0,
            Mode::Following => self.cfg.cruise_speed_mps,
            Mode::ClearingRowEnd => match self.row_end {
                Some(end) if self.stops_at_turn_start() => {
                    self.cfg.turn_speed_mps.min(self.braking_speed(self.exit_start_m() - along(&end, odom)))
                }
                _ => self.cfg.turn_speed_mps,
            },
            Mode::Turning if self.pivoting => 0.0,
            Mode::Turning => match self.turn.segments() {
                [leg, next, ..] if is_corner(leg, next) => {
                    self.cfg.turn_speed_mps.min(self.braking_speed(leg.length_m - self.s_hint_m))
                }
                _ => self.cfg.turn_speed_mps,
            },
            Mode::Entering => self.cfg.entry_speed_mps,
            Mode::Acquiring | Mode::Done | Mode::Stopped { .. } => 0.0,
        }
    }

    fn guidance(&self, reset_detector: bool, odom: &Pose2) -> Guidance {
        let speed_mps = if odom.is_finite() { self.speed_mps(odom) } else { 0.0 };
        Guidance {
            mode: self.mode,
            speed_mps,
            reset_detector,
            lanes_completed: self.lanes_completed,
            lane: self.lane,
            hold: matches!(self.mode, Mode::ClearingRowEnd | Mode::Following)
                && matches!(self.dwell, Dwell::Holding(_)),
        }
    }

    /// Advances the stand at a row end; true while it lasts. Standing starts once an update moved
    /// the robot less than `REST_STEP_M`.
    fn dwelling(&mut self, travelled: f64) -> bool {
        let Some(now) = self.now_s else {
            self.dwell = Dwell::Off;
            return false;
        };
        self.dwell = match self.dwell {
            Dwell::Braking if travelled < REST_STEP_M => Dwell::Holding(now),
            Dwell::Holding(since) if now - since >= self.cfg.bias_dwell_s => Dwell::Off,
            other => other,
        };
        self.dwell != Dwell::Off
    }

    /// Measures how fast the followed rows turn in `odom` (see `bias_suspect_rad_per_m`) over the
    /// last `BIAS_SUSPECT_WINDOW_M` driven with rows seen, every `ROW_HEADING_STEP_M`.
    fn watch_row_heading(&mut self, travelled: f64, saw_rows: bool) {
        self.odometer_m += travelled;
        let Some(path) = self.reference.path().filter(|_| saw_rows) else { return };
        let newest = self.row_headings[..self.row_headings_len].first();
        if newest.is_some_and(|(at_m, _)| self.odometer_m - at_m < ROW_HEADING_STEP_M) {
            return;
        }
        let heading = path.pose_at(self.s_hint_m).yaw;
        self.row_headings.rotate_right(1);
        self.row_headings[0] = (self.odometer_m, heading);
        self.row_headings_len = (self.row_headings_len + 1).min(ROW_HEADINGS);
        let headings = &self.row_headings[..self.row_headings_len];
        if let Some((_, yaw)) = headings.iter().find(|(at_m, _)| self.odometer_m - at_m >= ROW_TURN_WINDOW_M)
        {
            let (limit, turn) = (self.cfg.max_row_turn_rad, wrap_angle(heading - yaw));
            let past = limit > 0.0 && turn.abs() > limit;
            // Consecutive measurements past the limit the same way round: a fit that jumps one way
            // and back (re-found after a LiDAR dropout near a row end: 0.10 then -0.19 rad) is
            // not a turn.
            let way = if turn > 0.0 { 1 } else { -1 };
            self.rows_turning = match (past, self.rows_turning.signum() == way) {
                (false, _) => 0,
                (true, true) => self.rows_turning + way,
                (true, false) => way,
            };
        }
        let window = self.row_headings[..self.row_headings_len]
            .iter()
            .find(|(at_m, _)| self.odometer_m - at_m >= BIAS_SUSPECT_WINDOW_M);
        if let Some((at_m, yaw)) = window {
            let rate = wrap_angle(heading - yaw) / (self.odometer_m - at_m);
            self.bias_suspect = rate.abs() > self.cfg.bias_suspect_rad_per_m;
            self.bias_suspect_since_m =
                if self.bias_suspect { self.bias_suspect_since_m.or(Some(self.odometer_m)) } else { None };
            self.bias_suspected_in_lane |=
                self.bias_suspect_since_m.is_some_and(|since| self.odometer_m - since >= BIAS_HOLD_M);
        }
    }

    /// True when rows with direction `yaw` (`odom`) run within `entry_heading_tolerance_rad` of the
    /// planned new lane's, or no lane is planned.
    fn on_planned_heading(&self, yaw: f64) -> bool {
        self.entry_heading.is_none_or(|(planned, _)| {
            wrap_angle(yaw - planned).abs() <= self.cfg.entry_heading_tolerance_rad
        })
    }

    /// The watch of `entry_heading_watch_m`: false when the rows followed since the lane was entered
    /// turned off its planned direction. The watch ends once the robot followed that far.
    fn entry_heading_held(&mut self, saw_rows: bool) -> bool {
        let Some((_, Some(since_m))) = self.entry_heading else { return true };
        if self.odometer_m - since_m > self.cfg.entry_heading_watch_m {
            self.entry_heading = None;
            return true;
        }
        match self.reference.path().filter(|_| saw_rows) {
            Some(path) => self.on_planned_heading(path.pose_at(self.s_hint_m).yaw),
            None => true,
        }
    }

    fn enter_following(&mut self, odom: &Pose2) {
        self.mode = Mode::Following;
        // The watch starts where the new lane is first followed (a stop and resume inside it keeps it).
        self.entry_heading = match self.entry_heading {
            Some((planned, None)) => Some((planned, Some(self.odometer_m))),
            kept => kept,
        };
        self.blind_m = 0.0;
        self.resume_agree = 0;
        self.stop_rest_since_s = None;
        self.row_end = None;
        self.exit_line = None;
        self.end_trim_m = 0.0;
        self.pivoting = false;
        self.row_ends.clear();
        self.pivots = None;
        self.crop_past_end = 0;
        self.end_anchor = None;
        self.receding = 0;
        self.row_headings_len = 0;
        self.bias_suspect = false;
        self.bias_suspect_since_m = None;
        self.bias_suspected_in_lane = false;
        self.bias_stands_left = self.cfg.row_bias_stands;
        self.rows_turning = 0;
        self.dwell = Dwell::Off;
        self.s_hint_m = self.reference.path().map_or(0.0, |p| p.project(odom, 0.0).s_m);
    }

    fn follow(&mut self, odom: &Pose2, detection: Option<&Detection>, travelled: f64) {
        if self.gap_seen() {
            // Crop past the row end: it was a gap in the rows, and the detector reports the next end.
            self.forget_end();
        }
        let mut saw_rows = false;
        if let Some(d) = detection {
            if d.status != RowStatus::Lost && self.continues_line(d, odom) {
                saw_rows = self.reference.update(d, odom);
            }
            if saw_rows && let Some(s) = d.row_spacing_m.filter(|s| s.is_finite() && *s > 0.0) {
                // A slow running mean: one scan's estimate wobbles by centimetres.
                let m = self.measured_spacing_m.get_or_insert(s);
                *m += SPACING_GAIN * (s - *m);
            }
            if let Some(ahead) = self.end_ahead(d) {
                self.take_end(self.end_from(odom, ahead));
                if self.mode.is_stopped() {
                    return;
                }
            } else if d.status == RowStatus::EndOfRow && self.row_end.is_none() {
                self.take_end(self.end_from(odom, self.cfg.default_row_end_ahead_m));
            }
        }
        if let Some(path) = self.reference.path() {
            self.s_hint_m = path.project(odom, self.s_hint_m).s_m;
        }
        self.watch_row_heading(travelled, saw_rows);
        // Within `end_approach_m` of a row end the detector has seen, the rows in view are short and a
        // fit found again there (after a LiDAR dropout) turns by 0.2 rad: the line is carried to the
        // end instead (see below), and the watch over the lane's turn waits.
        let end_near = self.row_end.is_some_and(|end| -along(&end, odom) <= self.cfg.end_approach_m);
        let turned = !end_near && self.rows_turning.abs() >= ROW_TURN_SAMPLES;
        if !self.entry_heading_held(saw_rows) || turned {
            self.mode = Mode::Stopped { reason: StopReason::WrongLane };
            return;
        }
        if self.bias_suspect
            && self.dwell == Dwell::Off
            && self.bias_stands_left > 0
            && self.cfg.bias_dwell_s > 0.0
            && self.now_s.is_some()
        {
            // Stand now, not only at the row end: the bias bends the detector's map meanwhile.
            self.bias_stands_left -= 1;
            self.dwell = Dwell::Braking;
        }
        let ended = detection.is_some_and(|d| d.status == RowStatus::EndOfRow);
        if let Some(end) = self.row_end
            && (ended || along(&end, odom) >= 0.0)
        {
            // Past the canopy the detector's lines mean nothing: hold the last row direction.
            self.reference.straighten_at(odom);
            self.mode = Mode::ClearingRowEnd;
            // Rows that turned in `odom` mean the heading drifts: stand still for the EKF to learn
            // the gyro bias at rest before the blind drive and the pivots.
            let suspected = self.bias_suspect || self.bias_suspected_in_lane;
            let dwell = suspected && self.cfg.bias_dwell_s > 0.0 && self.now_s.is_some();
            self.dwell = if dwell { Dwell::Braking } else { Dwell::Off };
            return;
        }
        // Close to a row end the detector has seen, the last plants have left the scan: rows missing or
        // lost there are expected, and the line is carried to the end (`end_near`, above). Anywhere else
        // they stop the robot.
        if !end_near && detection.is_some_and(|d| d.status == RowStatus::Lost) {
            self.mode = Mode::Stopped { reason: StopReason::RowsLost };
            return;
        }
        self.blind_m = if saw_rows || end_near { 0.0 } else { self.blind_m + travelled };
        if self.blind_m > self.cfg.max_blind_distance_m {
            self.mode = Mode::Stopped { reason: StopReason::NoRows };
        }
    }

    /// True when the centre line `d` implies passes within `max_line_jump_m` of the path being
    /// followed at the robot (or there is nothing to compare). Believing a one-scan jump to a
    /// neighbouring lane would carry the rest of the mission, row end and turn included, one lane over.
    fn continues_line(&self, d: &Detection, odom: &Pose2) -> bool {
        let (Some(path), Some(line)) = (self.reference.path(), self.reference.centre_line(d)) else {
            return true;
        };
        // At the robot and a little ahead: a line that pivots about the robot (few rows left in view
        // at a row end, after a LiDAR dropout) jumps ahead, where the robot is about to drive.
        [0.0, LINE_CHECK_AHEAD_M].iter().all(|&ahead| {
            let on_line = odom.compose(&line.pose().compose(&Pose2::new(ahead, 0.0, 0.0)));
            path.project(&on_line, self.s_hint_m).lateral_m.abs() <= self.cfg.max_line_jump_m
        })
    }

    /// While stopped for a cause that clears by itself: counts consecutive detections of the lane that
    /// was followed (a step without a scan keeps the count) and follows again after
    /// `resume_confirmations` of them. The row end is forgotten: the detector reports it again (a
    /// stop just before the row end resumes on `end_of_row` detections and goes on to clear it). It
    /// does not follow before it has stood still for `resume_rest_s` (the EKF's rest check).
    fn recover(&mut self, odom: &Pose2, detection: Option<&Detection>, travelled: f64) {
        self.stop_rest_since_s = match self.now_s {
            Some(now) if travelled < REST_STEP_M => Some(self.stop_rest_since_s.unwrap_or(now)),
            _ => None,
        };
        let Some(d) = detection else { return };
        let same_lane = matches!(d.status, RowStatus::Tracking | RowStatus::EndOfRow)
            && self.reference.centre_line(d).is_some_and(|line| {
                let seen = odom.compose(&line.pose());
                self.reference.path().is_none_or(|path| {
                    let f = path.project(&seen, self.s_hint_m);
                    f.lateral_m.abs() <= self.cfg.entry_lateral_tolerance_m
                        && f.heading_rad.abs() <= self.cfg.entry_heading_tolerance_rad
                })
            });
        self.resume_agree = if same_lane { self.resume_agree.saturating_add(1) } else { 0 };
        let rested = self.cfg.resume_rest_s <= 0.0
            || self.now_s.is_none()
            || !self.rows_turned_before_stop()
            || self
                .stop_rest_since_s
                .zip(self.now_s)
                .is_some_and(|(since, now)| now - since >= self.cfg.resume_rest_s);
        if self.resume_agree >= self.cfg.resume_confirmations && rested && self.reference.update(d, odom) {
            self.enter_following(odom);
        }
    }

    /// True when the rows followed before a stop turned in `odom` faster than
    /// `resume_rest_rad_per_m` over the latest 1 to 2 m (the suspicion's window, shortened when the
    /// lane was entered less than 2 m before), or a bias error was suspected in the lane.
    fn rows_turned_before_stop(&self) -> bool {
        let headings = &self.row_headings[..self.row_headings_len];
        let turned = headings.first().zip(headings.last()).is_some_and(|((new_m, new), (old_m, old))| {
            let span_m = new_m - old_m;
            span_m >= SHORT_SUSPECT_WINDOW_M
                && (wrap_angle(new - old) / span_m).abs() > self.cfg.resume_rest_rad_per_m
        });
        self.bias_suspect || self.bias_suspected_in_lane || turned
    }

    /// The distance along the rows from `base_link` to the row end that a detection implies, m: the
    /// detector's canopy end, moved back to the farthest centroid of the lane's rows when that lies
    /// within `row_end_window_m` before it (see the module docs). The offset is kept for the scans
    /// that report the end without rows (the last plants out of view).
    fn end_ahead(&mut self, d: &Detection) -> Option<f64> {
        let ahead = d.row_end_ahead_m.filter(|a| a.is_finite())?;
        let far = [d.left, d.right]
            .iter()
            .flatten()
            .filter(|r| r.heading_rad.is_finite() && r.line.iter().all(|v| v.is_finite()))
            .map(|r| {
                let [_, _, x2, y2] = r.line;
                let (sin, cos) = r.heading_rad.sin_cos();
                x2 * cos + y2 * sin
            })
            .fold(f64::NEG_INFINITY, f64::max);
        if far.is_finite() {
            let trim = ahead - far;
            self.end_trim_m = if (0.0..=self.cfg.row_end_window_m).contains(&trim) { trim } else { 0.0 };
        }
        Some(ahead - self.end_trim_m)
    }

    /// The row end `ahead` metres along the current centre line from the robot.
    fn end_from(&self, odom: &Pose2, ahead: f64) -> Pose2 {
        match self.reference.path() {
            Some(path) => {
                let s = path.project(odom, self.s_hint_m).s_m;
                path.pose_at(s + ahead)
            }
            None => odom.compose(&Pose2::new(ahead, 0.0, 0.0)),
        }
    }

    fn plan_turn(&mut self, odom: &Pose2, end: &Pose2) {
        let side = self.next_side();
        let r = self.cfg.turn_radius_m;
        let spacing = self.spacing_m();
        let shift = 2.0 * spacing * f64::from(self.cfg.lane_step);
        // The new lane's rows: where its front tyres must stop until the lane is seen.
        let q = (side * 2.0 * f64::from(self.cfg.lane_step)) as i32;
        let window = self.cfg.row_end_window_m;
        self.entry_row_end_m = self
            .row_ends
            .end_or_fit_m(q - 1, end, spacing)
            .min(window)
            .max(self.row_ends.end_or_fit_m(q, end, spacing).min(window))
            + self.cfg.row_end_allowance_m;
        self.entry_anchored = false;
        let d = along(end, odom);
        let entry_m = d + self.cfg.max_unconfirmed_entry_m + 10.0;
        self.turn.clear();
        if self.cfg.pivots() {
            // Corners at the planned pivots, one on each lane's centre line (the straight between them
            // is oblique when the rows end on a skewed line): the robot stopped within a few
            // centimetres of the first, and the straight's lateral error takes that up.
            let start_m = self.exit_start_m();
            let PivotPlan { first_m, second_m } =
                self.pivots.unwrap_or(PivotPlan { first_m: start_m, second_m: start_m });
            let lateral = side * shift;
            let leg = Pose2::new(first_m, 0.0, lateral.atan2(second_m - first_m));
            self.turn.push(end.compose(&leg), (second_m - first_m).hypot(shift), 0.0);
            self.turn.push(end.compose(&Pose2::new(second_m, lateral, PI)), entry_m, 0.0);
            self.pivoting = true;
        } else {
            // Start on the old centre line abreast of the robot, heading along the row.
            let start = end.compose(&Pose2::new(d, 0.0, 0.0));
            let (arc, k) = (FRAC_PI_2 * r, side / r);
            self.turn.extend(start, arc, k);
            self.turn.extend(start, (shift - 2.0 * r).max(0.0), 0.0);
            self.turn.extend(start, arc, k);
            self.turn.extend(start, entry_m, 0.0);
            self.pivoting = false;
        }
        self.s_hint_m = 0.0;
        self.turn_index = self.turn_index.wrapping_add(1);
        self.exit_line = Some(*end);
        self.entry_heading =
            (self.cfg.entry_heading_watch_m > 0.0).then_some((wrap_angle(end.yaw + PI), None));
        self.row_end = None;
    }

    /// Moves the entry straight onto the detected centre line `c` (`odom`): odometry drifts by
    /// decimetres over a headland turn, so the robot aligns with the lane it sees, not the one it
    /// planned, before its wheels reach the crop. Only called for a detection that agrees with the
    /// plan (within `entry_lateral_tolerance_m`, under half a lane away).
    fn anchor_entry(&mut self, entry: &Segment, c: &Pose2, spacing_m: Option<f64>) {
        let rel = c.relative(&entry.start);
        // entry.start expressed on the detected line: its foot point, with the line's heading.
        let foot = c.compose(&Pose2::new(rel.x, 0.0, 0.0));
        // While entering, the entry straight is all that is left of the turn: the centre line of the
        // lane the detector sees.
        self.turn.clear();
        self.turn.push(foot, entry.length_m, 0.0);
        self.turn.set_row_spacing(Some(spacing_m.unwrap_or(self.spacing_m())));
        self.entry_anchored = true;
    }

    fn enter(&mut self, odom: &Pose2, detection: Option<&Detection>) -> bool {
        let f = self.turn.project(odom, self.s_hint_m);
        self.s_hint_m = f.s_m;
        let Some(entry) = self.turn.segments().last().copied() else { return false };
        let seen = detection.filter(|d| matches!(d.status, RowStatus::Tracking | RowStatus::EndOfRow));
        // Rows off the planned direction are a fit that took up a turn, not another lane: they count
        // neither way, and the detector searches afresh while the robot drives on.
        let search_again = seen
            .and_then(|d| self.reference.centre_line(d))
            .is_some_and(|line| !self.on_planned_heading(odom.yaw + line.heading_rad));
        if !search_again
            && let Some(d) = seen
            && let Some(line) = self.reference.centre_line(d)
        {
            let c = odom.compose(&line.pose());
            let (_, lateral) = {
                let rel = entry.start.relative(&c);
                (rel.x, rel.y)
            };
            let heading = wrap_angle(c.yaw - entry.start.yaw);
            if lateral.abs() <= self.cfg.entry_lateral_tolerance_m
                && heading.abs() <= self.cfg.entry_heading_tolerance_rad
            {
                self.agree = self.agree.saturating_add(1);
                self.disagree = 0;
                self.anchor_entry(&entry, &c, d.row_spacing_m);
            } else {
                self.disagree = self.disagree.saturating_add(1);
                self.agree = 0;
            }
            let aligned = f.lateral_m.abs() <= self.cfg.entry_alignment_m
                && f.heading_rad.abs() <= self.cfg.entry_heading_tolerance_rad;
            if self.agree >= self.cfg.entry_confirmations && aligned && self.reference.update(d, odom) {
                self.lane = self.lane.saturating_add(self.cfg.lane_step);
                self.enter_following(odom);
                return false;
            }
            if self.disagree >= self.cfg.entry_confirmations {
                self.mode = Mode::Stopped { reason: StopReason::WrongLane };
                return false;
            }
        }
        if let Some(end) = self.exit_line {
            // Until a detection agrees with the plan, the robot drives on odometry alone: its front
            // tyres stay out of the new lane's crop.
            let front_m = along(&end, odom) - self.cfg.wheel_x_m - 0.5 * self.cfg.tire_length_m;
            // Nor do they go in while the robot is too far off the lane the detector agrees on: the
            // tyres would land on its rows.
            let off_lane = f.lateral_m.abs() > self.cfg.entry_max_offset_m;
            let blind_limit = (!self.entry_anchored || off_lane)
                && self.cfg.pivots()
                && front_m < self.entry_row_end_m + self.cfg.clearance_margin_m;
            if blind_limit || -along(&end, odom) > self.cfg.max_unconfirmed_entry_m {
                self.mode = Mode::Stopped { reason: StopReason::ReentryNotConfirmed };
            }
        }
        if search_again {
            self.agree = 0;
        }
        search_again
    }
}

/// Distance from a pivot or mission end within which the robot counts as there, m: the braking
/// profile reaches zero speed only at the point itself.
const STOP_TOLERANCE_M: f64 = 0.02;

/// True when `next` does not continue `leg`'s heading: the robot must pivot there.
fn is_corner(leg: &Segment, next: &Segment) -> bool {
    wrap_angle(next.start.yaw - leg.end().yaw).abs() > 1e-6
}

/// Signed distance of `pose` past the row-end line `end` along the row direction, m.
fn along(end: &Pose2, pose: &Pose2) -> f64 {
    end.inverse_transform_point(pose.x, pose.y).0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::RowEstimate;

    /// The detection of the lane y = 0 (rows at y = ±0.375 m along x) made by a robot at `(x, dy, 0)`.
    fn rows(t: f64, dy: f64) -> Detection {
        let row = |offset_m: f64| RowEstimate {
            line: [0.0, offset_m, 3.0, offset_m],
            offset_m,
            heading_rad: 0.0,
            curvature_per_m: 0.0,
            confidence: 1.0,
        };
        Detection {
            left: Some(row(0.375 - dy)),
            right: Some(row(-0.375 - dy)),
            row_spacing_m: Some(0.75),
            ..Detection::empty(t, RowStatus::Tracking)
        }
    }

    /// A switcher following the lane y = 0 and then stopped by lost rows at x = 2.
    fn stopped_by_lost_rows(cfg: LaneSwitchConfig) -> LaneSwitcher {
        let mut sw = LaneSwitcher::new(cfg, ReferenceConfig::default()).unwrap();
        sw.update(&Pose2::new(1.0, 0.0, 0.0), Some(&rows(0.0, 0.0)));
        assert_eq!(sw.mode(), Mode::Following);
        let g = sw.update(&Pose2::new(2.0, 0.0, 0.0), Some(&Detection::empty(0.1, RowStatus::Lost)));
        assert_eq!(g.mode, Mode::Stopped { reason: StopReason::RowsLost });
        sw
    }

    #[test]
    fn a_rows_lost_stop_resumes_after_enough_consistent_detections() {
        let mut sw = stopped_by_lost_rows(LaneSwitchConfig::default());
        let at = Pose2::new(2.0, 0.0, 0.0);
        for k in 0..4 {
            let g = sw.update(&at, Some(&rows(0.2 + 0.1 * k as f64, 0.0)));
            assert_eq!((g.mode, g.speed_mps), (Mode::Stopped { reason: StopReason::RowsLost }, 0.0));
            // Control steps between scans keep the count.
            sw.update(&at, None);
        }
        let g = sw.update(&at, Some(&rows(0.6, 0.0)));
        assert_eq!(g.mode, Mode::Following);
        assert!(g.speed_mps > 0.0);
    }

    /// A switcher that followed rows turning in `odom` at `rate` rad/m for 1.5 m (shorter than the
    /// suspicion's 2 m window, as soak seed 664 between its gyro step and its stop), then stopped by
    /// lost rows; the pose it stopped at.
    fn stopped_after_turning_rows(rate: f64) -> (LaneSwitcher, Pose2) {
        let mut sw = LaneSwitcher::new(LaneSwitchConfig::default(), ReferenceConfig::default()).unwrap();
        let pose = |x: f64| Pose2::new(x, 0.0, -rate * (x - 1.0));
        for i in 0..=15 {
            let x = 1.0 + 0.1 * f64::from(i);
            sw.update(&pose(x), Some(&rows(0.2 * f64::from(i), 0.0)));
            assert_eq!(sw.mode(), Mode::Following, "at x {x}");
        }
        let at = pose(2.6);
        let g = sw.update(&at, Some(&Detection::empty(3.2, RowStatus::Lost)));
        assert_eq!(g.mode, Mode::Stopped { reason: StopReason::RowsLost });
        assert!(!sw.bias_suspected(), "too short for the 2 m window");
        (sw, at)
    }

    /// Stamped scans at 10 Hz of the stopped-at lane, from t = 10 s, the robot at `poses[k]` for the
    /// `k`th; the mode after each.
    fn resume_modes(sw: &mut LaneSwitcher, poses: &[Pose2]) -> Vec<Mode> {
        poses
            .iter()
            .enumerate()
            .map(|(k, at)| {
                let t = 10.0 + 0.1 * k as f64;
                sw.set_time(t);
                sw.update(at, Some(&rows(t, 0.0))).mode
            })
            .collect()
    }

    /// Scans (10 Hz) in the stand at rest `resume_rest_s` lasts.
    fn rest_scans(sw: &LaneSwitcher) -> usize {
        (sw.config().resume_rest_s / 0.1).round() as usize
    }

    #[test]
    fn a_stop_after_rows_turned_in_odom_stands_for_the_rest_time_before_following() {
        // Regression (soak seed 664): the stop is where the EKF finds a gyro bias step at rest.
        // 0.007 rad/m: the followed path of 664 before its stop (a 0.018 rad/s step).
        let (mut sw, at) = stopped_after_turning_rows(0.007);
        let steps = rest_scans(&sw);
        let modes = resume_modes(&mut sw, &vec![at; steps + 2]);
        // Five agreeing scans after 0.4 s; still standing until `resume_rest_s` has passed (±1 scan).
        let stopped = Mode::Stopped { reason: StopReason::RowsLost };
        assert!(modes[..steps - 1].iter().all(|m| *m == stopped), "{modes:?}");
        assert_eq!(modes.last(), Some(&Mode::Following), "{modes:?}");
    }

    #[test]
    fn a_stop_after_straight_rows_resumes_without_the_rest() {
        // 0.0025 rad/m: `fault-lidar-dropout` before its stops (a healthy gyro).
        let (mut sw, at) = stopped_after_turning_rows(0.0025);
        let modes = resume_modes(&mut sw, &[at; 5]);
        assert_eq!(modes[4], Mode::Following, "{modes:?}");
    }

    #[test]
    fn creeping_while_stopped_restarts_the_rest_time() {
        let (mut sw, at) = stopped_after_turning_rows(0.03);
        let steps = rest_scans(&sw);
        // 2 cm per scan (0.2 m/s, still braking) for the first half, then still.
        let poses: Vec<Pose2> = (0..steps + 2)
            .map(|k| at.compose(&Pose2::new(0.02 * k.min(steps / 2) as f64, 0.0, 0.0)))
            .collect();
        let modes = resume_modes(&mut sw, &poses);
        assert!(modes.iter().all(|m| *m == Mode::Stopped { reason: StopReason::RowsLost }), "{modes:?}");
    }

    #[test]
    fn a_centre_line_pivoting_about_the_robot_is_not_followed() {
        // Regression: after a LiDAR dropout near a row end the detector fitted the few rows left in
        // view 0.29 rad off, 0.2 m to the side at the robot (under the 0.25 m jump limit); the robot
        // steered onto a row. The jump is checked 1.5 m ahead too, so such a line counts as no row.
        let pivoted = |t: f64| {
            let mut d = rows(t, 0.0);
            for r in [d.left.as_mut(), d.right.as_mut()].into_iter().flatten() {
                r.offset_m += 0.2;
                r.heading_rad = 0.29;
                r.line = [0.0, r.offset_m, 1.9, r.offset_m + 1.9 * 0.29_f64.tan()];
            }
            d
        };
        let mut sw = LaneSwitcher::new(LaneSwitchConfig::default(), ReferenceConfig::default()).unwrap();
        sw.update(&Pose2::new(1.0, 0.0, 0.0), Some(&rows(0.0, 0.0)));
        let mut mode = sw.mode();
        for k in 1..=12 {
            let at = Pose2::new(1.0 + 0.1 * k as f64, 0.0, 0.0);
            mode = sw.update(&at, Some(&pivoted(0.1 * k as f64))).mode;
        }
        assert_eq!(mode, Mode::Stopped { reason: StopReason::NoRows });
    }

    #[test]
    fn an_inconsistent_detection_restarts_the_resume_count() {
        let mut sw = stopped_by_lost_rows(LaneSwitchConfig::default());
        let at = Pose2::new(2.0, 0.0, 0.0);
        for k in 0..4 {
            sw.update(&at, Some(&rows(0.2 + 0.1 * k as f64, 0.0)));
        }
        // The neighbouring lane (0.75 m over) or a searching detector breaks the streak.
        sw.update(&at, Some(&rows(0.6, 0.75)));
        for k in 0..4 {
            sw.update(&at, Some(&rows(0.7 + 0.1 * k as f64, 0.0)));
        }
        assert_eq!(sw.mode(), Mode::Stopped { reason: StopReason::RowsLost });
        sw.update(&at, Some(&Detection::empty(1.1, RowStatus::Searching)));
        for k in 0..4 {
            sw.update(&at, Some(&rows(1.2 + 0.1 * k as f64, 0.0)));
        }
        assert_eq!(sw.mode(), Mode::Stopped { reason: StopReason::RowsLost });
        sw.update(&at, Some(&rows(1.6, 0.0)));
        assert_eq!(sw.mode(), Mode::Following);
    }

    #[test]
    fn latched_stops_do_not_resume_by_themselves() {
        let at = Pose2::new(2.0, 0.0, 0.0);
        // With resume_confirmations = 0 every stop is latched.
        let mut sw = stopped_by_lost_rows(LaneSwitchConfig { resume_confirmations: 0, ..Default::default() });
        for k in 0..20 {
            sw.update(&at, Some(&rows(0.2 + 0.1 * k as f64, 0.0)));
        }
        assert_eq!(sw.mode(), Mode::Stopped { reason: StopReason::RowsLost });
        for reason in [StopReason::SolverFailed, StopReason::WrongLane, StopReason::ReentryNotConfirmed] {
            let mut sw = stopped_by_lost_rows(LaneSwitchConfig::default());
            sw.stop(reason);
            for k in 0..20 {
                sw.update(&at, Some(&rows(0.2 + 0.1 * k as f64, 0.0)));
            }
            assert_eq!(sw.mode(), Mode::Stopped { reason });
            assert!(!reason.clears_by_itself());
        }
    }

    #[test]
    fn default_turn_pivots_inside_the_headland() {
        let cfg = LaneSwitchConfig::default();
        cfg.validate().unwrap();
        assert!(cfg.pivots());
        // The second pivot binds: 0.075 m lateral drift over the 1.5 m shift leaves the nearest row
        // 0.3 m to the side, √(ρ² − 0.3²) = 1.0289 with ρ = 1.0717; plus 0.05 allowance, 0.05 margin
        // and 0.05·(1.6 + ρ + 1.5) drift = 1.3376 m.
        let reach = 0.6695f64.hypot(0.837);
        let expected = (reach * reach - 0.09).sqrt() + 0.05 + 0.05 + 0.05 * (1.6 + reach + 1.5);
        assert!((cfg.turn_excursion_m() - expected).abs() < 1e-9, "{}", cfg.turn_excursion_m());
        assert!((expected - 1.3376).abs() < 1e-4, "{expected}");
        // Two lanes over (3 m), still inside the 1.5 m headland.
        let skip = LaneSwitchConfig { lane_step: 2, ..LaneSwitchConfig::default() };
        skip.validate().unwrap();
        assert!(skip.turn_excursion_m() > cfg.turn_excursion_m());
    }

    #[test]
    fn a_pivot_starts_where_the_swept_tyres_just_miss_the_nearest_plants() {
        let cfg = LaneSwitchConfig {
            clearance_margin_m: 0.0,
            row_end_allowance_m: 0.0,
            odometry_drift_fraction: 0.0,
            ..LaneSwitchConfig::default()
        };
        // The farthest tyre-patch corner from base_link sweeps a circle; the nearest plants stand at
        // the row end on the lane's rows, half a row spacing to the side (arithmetic: 1e-12).
        let reach = (0.6095f64 + 0.06).hypot(0.762 + 0.075);
        assert!((cfg.turn_start_m().hypot(0.375) - reach).abs() < 1e-12);
    }

    #[test]
    fn arcs_start_where_the_inner_tyres_swing_clear() {
        // r = 0.6: the inner tyre corner is √(0.6695² + 0.237²) = 0.7102 m from the turning centre,
        // whose nearest row is 0.225 m to its side; the outer rear tyre starts 0.6695 m back.
        let r06 = LaneSwitchConfig { turn_radius_m: 0.6, ..LaneSwitchConfig::default() };
        let reach = 0.6695f64.hypot(0.237);
        let swing = (reach.powi(2) - 0.225f64.powi(2)).sqrt();
        let budget = 0.05 + 0.05 + 0.05 * (1.6 + reach);
        assert!((r06.turn_start_m() - (swing + budget)).abs() < 1e-9, "{}", r06.turn_start_m());
        assert!((r06.turn_excursion_m() - (swing + budget + 0.6)).abs() < 1e-9);
    }

    /// A switcher that followed y = 0 from x = 1 and saw the canopy end 2 m ahead (x = 3), with the
    /// row centroids `centroids` (`base_link` at x = 1), then drove on to `to_x` (or until it turns).
    /// Follows rows from x = 1 to 5 m in `odom` while the odometry's heading turns by `rate` rad/m
    /// (the rows stay straight ahead of the robot, so they turn in `odom`), one scan per 0.1 m at
    /// 0.5 m/s, then sees the row end. Returns the switcher, clearing the row end, and the time, s.
    fn follow_turning_rows(rate: f64) -> (LaneSwitcher, Pose2, f64) {
        let mut sw = LaneSwitcher::new(LaneSwitchConfig::default(), ReferenceConfig::default()).unwrap();
        let mut pose = Pose2::new(1.0, 0.0, 0.0);
        let mut t = 0.0;
        for i in 0..=40 {
            let x = 1.0 + 0.1 * f64::from(i);
            pose = Pose2::new(x, 0.0, -rate * (x - 1.0));
            t = 0.2 * f64::from(i);
            sw.set_time(t);
            sw.update(&pose, Some(&rows(t, 0.0)));
            assert_eq!(sw.mode(), Mode::Following, "at x {x}");
        }
        assert_eq!(sw.bias_suspected(), rate.abs() > sw.config().bias_suspect_rad_per_m);
        t += 0.2;
        sw.set_time(t);
        pose = pose.compose(&Pose2::new(0.1, 0.0, 0.0));
        let g = sw.update(&pose, Some(&Detection::empty(t, RowStatus::EndOfRow)));
        assert_eq!(g.mode, Mode::ClearingRowEnd);
        (sw, pose, t)
    }

    #[test]
    fn rows_turning_in_odom_mid_row_make_the_robot_stand_once_and_follow_on() {
        // 0.05 rad/m: a 0.025 rad/s gyro bias error at 0.5 m/s (soak seeds 41, 55: 0.027, 0.022).
        let rate = 0.05;
        let cfg = LaneSwitchConfig { row_bias_stands: 1, ..LaneSwitchConfig::default() };
        let mut sw = LaneSwitcher::new(cfg, ReferenceConfig::default()).unwrap();
        let mut x = 1.0;
        let mut t = 0.0;
        let step = |sw: &mut LaneSwitcher, x: f64, t: f64| {
            sw.set_time(t);
            sw.update(&Pose2::new(x, 0.0, -rate * (x - 1.0)), Some(&rows(t, 0.0)))
        };
        // Cruising until the rows have turned for a 2 m window, then braking.
        let mut g = step(&mut sw, x, t);
        while g.speed_mps > 0.0 {
            x += 0.05;
            t += 0.1;
            g = step(&mut sw, x, t);
            assert!(x < 4.0, "no stand within 3 m");
        }
        assert_eq!((g.mode, g.hold), (Mode::Following, false));
        // Standing: held for `bias_dwell_s` (1.5 s, updates every 0.1 s), then following at cruise.
        let mut held_s = 0.0_f64;
        loop {
            t += 0.1;
            g = step(&mut sw, x, t);
            if !g.hold {
                break;
            }
            held_s += 0.1;
            assert!(held_s < 3.0, "held too long");
        }
        assert!((held_s - 1.6).abs() < 0.11, "held {held_s} s");
        assert_eq!((g.mode, g.speed_mps), (Mode::Following, sw.config().cruise_speed_mps));
        // One stand per lane: the rows keep turning for 3 m more and the robot keeps going.
        for _ in 0..60 {
            x += 0.05;
            t += 0.1;
            g = step(&mut sw, x, t);
            assert_eq!((g.mode, g.speed_mps), (Mode::Following, sw.config().cruise_speed_mps), "at {x}");
        }
    }

    #[test]
    fn no_stand_mid_row_by_default() {
        let mut sw = LaneSwitcher::new(LaneSwitchConfig::default(), ReferenceConfig::default()).unwrap();
        for i in 0..80 {
            let x = 1.0 + 0.05 * f64::from(i);
            let t = 0.1 * f64::from(i);
            sw.set_time(t);
            let g = sw.update(&Pose2::new(x, 0.0, -0.05 * (x - 1.0)), Some(&rows(t, 0.0)));
            assert_eq!(g.speed_mps, sw.config().cruise_speed_mps, "at {x}");
        }
        assert!(sw.bias_suspected());
    }

    #[test]
    fn a_lane_far_off_the_robot_heading_is_not_started_on() {
        // 15° off the robot (soak seed 31: tall weeds filling the view at the start), over
        // `max_start_heading_rad` (0.2 rad): searched again; 8° (the recovery runs) is started on.
        let turned = |t: f64, deg: f64| {
            let h = deg.to_radians();
            let row = |offset_m: f64| RowEstimate {
                line: [0.0, offset_m, 3.0 * h.cos(), offset_m + 3.0 * h.sin()],
                offset_m,
                heading_rad: h,
                curvature_per_m: 0.0,
                confidence: 1.0,
            };
            Detection { left: Some(row(0.375)), right: Some(row(-0.375)), ..rows(t, 0.0) }
        };
        let mut sw = LaneSwitcher::new(LaneSwitchConfig::default(), ReferenceConfig::default()).unwrap();
        let at = Pose2::new(1.0, 0.0, 0.0);
        for k in 0..5 {
            let g = sw.update(&at, Some(&turned(0.1 * f64::from(k), 15.0)));
            assert_eq!((g.mode, g.reset_detector, g.speed_mps), (Mode::Acquiring, true, 0.0));
        }
        let g = sw.update(&at, Some(&turned(0.5, 8.0)));
        assert_eq!((g.mode, g.reset_detector), (Mode::Following, false));
    }

    #[test]
    fn a_lattice_at_another_spacing_is_searched_again_while_acquiring() {
        // Twice the planted 0.75 m (soak seeds 439, 982: the start-up search took a closed canopy for a
        // lattice of every second row); left to itself the fit wandered at rest into the 25 % band,
        // 20° off the rows, and the robot followed it.
        let double = |t: f64| Detection { row_spacing_m: Some(1.5), ..rows(t, 0.0) };
        let mut sw = LaneSwitcher::new(LaneSwitchConfig::default(), ReferenceConfig::default()).unwrap();
        let at = Pose2::new(1.0, 0.0, 0.0);
        let g = sw.update(&at, Some(&double(0.0)));
        assert_eq!((g.mode, g.reset_detector, g.speed_mps), (Mode::Acquiring, true, 0.0));
        // No detection, or one the switcher takes, is no reason to search again.
        assert!(!sw.update(&at, None).reset_detector);
        let g = sw.update(&at, Some(&rows(0.1, 0.0)));
        assert_eq!((g.mode, g.reset_detector), (Mode::Following, false));
    }

    #[test]
    fn a_lattice_narrower_than_planted_is_not_followed() {
        // 20 % narrower than the planted 0.75 m: inside `spacing_tolerance` (25 %), so believed when
        // acquiring, but over `following_spacing_tolerance` (15 %) once following (soak seed 168:
        // 0.60 for 0.73 m, 25 cm off the lane centre into a row).
        let narrow = |t: f64| {
            let mut d = rows(t, 0.0);
            d.row_spacing_m = Some(0.6);
            d
        };
        let mut sw = LaneSwitcher::new(LaneSwitchConfig::default(), ReferenceConfig::default()).unwrap();
        assert_eq!(sw.update(&Pose2::new(1.0, 0.0, 0.0), Some(&narrow(0.0))).mode, Mode::Following);
        let mut mode = sw.mode();
        for k in 1..=12 {
            mode = sw
                .update(&Pose2::new(1.0 + 0.1 * f64::from(k), 0.0, 0.0), Some(&narrow(0.1 * f64::from(k))))
                .mode;
        }
        assert_eq!(mode, Mode::Stopped { reason: StopReason::NoRows });
        // Stopped, the narrow lattice does not resume it; the planted one does.
        let at = Pose2::new(2.2, 0.0, 0.0);
        for k in 0..10 {
            sw.update(&at, Some(&narrow(1.3 + 0.1 * f64::from(k))));
        }
        assert_eq!(sw.mode(), Mode::Stopped { reason: StopReason::NoRows });
        for k in 0..5 {
            sw.update(&at, Some(&rows(2.3 + 0.1 * f64::from(k), 0.0)));
        }
        assert_eq!(sw.mode(), Mode::Following);
    }

    #[test]
    fn rows_turning_in_odom_make_the_robot_stand_at_the_row_end_for_the_dwell() {
        // 0.04 rad/m: a 0.02 rad/s gyro bias error at 0.5 m/s.
        let (mut sw, pose, mut t) = follow_turning_rows(0.04);
        // Braking: no cruise speed, but the MPC still steers the robot to a stop.
        t += 0.05;
        sw.set_time(t);
        let pose = pose.compose(&Pose2::new(0.02, 0.0, 0.0));
        let g = sw.update(&pose, None);
        assert!(g.speed_mps == 0.0 && !g.hold, "{g:?}");
        // Standing still from the first update that did not move it, for `bias_dwell_s` (1.5 s).
        let mut held_s = 0.0_f64;
        loop {
            t += 0.05;
            sw.set_time(t);
            let g = sw.update(&pose, None);
            if !g.hold {
                assert!(g.speed_mps > 0.0 && g.mode == Mode::ClearingRowEnd, "{g:?}");
                break;
            }
            held_s += 0.05;
            assert!(held_s < 3.0, "held too long");
        }
        // Stamps every 0.05 s: the stand ends on the first update at least 1.5 s after it began.
        assert!((held_s - 1.55).abs() < 0.051, "held {held_s} s");
    }

    #[test]
    fn straight_rows_in_odom_do_not_stop_the_robot_at_the_row_end() {
        // 0.005 rad/m: the soak's curved rows bend by up to 0.004 rad/m.
        let (mut sw, pose, t) = follow_turning_rows(0.005);
        sw.set_time(t + 0.05);
        let g = sw.update(&pose, None);
        assert!(g.speed_mps > 0.0 && !g.hold, "{g:?}");
    }

    #[test]
    fn without_stamps_the_robot_never_stands_at_the_row_end() {
        let (mut sw, pose, _) = follow_turning_rows(0.04);
        sw.set_time(f64::NAN);
        let g = sw.update(&pose, None);
        assert!(g.speed_mps > 0.0 && !g.hold, "{g:?}");
    }

    fn approach_end(cfg: LaneSwitchConfig, centroids: &[[f64; 2]], to_x: f64) -> (LaneSwitcher, f64) {
        let mut sw = LaneSwitcher::new(cfg, ReferenceConfig::default()).unwrap();
        let ended = |t: f64, ahead: f64| Detection { row_end_ahead_m: Some(ahead), ..rows(t, 0.0) };
        let at = Pose2::new(1.0, 0.0, 0.0);
        sw.update(&at, Some(&rows(0.0, 0.0)));
        sw.update(&at, Some(&ended(0.1, 2.0)));
        sw.observe_canopy(&at, &ended(0.1, 2.0), centroids);
        let mut x = 1.0;
        while !matches!(sw.mode(), Mode::Turning | Mode::Stopped { .. }) && x < to_x {
            x += 0.01;
            sw.update(&Pose2::new(x, 0.0, 0.0), None);
        }
        (sw, x)
    }

    #[test]
    fn a_measured_row_end_past_the_lane_end_moves_the_first_pivot_out() {
        // The left row's last centroid 0.2 m past the lane's end (a ragged end): the robot pivots
        // 0.2 m farther out. A centroid more than a map bin past the canopy end is not believed. The
        // rows not seen are taken to run as far as the farthest seen: the second pivot moves out too,
        // past 1.5 m.
        let cfg = LaneSwitchConfig { max_headland_excursion_m: 2.0, ..LaneSwitchConfig::default() };
        let (sw, x) =
            approach_end(cfg.clone(), &[[1.9, 0.37], [2.2, 0.38], [1.95, -0.37], [2.4, -0.36]], 6.0);
        assert_eq!(sw.mode(), Mode::Turning);
        let plan = sw.pivots().unwrap();
        let square = cfg.pivot_plan(0.75, -1.0, |_| 0.0);
        assert!((plan.first_m - (square.first_m + 0.2)).abs() < 1e-9, "{plan:?}");
        assert!((x - 3.0 - plan.first_m).abs() <= 0.021, "turned at x {x}, plan {plan:?}");
    }

    #[test]
    fn a_turn_the_measured_ends_push_past_the_headland_stops_instead() {
        // The row beyond the lane's right row runs on 0.2 m: turning right, the second pivot would stand
        // 1.54 m out, past the 1.5 m headland.
        let (sw, _) = approach_end(LaneSwitchConfig::default(), &[[1.9, 0.37], [2.2, -1.12]], 3.1);
        assert_eq!(sw.mode(), Mode::Stopped { reason: StopReason::NoRoomToTurn });
        // With room for it, the same field is turned in.
        let roomy = LaneSwitchConfig { max_headland_excursion_m: 2.0, ..LaneSwitchConfig::default() };
        let (sw, _) = approach_end(roomy, &[[1.9, 0.37], [2.2, -1.12]], 6.0);
        assert_eq!(sw.mode(), Mode::Turning);
        assert!(sw.pivots().unwrap().second_m > 1.5, "{:?}", sw.pivots());
    }

    #[test]
    fn a_turn_past_the_headland_is_refused() {
        let cfg = LaneSwitchConfig { clearance_margin_m: 0.5, ..LaneSwitchConfig::default() };
        assert!(cfg.validate().unwrap_err().to_string().contains("lane_switch.max_headland_excursion_m"));
        let cfg = LaneSwitchConfig { turn_radius_m: -0.1, ..LaneSwitchConfig::default() };
        assert!(cfg.validate().unwrap_err().to_string().contains("lane_switch.turn_radius_m"));
    }

    /// Asserts that each of `bad` set by `set` is refused naming `field`, and that `good` is taken.
    fn assert_range_checked(field: &str, set: fn(&mut LaneSwitchConfig, f64), bad: &[f64], good: f64) {
        let with = |v: f64| {
            let mut cfg = LaneSwitchConfig::default();
            set(&mut cfg, v);
            cfg
        };
        for &v in bad {
            let err = with(v).validate().unwrap_err().to_string();
            assert!(err.contains(field), "{v}: {err}");
        }
        with(good).validate().unwrap();
    }

    #[test]
    fn a_slide_limit_out_of_range_is_refused() {
        assert_range_checked(
            "lane_switch.max_slide_per_m",
            |c, v| c.max_slide_per_m = v,
            &[-0.1, 1.5, f64::NAN, f64::INFINITY],
            0.0,
        );
    }

    #[test]
    fn a_slide_lag_limit_out_of_range_is_refused() {
        assert_range_checked(
            "lane_switch.max_slide_lag_m",
            |c, v| c.max_slide_lag_m = v,
            &[-0.01, 11.0, f64::NAN, f64::NEG_INFINITY],
            0.08,
        );
    }

    #[test]
    fn a_slipping_lag_limit_out_of_range_is_refused() {
        assert_range_checked(
            "lane_switch.slipping_slide_lag_m",
            |c, v| c.slipping_slide_lag_m = v,
            &[-0.01, 11.0, f64::NAN],
            0.0,
        );
        assert_range_checked(
            "lane_switch.slipping_min_slip",
            |c, v| c.slipping_min_slip = v,
            &[-0.1, 1.5, f64::INFINITY],
            0.3,
        );
    }

    #[test]
    fn a_row_turn_limit_out_of_range_is_refused() {
        assert_range_checked(
            "lane_switch.max_row_turn_rad",
            |c, v| c.max_row_turn_rad = v,
            &[-0.1, 4.0, f64::NAN, f64::INFINITY],
            0.0,
        );
    }

    #[test]
    fn an_entry_heading_watch_out_of_range_is_refused() {
        assert_range_checked(
            "lane_switch.entry_heading_watch_m",
            |c, v| c.entry_heading_watch_m = v,
            &[-1.0, 2000.0, f64::NAN, f64::INFINITY],
            0.0,
        );
    }

    #[test]
    fn a_following_curvature_out_of_range_is_refused() {
        assert_range_checked(
            "lane_switch.max_following_curvature_per_m",
            |c, v| c.max_following_curvature_per_m = v,
            &[-0.1, 101.0, f64::NAN, f64::INFINITY],
            0.5,
        );
    }

    #[test]
    fn more_lanes_than_the_field_has_are_refused() {
        let cfg = LaneSwitchConfig { field_lanes: 8, start_lane: 3, lanes: 6, ..LaneSwitchConfig::default() };
        assert!(cfg.validate().unwrap_err().to_string().contains("lane_switch.lanes"));
        let all = LaneSwitchConfig {
            field_lanes: 8,
            start_lane: 3,
            lanes: 0,
            lane_step: 2,
            ..LaneSwitchConfig::default()
        };
        all.validate().unwrap();
        // Lanes 3, 5, 7.
        assert_eq!(all.lane_count(), 3);
    }

    /// Scans of a switcher at `x` on the lane y = 0 that track the rows, report no row end and map
    /// crop on the rows `ys` (m, left of the centre line) at `crop_x` (`odom` x, m).
    fn see_crop_past(sw: &mut LaneSwitcher, x: f64, t: f64, crop_x: f64, ys: &[f64]) -> Mode {
        let at = Pose2::new(x, 0.0, 0.0);
        let d = rows(t, 0.0);
        let centroids: Vec<[f64; 2]> = ys.iter().map(|&y| [crop_x - x, y]).collect();
        sw.observe_canopy(&at, &d, &centroids);
        sw.update(&at, Some(&d)).mode
    }

    /// The gap rule on with 3 scans (the default, spelt out: these tests are about the rule).
    fn gap_rule() -> LaneSwitchConfig {
        LaneSwitchConfig { gap_confirmations: 3, ..LaneSwitchConfig::default() }
    }

    #[test]
    fn crop_past_the_row_end_while_following_makes_it_a_gap() {
        // The canopy seemed to end at x = 3 (a stretch of every row missing); from x = 1.5 the lane's
        // rows show crop again at x = 4.5, 1.5 m past it, and the detector withdraws its end. Once
        // the robot drove 0.5 m with the crop standing still, the end is dropped.
        let (mut sw, _) = approach_end(gap_rule(), &[[1.9, 0.37], [1.95, -0.37]], 1.5);
        assert_eq!(sw.mode(), Mode::Following);
        for k in 0..5 {
            see_crop_past(&mut sw, 1.5 + 0.1 * k as f64, 1.0 + 0.1 * k as f64, 4.5, &[0.375, -0.375]);
            assert!(sw.row_end().is_some(), "dropped after {k} scans");
        }
        see_crop_past(&mut sw, 2.0, 1.5, 4.5, &[0.375, -0.375]);
        assert_eq!((sw.mode(), sw.row_end()), (Mode::Following, None));
        // Driving on across the gap, no turn starts where the end was.
        for k in 0..40 {
            let x = 2.1 + 0.05 * k as f64;
            let mode = sw.update(&Pose2::new(x, 0.0, 0.0), Some(&rows(2.0 + 0.1 * k as f64, 0.0))).mode;
            assert_eq!(mode, Mode::Following, "at x {x}");
        }
    }

    #[test]
    fn crop_past_the_row_end_that_keeps_ahead_of_the_robot_is_no_gap() {
        // A pitched LiDAR reads the ground 3.7 m ahead as canopy wherever the robot is: the end stays.
        let (mut sw, _) = approach_end(gap_rule(), &[[1.9, 0.37], [1.95, -0.37]], 1.5);
        for k in 0..10 {
            let x = 1.5 + 0.1 * k as f64;
            see_crop_past(&mut sw, x, 1.0 + 0.1 * k as f64, x + 3.7, &[0.375, -0.375]);
        }
        assert!(sw.row_end().is_some());
    }

    #[test]
    fn crop_past_the_row_end_while_clearing_it_cancels_the_turn() {
        // The robot reached the "end" at x = 3 and drives on to the pivot; the crop beyond the gap
        // comes into view on both lane rows: it follows again instead of turning.
        let (mut sw, x) = approach_end(gap_rule(), &[[1.9, 0.37], [1.95, -0.37]], 3.3);
        assert_eq!(sw.mode(), Mode::ClearingRowEnd, "at x {x}");
        let modes: Vec<Mode> = (0..7)
            .map(|k| see_crop_past(&mut sw, x + 0.1 * k as f64, 2.0 + 0.1 * k as f64, 6.0, &[0.375, -0.375]))
            .collect();
        assert_eq!(modes.last(), Some(&Mode::Following), "{modes:?}");
        assert!(modes[..5].iter().all(|m| *m == Mode::ClearingRowEnd), "{modes:?}");
        assert_eq!((sw.row_end(), sw.lanes_completed()), (None, 0));
    }

    #[test]
    fn crop_past_the_row_end_on_one_row_keeps_the_end() {
        // A weed on one row line (or the detector confirming its end) is not a row running on.
        let (mut sw, x) = approach_end(gap_rule(), &[[1.9, 0.37], [1.95, -0.37]], 3.3);
        for k in 0..7 {
            see_crop_past(&mut sw, x + 0.1 * k as f64, 2.0 + 0.1 * k as f64, 6.0, &[0.375]);
        }
        assert_eq!(sw.mode(), Mode::ClearingRowEnd);
        let x = x + 0.7;
        let confirmed = Detection { row_end_ahead_m: Some(3.0 - x), ..rows(3.0, 0.0) };
        for k in 0..5 {
            let at = Pose2::new(x + 0.1 * k as f64, 0.0, 0.0);
            let crop = [[6.0 - at.x, 0.375], [6.0 - at.x, -0.375]];
            sw.observe_canopy(&at, &confirmed, &crop);
            sw.update(&at, Some(&Detection { stamp_s: 3.0 + 0.1 * k as f64, ..confirmed }));
        }
        assert!(sw.row_end().is_some());
        assert_ne!(sw.mode(), Mode::Following);
    }

    #[test]
    fn crop_past_the_row_end_at_the_first_pivot_stops_the_turn() {
        let (mut sw, x) = approach_end(gap_rule(), &[[1.9, 0.37], [1.95, -0.37]], 6.0);
        assert_eq!((sw.mode(), sw.lanes_completed()), (Mode::Turning, 1), "at x {x}");
        // Pivoting on the spot, 0.2 rad round, the scan still looks past the end.
        let at = Pose2::new(x, 0.0, -0.2);
        let (ahead_x, ahead_y) = at.inverse_transform_point(6.0, 0.375);
        let (ahead_x2, ahead_y2) = at.inverse_transform_point(6.0, -0.375);
        for k in 0..3 {
            sw.observe_canopy(
                &at,
                &rows(5.0 + 0.1 * k as f64, 0.0),
                &[[ahead_x, ahead_y], [ahead_x2, ahead_y2]],
            );
            sw.update(&at, Some(&rows(5.0 + 0.1 * k as f64, 0.0)));
        }
        assert_eq!(sw.mode(), Mode::Stopped { reason: StopReason::CropPastRowEnd });
        // The lane was not done, and the stop waits for a person.
        assert_eq!(sw.lanes_completed(), 0);
        assert!(!StopReason::CropPastRowEnd.clears_by_itself());
    }

    #[test]
    fn with_the_gap_rule_off_the_first_row_end_seen_is_final() {
        let off = LaneSwitchConfig { gap_confirmations: 0, ..LaneSwitchConfig::default() };
        let (mut sw, x) = approach_end(off, &[[1.9, 0.37], [1.95, -0.37]], 3.3);
        for k in 0..10 {
            see_crop_past(&mut sw, x + 0.1 * k as f64, 2.0 + 0.1 * k as f64, 6.0, &[0.375, -0.375]);
        }
        assert!(matches!(sw.mode(), Mode::ClearingRowEnd | Mode::Turning), "{:?}", sw.mode());
    }

    #[test]
    fn a_row_end_that_moves_away_with_the_robot_stops_it() {
        // A tilted LiDAR reading the ground as crop: the canopy "ends" 2.75 m ahead of the robot
        // wherever it is. The end first seen at x = 3.75 is kept, and the fifth report more than 2 m
        // past it stops the robot before it gets there.
        let mut sw = LaneSwitcher::new(LaneSwitchConfig::default(), ReferenceConfig::default()).unwrap();
        sw.update(&Pose2::new(1.0, 0.0, 0.0), Some(&rows(0.0, 0.0)));
        let mut modes = Vec::new();
        for k in 0..60 {
            let x = 1.0 + 0.05 * k as f64;
            let d = Detection { row_end_ahead_m: Some(2.75), ..rows(0.1 * (k + 1) as f64, 0.0) };
            modes.push(sw.update(&Pose2::new(x, 0.0, 0.0), Some(&d)).mode);
            if modes.last().is_some_and(Mode::is_stopped) {
                break;
            }
        }
        let stop = modes.iter().position(Mode::is_stopped).expect("stops");
        assert_eq!(modes[stop], Mode::Stopped { reason: StopReason::RowEndReceding });
        // Reports up to 2 m past 3.75 are taken (robot at x = 3.0, step 40); five refusals follow.
        assert_eq!(stop, 40 + 5, "{modes:?}");
        let end = sw.row_end().unwrap();
        assert!((end.x - 5.75).abs() < 1e-9, "{end:?}");
    }

    #[test]
    fn a_row_end_refined_closer_or_a_little_farther_is_taken() {
        let mut sw = LaneSwitcher::new(LaneSwitchConfig::default(), ReferenceConfig::default()).unwrap();
        sw.update(&Pose2::new(1.0, 0.0, 0.0), Some(&rows(0.0, 0.0)));
        // First seen at x = 4.5, then 0.25 m nearer, then 1.9 m past the first sighting.
        for (k, end_x) in [4.5, 4.25, 6.4, 6.4].into_iter().enumerate() {
            let x = 1.0 + 0.05 * k as f64;
            let mut d = Detection { row_end_ahead_m: Some(end_x - x), ..rows(0.1 * (k + 1) as f64, 0.0) };
            // Rows fitted past the reported end: no trim to the last centroid.
            for r in [d.left.as_mut(), d.right.as_mut()].into_iter().flatten() {
                r.line[2] = 10.0;
            }
            assert_eq!(sw.update(&Pose2::new(x, 0.0, 0.0), Some(&d)).mode, Mode::Following);
            assert!((sw.row_end().unwrap().x - end_x).abs() < 1e-9);
        }
    }
}
