//! The lane switcher's settings ([`LaneSwitchConfig`]) and the geometry derived from them: the lane
//! shift of a turn, where a turn may start, the robot's footprint and the pivots' clearance.

use serde::{Deserialize, Serialize};

use crate::control::headland::{Clearance, Footprint, PivotPlan, plan_pivots};
use crate::error::{ConfigError, check_range};

use super::GAP_ROWS;

/// Which way the robot turns at a row end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TurnDirection {
    /// Counter-clockwise, towards +y of `base_link`.
    Left,
    /// Clockwise, towards −y of `base_link`.
    Right,
}

impl TurnDirection {
    pub(super) fn sign(self) -> f64 {
        match self {
            TurnDirection::Left => 1.0,
            TurnDirection::Right => -1.0,
        }
    }
}

/// Settings of the lane-switching state machine and of the headland turn.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LaneSwitchConfig {
    /// Lanes to drive, the start lane included; 0 means every lane up to the field edge (needs
    /// `field_lanes`). Default 8 (the paper's 16-row whole field, Sec. V-C).
    pub lanes: u32,
    /// Lanes in the field, counted in the direction of the first turn; 0 when unknown. Default 0.
    pub field_lanes: u32,
    /// Index of the start lane (0 = the lane at the edge the first turn moves away from). Default 0.
    pub start_lane: u32,
    /// Lanes moved per switch: 1 goes to the adjacent lane (two row spacings over, the paper),
    /// 2 skips one. Default 1.
    pub lane_step: u32,
    /// Direction of the first turn; turns then alternate (Sec. III-B). Default right.
    pub first_turn: TurnDirection,
    /// Row spacing used for the turn geometry, m. Default 0.75 (Sec. V).
    pub row_spacing_m: f64,
    /// Cruise speed along the rows, m/s. Default 0.5.
    pub cruise_speed_mps: f64,
    /// Speed while clearing the row end and turning, m/s. Default 0.3.
    pub turn_speed_mps: f64,
    /// Speed while entering a new lane, m/s. Default 0.2.
    pub entry_speed_mps: f64,
    /// Radius of the two quarter arcs of the headland turn, m; 0 pivots in place, the turn that stays
    /// nearest to the row end (see the module docs). Default 0 (a skid-steer).
    pub turn_radius_m: f64,
    /// Distance kept along the rows between the swept tyre patches and the nearest plant, m, on top
    /// of `row_end_allowance_m` and the odometry drift (`odometry_drift_fraction`). Default 0.05.
    pub clearance_margin_m: f64,
    /// Distance a row's last stem may stand past the farthest row centroid the detector mapped on it,
    /// m: a centroid is the mean of a 0.25 m map bin, the last plants' canopy centre, so with two
    /// plants in the last bin (0.15-0.2 m apart) the last stem is half that past it. Default 0.05.
    pub row_end_allowance_m: f64,
    /// Odometry error per metre driven since the row ends were last seen, along and across the rows:
    /// wheel slip makes the wheels over-report the distance (the simulated soil slips 3 % ± 1 %, and
    /// the odometry over-reported 4.5-5.2 % on the soak's lanes), so a pivot planned 1.2 m past an end
    /// last seen 1.6 m ahead lands up to 0.14 m short. Default 0.05.
    pub odometry_drift_fraction: f64,
    /// Distance of the wheel contact points ahead of and behind `base_link`, m. Default 0.6095.
    pub wheel_x_m: f64,
    /// Distance of the wheel contact points to the side of `base_link`, m. Default 0.762.
    pub wheel_y_m: f64,
    /// Width of a tyre's contact patch, m. Default 0.15.
    pub tire_width_m: f64,
    /// Length of a tyre's contact patch, m. Default 0.12.
    pub tire_length_m: f64,
    /// Heading error at which a pivot is done and the robot drives on, rad. Default 0.05.
    pub pivot_tolerance_rad: f64,
    /// Deceleration planned to stop at a pivot or at the end of the mission, m/s². Default 0.25.
    pub stop_decel_mps2: f64,
    /// The row end is moved back to the farthest centroid of the lane's rows when that lies at most
    /// this far before the detector's canopy end, m; 0 keeps the canopy end. Default 0.5: one 0.25 m
    /// map bin plus the leaves' overhang.
    pub row_end_window_m: f64,
    /// Largest planned distance of `base_link` past the row end, m. Default 1.5 (Sec. V-C).
    pub max_headland_excursion_m: f64,
    /// Distance driven without any row while following before stopping, m. Default 1.0.
    pub max_blind_distance_m: f64,
    /// Distance to a row end the detector has seen within which missing or lost rows are expected
    /// and the robot drives on to the end, m. Default 2.5: the paper's mount sees no canopy nearer
    /// than about 1.6 m ahead of `base_link`, and the end estimate wobbles by a few decimetres.
    pub end_approach_m: f64,
    /// Largest lateral offset between the detected and the planned centre line of a new lane, m.
    /// Default 0.25 (a third of a row spacing: a neighbouring lane is 0.75 m or more away).
    pub entry_lateral_tolerance_m: f64,
    /// Largest heading difference between detected and planned centre line, and largest heading
    /// error of the robot, to confirm a new lane, rad. Default 0.15.
    pub entry_heading_tolerance_rad: f64,
    /// Largest lateral error of the robot from the planned lane to enter it, m. Default 0.1.
    pub entry_alignment_m: f64,
    /// Largest lateral offset of `base_link` from the centre line of the lane the detector agrees on
    /// at which the robot drives its front tyres into the new lane's crop, m; further off, it stops
    /// `clearance_margin_m` short of the row ends (`reentry_not_confirmed`) as it does while no
    /// detection agrees. Default 0.2: the tyres keep about 0.29 m to the rows at a 0.79 m spacing,
    /// and the robot's heading and the plants' width take the rest. Fault-free soak seed 799 agreed
    /// on a lane 0.23 m from its plan after a 3 m headland crossing (its odometry over-reads
    /// distance by 5 %), was still 0.28-0.30 m off it when its tyres reached the crop, and ran over
    /// 4 plants. The row spacing lets the robot in at any offset.
    pub entry_max_offset_m: f64,
    /// Consistent detections needed to confirm a lane (and inconsistent ones to refuse it). Default 3.
    pub entry_confirmations: u32,
    /// Deepest `base_link` may go into the field before the new lane is confirmed, m, once the
    /// detector agrees with the planned lane (the robot then tracks the rows it sees). Before any
    /// detection agrees, or while the robot is more than `entry_max_offset_m` off the lane it agrees
    /// on, the front tyres stop `clearance_margin_m` short of the new lane's row ends. Default 1.0.
    pub max_unconfirmed_entry_m: f64,
    /// Distance to the row end assumed when the detector reports the end of the row without saying
    /// where (the paper's pipeline, which sees the canopy thin out), m. Default 1.6: where the lowest
    /// beam of the paper's mount (1.5 m high, 30° down, 0.6 m ahead of `base_link`) meets a 0.5 m
    /// canopy, the nearest canopy a scan shows. The default pipeline reports the distance itself.
    pub default_row_end_ahead_m: f64,
    /// Largest relative difference between the row spacing a detection reports and `row_spacing_m`
    /// for its rows to be believed. Default 0.25: a detector locked on half or twice the row period
    /// (the two crests of a closed canopy) is 50 % off or more, while its online estimate stays within
    /// 10 % on the simulated fields (soak, issue 6). Rows not believed count as no row: the robot does
    /// not start, stops after `max_blind_distance_m`, or does not confirm a new lane. While acquiring,
    /// a tracked lattice outside it also resets the detector, which searches again: its fit, left to
    /// itself at rest, wanders (soak seeds 439 and 982: twice the spacing, then 20° off the rows
    /// within 5 s as the spacing shrank into the band, and the robot drove along it).
    pub spacing_tolerance: f64,
    /// Largest lateral jump, at the robot and 1.5 m ahead of it, of the detected centre line from
    /// the one being followed, m. A larger one (the rows of a neighbouring lane, seen for a scan) is not believed and counts
    /// as no row. Default 0.25 (a third of a row spacing; scan-to-scan changes are centimetres).
    pub max_line_jump_m: f64,
    /// Consecutive detections needed to leave a stop whose cause can clear by itself (`rows_lost`,
    /// `no_rows`: a LiDAR dropout, dust, a gap in the rows) and follow again: each must be `tracking`
    /// (or `end_of_row`) and its centre line within `entry_lateral_tolerance_m` and `entry_heading_tolerance_rad` of the
    /// line followed before the stop (the robot stood still: the lane cannot have changed). 0 latches
    /// every stop until [`LaneSwitcher::resume`]. Default 5 (half a second of scans at 10 Hz).
    pub resume_confirmations: u32,
    /// Least time the robot stands still in such a stop before it follows again when the rows it
    /// followed before the stop turned in `odom` (see `resume_rest_rad_per_m`), s; 0 resumes as
    /// soon as the detections agree. Such a stop is a stand for the gyro bias: the EKF's bias check finds a
    /// step at rest in one block (`ekf.bias_check_rest_s`, 1 s) that the moving blocks miss. Soak
    /// seed 664 (a -0.018 rad/s step 1.5 m before scans stamped 0.75 s off) stood 0.7 s at its
    /// `no_rows` stop, drove on with the bias unfound and pivoted 0.37 rad off at the row end (2
    /// plants, `wrong_lane`); with the stand it is done, 0 plants. On straight rows the stop is not
    /// lengthened: standing 1.5 s longer at each LiDAR dropout of `fault-lidar-dropout` moved its
    /// third dropout's re-entry onto a lattice half a spacing off near the row end (1 plant).
    /// Default 1.5, as `bias_dwell_s` (a second at rest after the wheels settle); without stamps
    /// ([`LaneSwitcher::set_time`]) it is not waited for.
    pub resume_rest_s: f64,
    /// Rate at which the followed rows' direction in `odom` (the followed path's, over the latest 2
    /// m before the stop, at least 1 m) must have turned for a stop to last `resume_rest_s`, rad/m.
    /// Half `bias_suspect_rad_per_m`: a false suspicion at a stop costs only the stand, not a stop
    /// in the rows. Measured: soak seed 664 0.0069 rad/m before its stop (the path lags the map,
    /// which lags a 0.036 rad/m heading error), `fault-lidar-dropout` 0.0025 at both its stops (the
    /// lane where standing longer cost a plant, see above). Default 0.005.
    pub resume_rest_rad_per_m: f64,
    /// Distance past the canopy end of the row end beyond which crop on the lane's rows means the
    /// "end" was a gap in the rows, m; from one map bin past the canopy end (where the last plants'
    /// centroids may still lie) up to this distance the rows must stay empty. Default 1.0: the
    /// detector calls an end after seeing 1 m of empty ground past the canopy
    /// (`detector.end_empty_m`); crop "appearing" inside that stretch contradicts what was seen (a
    /// LiDAR pitched off its mount reads the far ground as canopy), crop beyond it was out of view.
    pub gap_margin_m: f64,
    /// Rows, of the lane's two and their outer neighbours (the rows the detector ends a lane on),
    /// that must hold crop past the row end for it to count as a gap. Default 2: a weed on one row
    /// line or a stray return is not a row running on.
    pub gap_rows: u32,
    /// Consecutive scans, each tracking the rows without confirming the end, that must show crop
    /// past the row end, standing still while the robot drives 0.5 m towards it, before the end is
    /// dropped as a gap (see the module docs); 0 makes the first end seen final. Default 3 (0.3 s
    /// of scans at 10 Hz). It relies on the detector's levelling (`detector.level_enabled`): an
    /// unlevelled LiDAR pitched 3° off its mount reads the ground at the scan's far edge as canopy
    /// past a true row end, which this rule cannot tell from crop beyond a gap (the robot then
    /// followed phantom rows out of the field for 150 m, `fault-mount-error`).
    pub gap_confirmations: u32,
    /// Farthest a reported row end is believed past where the lane's end was first seen, m. A row
    /// end is a place: one that keeps moving away ahead of the robot is canopy seen everywhere (a
    /// tilted LiDAR reading the ground as crop), not the end of the rows. Farther reports are not
    /// taken; `end_recession_scans` of them stop the robot (`row_end_receding`). A gap across the rows
    /// (crop beyond an empty stretch, see `gap_confirmations`) starts the count over at the next end.
    /// Default 2.0: the end of a grown soybean lane was seen to move out 1-2 m as the robot came
    /// closer (soak seed 11); a tilted LiDAR's phantom end keeps moving.
    pub max_end_recession_m: f64,
    /// Reports of a row end past `max_end_recession_m` that stop the robot. Default 5.
    pub end_recession_scans: u32,
    /// Time the robot stands still where it starts to clear a row end when the rows turned in
    /// `odom` while it followed them (see `bias_suspect_rad_per_m`), s; 0 never stops there. At rest
    /// the EKF's bias check finds a gyro bias step in one block (`ekf.bias_check_rest_s`, 1 s), which
    /// the pivots would otherwise turn by for 10-15 s blind. Default 1.5 (a second at rest after the
    /// wheels settle); the stop costs about 3 s with braking and starting (docs/faults.md).
    pub bias_dwell_s: f64,
    /// Rate at which the followed rows' direction in `odom` must turn, over each 2 m driven, for a
    /// gyro bias error to be suspected, rad/m. The rows stay where they are: their direction in
    /// `odom` turns by the odometry's heading error, the bias error over the speed (0.021 rad/s at
    /// 0.5 m/s is 0.042 rad/m), of which the map fit follows about two thirds (soak seed 664: 0.017
    /// of 0.026 rad/m). Default 0.01 (a 0.0075 rad/s bias error at cruise speed): the soak's curved
    /// rows bend by at most 0.004 rad/m, a fit's heading wobbles by about 0.01 rad per 2 m. A false
    /// suspicion costs one stand.
    pub bias_suspect_rad_per_m: f64,
    /// Stands of `bias_dwell_s` per lane in the middle of the rows, as soon as a gyro bias error is
    /// suspected there (`bias_suspect_rad_per_m`), instead of only at the row end. While following,
    /// the detector's map lives in `odom`; a bias error turns it and bends the fitted rows: the soak's
    /// steps of 0.022-0.027 rad/s that the moving blocks missed drove the robot 20 cm off the lane
    /// centre within 4 m while the detection read it centred (seeds 41, 55, 495: 20 plants). Standing
    /// lets the EKF find the bias at rest (`ekf.bias_check_rest_s`) before the bend reaches a row.
    /// Default 0 (off: stands only at the row end). With 1 (the stand costs about 3 s; a second
    /// suspicion in the lane waits for the row end) seeds 41 and 55 ran over 0 plants and were done,
    /// but a fit's wobble on the 200 m grown-soybean lane of Table I stood the robot once mid-row and
    /// its following error grew 1.07 -> 1.29 cm for the rest of the lane; asking for a faster turn
    /// (0.02 rad/m) before standing avoided that stand and missed both seeds (docs/faults.md).
    pub row_bias_stands: u32,
    /// Largest relative difference between the row spacing a detection reports and `row_spacing_m`
    /// while following the lane or stopped in it, the tighter of this and `spacing_tolerance`. A lattice
    /// 18-22 % narrower than planted, taken up from a scan with a sector missing or on re-entry in a
    /// closed canopy, was followed 20-27 cm off the lane centre into a row (soak seeds 7, 168, 310: 37
    /// plants), while the online estimate of the lanes followed stays within 10 % (see
    /// `spacing_tolerance`). Rows not believed count as no row: the robot stops after
    /// `max_blind_distance_m` (`no_rows`). Default 0.15; 0.25 (or more) leaves `spacing_tolerance` alone.
    pub following_spacing_tolerance: f64,
    /// Largest heading of a lane's centre line relative to the robot, rad, for the robot to start
    /// following it from `acquiring`. A robot is set down in its lane roughly along it (the soak
    /// within ±3°, the recovery runs at ±8°); a lane further off is a fit that is not the crop's
    /// lattice: tall weeds filling the view (soak seed 31: 15°), a metre of row before a gap across
    /// every row (337: 26°), a closed canopy's fit wandering at rest (439, 982: 19-21°). Such a lane
    /// resets the detector, which searches again, and the robot waits. Default 0.2 (11.5°).
    pub max_start_heading_rad: f64,
    /// Largest sideways drift of `odom` against the canopy that the detector may measure while the
    /// robot follows a lane, m per metre driven (canopy registration: a wheel slide on wet soil, or a
    /// gyro bias the EKF has not learnt, whose turn of `odom` reads the same). At or past it the robot
    /// stops (`sliding`) and waits for a person rather than drive on with a row map that lags the
    /// slide: the lag grows a few centimetres per metre and a correction moves the lane 5 cm at once
    /// (soak seed 78: 3 plants with the stop off, none with it on). The reading is the detector's
    /// (`RowDetector::slide_per_m`: registration's, or the opt-in slide test's). Default 0.1: in the
    /// 1000-run soak it stopped 88 runs (39 with a wheel slide, 43 with a gyro bias step, 5 with other
    /// faults, one without any) and took the contacts from 93 plants in 26 runs to 58 in 14
    /// (docs/faults.md, session 30); a 2 cm/s slide (`fault-slip-patch`, read at 0.05-0.06) is driven
    /// through. 0 turns the stop off.
    pub max_slide_per_m: f64,
    /// Farthest the lane may lag a slide the slide watch measures (`detector.register_rest_watch`),
    /// m: the watch's correction ahead of the one the lanes run on, along the slide. With the watch
    /// finding a slide of at least half `max_slide_per_m` and the lanes lagging it this far or
    /// more, the robot stops (`sliding`), as at `max_slide_per_m`. The registration the lanes run on
    /// waits a metre of lane and then its own significance, so a slide from the first metres under
    /// the limit reaches the crop before the lanes follow it: soak seed 78 slid 0.06-0.09 m/m, the
    /// lanes lagged the watch by 15 cm and a tyre took 2 plants. Default 0.08: over Table I's 200 m
    /// runs, fault-free, the lag passed it only with the watch's slide under 0.03 m/m (it is a random
    /// walk over a long lane), and the stop costs 27 runs done of the 2000-run soak for 3 plants
    /// (docs/faults.md, session 42). At 0.045 two of the soak's three remaining slides stop before
    /// the crop (13, 1106: 1 plant in 1 run over the 2000 seeds, against 5 in 3), but 44 runs fewer
    /// are done, 15 fault-free runs stop against 2, and a 2 cm/s wet patch is no longer driven
    /// through (session 49); `slipping_slide_lag_m` asks 0.045 only where the wheels slip. 0 turns
    /// the stop off.
    pub max_slide_lag_m: f64,
    /// The lag stop's limit while the wheels are seen slipping (the odometry's slip witness,
    /// `NavInput::wheel_slip`, at `slipping_min_slip` or more), m; the watch must still find a slide
    /// of half `max_slide_per_m`. Wet soil is where slides happen, and a slipping wheel overcounts
    /// the distance, which makes registration read a slide short (session 43): the soak's three
    /// contacts were slides in wet patches the lanes caught up with late. Default 0.045: at that
    /// limit everywhere, two of the three stopped before the crop, but 15 fault-free runs stopped
    /// too (session 49); asked only where the wheels slip, the same two stop (13, 1106: 1 plant in 1
    /// run over the 2000 seeds against 5 in 3), 7 runs fewer are done, no fault-free run stops more,
    /// and a 2 cm/s wet patch (`fault-slip-patch`) stops 5.5 m in (session 50). At or over
    /// `max_slide_lag_m` it changes nothing; 0 turns it off.
    pub slipping_slide_lag_m: f64,
    /// Least slip ratio the odometry's witness must read for `slipping_slide_lag_m`. Default 0.2:
    /// the soak's wet patches slip 0.2-0.4, dry soil 0.03; fault-free following reads over 0.2 now
    /// and then, but with the watch's slide and lag also asked the 2000-run soak stopped no
    /// fault-free run more (session 50).
    pub slipping_min_slip: f64,
    /// Tightest turn while following rows, 1/m: the navigator holds the command's yaw rate within
    /// this times the forward speed the MPC plans (its first step's, before the acceleration limit),
    /// plus 0.02 rad/s. Rows bend gently (the paper's curved field at most 0.024 1/m), yet a robot just
    /// set down, or one whose lattice jumped, was swung 13-23° towards a fresh lattice before it had
    /// rolled a metre, which turned the view the detector tracks (soak seed 1390, fault-free grown
    /// corn: a 0.23 rad swing at the start, then the whole lane 14-23 cm off the centre line; that
    /// offset came from the start-up search, a lane centre a quarter spacing off, since mended). Default
    /// 0 (off): at 0.5 the soak's seeds 1000-1999 ran over 36 plants instead of 86, but seeds 0-999
    /// 46 instead of 39 (fault-free 765: 0 -> 5), as many runs touched plants over the 2000 (24),
    /// 24 fewer were done, and the `recovery` start (0.3 m, 8° off) ran over 12 plants instead of 9
    /// (docs/faults.md, session 32).
    pub max_following_curvature_per_m: f64,
    /// The planned direction holds a new lane's rows while the robot enters it and for this distance
    /// followed, m: the rows seen must run within `entry_heading_tolerance_rad` of the turned-at
    /// lane's rows at its end, reversed (`odom`; the rows are parallel). A fit that turns a little
    /// from scan to scan passes a comparison with the scan before: in a closed canopy the lattice is
    /// weakly held sideways, and a fit that took up a turn on entry was followed across two rows (soak
    /// seed 765, fault-free grown corn: 0.18 rad off at the first scan followed, 13 plants). While
    /// entering, rows off the planned direction ask the detector to search again and do not count for
    /// or against the lane (the robot drives on; the entry limits still stop it); once following, they
    /// stop the robot (`wrong_lane`). Rows that curve by more than the tolerance within this distance
    /// of the headland, or a heading the odometry lost in the turn (an unlearnt gyro bias step), are
    /// refused too. Default 2; 0 turns the hold off (the entry compares each scan with the last only).
    pub entry_heading_watch_m: f64,
    /// Most the followed rows may turn in `odom` over 1 m driven with rows seen, rad: past it, twice
    /// in a row the same way round (one measurement every 0.25 m), the robot stops (`wrong_lane`).
    /// Crop rows bend gently (the paper's curved field at most 0.024 rad per metre, the soak's under
    /// 0.004) and an unlearnt gyro bias turns `odom` by its error over the speed (the soak's largest
    /// steps, 0.027 rad/s at 0.5 m/s: 0.054 rad/m); a fit that turns faster follows something else.
    /// Where a gap crosses every row, a strip of tall weeds in it took the fit 0.14-0.15 rad round
    /// within a metre, and the robot followed it over a plant (soak seeds 324 and 680). Not checked
    /// within `end_approach_m` of a row end the detector has seen: a fit found again there after a
    /// LiDAR dropout, on the last 2 m of rows, ran 0.2 rad off (`fault-lidar-dropout`), and the line
    /// is carried to the end there. Default 0.1; 0 turns the watch off.
    pub max_row_turn_rad: f64,
}

impl Default for LaneSwitchConfig {
    fn default() -> Self {
        Self {
            lanes: 8,
            field_lanes: 0,
            start_lane: 0,
            lane_step: 1,
            first_turn: TurnDirection::Right,
            row_spacing_m: 0.75,
            cruise_speed_mps: 0.5,
            turn_speed_mps: 0.3,
            entry_speed_mps: 0.2,
            turn_radius_m: 0.0,
            clearance_margin_m: 0.05,
            row_end_allowance_m: 0.05,
            odometry_drift_fraction: 0.05,
            wheel_x_m: 0.6095,
            wheel_y_m: 0.762,
            tire_width_m: 0.15,
            tire_length_m: 0.12,
            pivot_tolerance_rad: 0.05,
            stop_decel_mps2: 0.25,
            row_end_window_m: 0.5,
            max_headland_excursion_m: 1.5,
            max_blind_distance_m: 1.0,
            end_approach_m: 2.5,
            entry_lateral_tolerance_m: 0.25,
            entry_heading_tolerance_rad: 0.15,
            entry_alignment_m: 0.1,
            entry_max_offset_m: 0.2,
            entry_confirmations: 3,
            max_unconfirmed_entry_m: 1.0,
            default_row_end_ahead_m: 1.6,
            spacing_tolerance: 0.25,
            max_line_jump_m: 0.25,
            resume_confirmations: 5,
            resume_rest_s: 1.5,
            resume_rest_rad_per_m: 0.005,
            gap_margin_m: 1.0,
            gap_rows: 2,
            gap_confirmations: 3,
            max_end_recession_m: 2.0,
            end_recession_scans: 5,
            bias_dwell_s: 1.5,
            bias_suspect_rad_per_m: 0.01,
            row_bias_stands: 0,
            following_spacing_tolerance: 0.15,
            max_start_heading_rad: 0.2,
            max_slide_per_m: 0.1,
            max_slide_lag_m: 0.08,
            slipping_slide_lag_m: 0.045,
            slipping_min_slip: 0.2,
            max_following_curvature_per_m: 0.0,
            entry_heading_watch_m: 2.0,
            max_row_turn_rad: 0.1,
        }
    }
}

impl LaneSwitchConfig {
    /// Checks every field and the turn geometry, naming the first bad field (`lane_switch.<field>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("lane_switch.lanes", self.lanes as f64, 0.0, 10_000.0)?;
        check_range("lane_switch.lane_step", self.lane_step as f64, 1.0, 100.0)?;
        check_range("lane_switch.row_spacing_m", self.row_spacing_m, 0.1, 5.0)?;
        check_range("lane_switch.cruise_speed_mps", self.cruise_speed_mps, 0.01, 5.0)?;
        check_range("lane_switch.turn_speed_mps", self.turn_speed_mps, 0.01, 5.0)?;
        check_range("lane_switch.entry_speed_mps", self.entry_speed_mps, 0.01, 5.0)?;
        check_range("lane_switch.wheel_x_m", self.wheel_x_m, 0.0, 5.0)?;
        check_range("lane_switch.wheel_y_m", self.wheel_y_m, 0.0, 5.0)?;
        check_range("lane_switch.tire_width_m", self.tire_width_m, 0.0, 2.0)?;
        check_range("lane_switch.tire_length_m", self.tire_length_m, 0.0, 2.0)?;
        check_range("lane_switch.pivot_tolerance_rad", self.pivot_tolerance_rad, 0.001, 0.5)?;
        check_range("lane_switch.stop_decel_mps2", self.stop_decel_mps2, 0.01, 10.0)?;
        check_range("lane_switch.row_end_window_m", self.row_end_window_m, 0.0, 5.0)?;
        check_range("lane_switch.clearance_margin_m", self.clearance_margin_m, 0.0, 10.0)?;
        check_range("lane_switch.row_end_allowance_m", self.row_end_allowance_m, 0.0, 5.0)?;
        check_range("lane_switch.odometry_drift_fraction", self.odometry_drift_fraction, 0.0, 0.5)?;
        check_range("lane_switch.max_headland_excursion_m", self.max_headland_excursion_m, 0.1, 50.0)?;
        check_range("lane_switch.max_blind_distance_m", self.max_blind_distance_m, 0.0, 100.0)?;
        check_range("lane_switch.end_approach_m", self.end_approach_m, 0.0, 10.0)?;
        check_range(
            "lane_switch.entry_lateral_tolerance_m",
            self.entry_lateral_tolerance_m,
            0.01,
            self.row_spacing_m,
        )?;
        check_range("lane_switch.entry_heading_tolerance_rad", self.entry_heading_tolerance_rad, 0.001, 1.0)?;
        check_range("lane_switch.entry_alignment_m", self.entry_alignment_m, 0.001, self.row_spacing_m)?;
        check_range("lane_switch.entry_max_offset_m", self.entry_max_offset_m, 0.001, self.row_spacing_m)?;
        check_range("lane_switch.entry_confirmations", self.entry_confirmations as f64, 1.0, 1000.0)?;
        check_range("lane_switch.max_unconfirmed_entry_m", self.max_unconfirmed_entry_m, 0.0, 100.0)?;
        check_range("lane_switch.default_row_end_ahead_m", self.default_row_end_ahead_m, -10.0, 10.0)?;
        check_range("lane_switch.spacing_tolerance", self.spacing_tolerance, 0.01, 10.0)?;
        check_range("lane_switch.max_line_jump_m", self.max_line_jump_m, 0.01, 10.0)?;
        check_range("lane_switch.resume_confirmations", f64::from(self.resume_confirmations), 0.0, 1000.0)?;
        check_range("lane_switch.resume_rest_s", self.resume_rest_s, 0.0, 30.0)?;
        check_range("lane_switch.resume_rest_rad_per_m", self.resume_rest_rad_per_m, 1e-4, 1.0)?;
        check_range("lane_switch.max_start_heading_rad", self.max_start_heading_rad, 0.01, 1.0)?;
        check_range("lane_switch.max_slide_per_m", self.max_slide_per_m, 0.0, 1.0)?;
        check_range("lane_switch.max_slide_lag_m", self.max_slide_lag_m, 0.0, 10.0)?;
        check_range("lane_switch.slipping_slide_lag_m", self.slipping_slide_lag_m, 0.0, 10.0)?;
        check_range("lane_switch.slipping_min_slip", self.slipping_min_slip, 0.0, 1.0)?;
        check_range(
            "lane_switch.max_following_curvature_per_m",
            self.max_following_curvature_per_m,
            0.0,
            100.0,
        )?;
        check_range("lane_switch.entry_heading_watch_m", self.entry_heading_watch_m, 0.0, 1000.0)?;
        check_range("lane_switch.max_row_turn_rad", self.max_row_turn_rad, 0.0, std::f64::consts::PI)?;
        check_range("lane_switch.gap_margin_m", self.gap_margin_m, 0.0, 10.0)?;
        check_range(
            "lane_switch.gap_rows",
            f64::from(self.gap_rows),
            1.0,
            f64::from(GAP_ROWS.end() - GAP_ROWS.start() + 1),
        )?;
        check_range("lane_switch.gap_confirmations", f64::from(self.gap_confirmations), 0.0, 1000.0)?;
        check_range("lane_switch.max_end_recession_m", self.max_end_recession_m, 0.1, 100.0)?;
        check_range("lane_switch.end_recession_scans", f64::from(self.end_recession_scans), 1.0, 1000.0)?;
        check_range("lane_switch.bias_dwell_s", self.bias_dwell_s, 0.0, 30.0)?;
        check_range("lane_switch.bias_suspect_rad_per_m", self.bias_suspect_rad_per_m, 1e-3, 1.0)?;
        check_range("lane_switch.row_bias_stands", f64::from(self.row_bias_stands), 0.0, 100.0)?;
        check_range("lane_switch.following_spacing_tolerance", self.following_spacing_tolerance, 0.01, 10.0)?;
        let shift = self.shift_m();
        check_range("lane_switch.turn_radius_m", self.turn_radius_m, 0.0, 0.5 * shift)?;
        let reach = self.turn_excursion_m();
        if reach > self.max_headland_excursion_m {
            return Err(ConfigError::invalid(
                "lane_switch.max_headland_excursion_m",
                format!(
                    "the turn reaches {reach:.3} m past the row end (turn start {:.3} m + turn_radius_m), over {}",
                    self.turn_start_m(),
                    self.max_headland_excursion_m
                ),
            ));
        }
        if self.lanes == 0 && self.field_lanes == 0 {
            return Err(ConfigError::invalid(
                "lane_switch.lanes",
                "0 (all lanes) needs lane_switch.field_lanes",
            ));
        }
        if self.field_lanes > 0 {
            if self.start_lane >= self.field_lanes {
                return Err(ConfigError::invalid(
                    "lane_switch.start_lane",
                    "must be below lane_switch.field_lanes",
                ));
            }
            let last =
                u64::from(self.start_lane) + u64::from(self.lanes.max(1) - 1) * u64::from(self.lane_step);
            if last >= u64::from(self.field_lanes) {
                return Err(ConfigError::invalid(
                    "lane_switch.lanes",
                    format!("lane {last} would be needed but the field has {} lanes", self.field_lanes),
                ));
            }
        }
        Ok(())
    }

    /// Lateral distance between two consecutive lanes driven, m.
    pub fn shift_m(&self) -> f64 {
        2.0 * self.row_spacing_m * f64::from(self.lane_step)
    }

    /// Distance `d₀` of `base_link` past the row end where the turn starts on a square headland with
    /// rows `row_spacing_m` apart, m: the least that keeps every tyre patch off the crop during the
    /// turn, plus the clearance budget (see the module docs). A pivot turn starts no nearer than this
    /// and farther where the measured row ends need it.
    pub fn turn_start_m(&self) -> f64 {
        if self.pivots() {
            // A square headland is symmetric: either side gives the same pivots.
            return self.pivot_plan(self.row_spacing_m, 1.0, |_| 0.0).excursion_m();
        }
        let r = self.turn_radius_m;
        let (half_l, half_w) = (0.5 * self.tire_length_m, 0.5 * self.tire_width_m);
        let reach = (self.wheel_x_m + half_l).hypot((self.wheel_y_m - r).abs() + half_w);
        // Lateral distance from the turning centre to the nearest row line, (k + ½)·spacing.
        let phase = (r / self.row_spacing_m - 0.5).rem_euclid(1.0);
        let nearest = phase.min(1.0 - phase) * self.row_spacing_m;
        let swing = (reach * reach - nearest * nearest).max(0.0).sqrt();
        let sideways = self.wheel_y_m + half_w - r;
        let outer_rear = if r > 0.0 { self.wheel_x_m + half_l } else { 0.0 };
        let budget = self.clearance();
        swing.max(sideways).max(outer_rear)
            + self.clearance_margin_m
            + budget.allowance_m
            + budget.drift_fraction * (budget.view_m + reach)
    }

    /// The tyre patches.
    pub fn footprint(&self) -> Footprint {
        Footprint {
            wheel_x_m: self.wheel_x_m,
            wheel_y_m: self.wheel_y_m,
            tire_length_m: self.tire_length_m,
            tire_width_m: self.tire_width_m,
        }
    }

    fn clearance(&self) -> Clearance {
        Clearance {
            margin_m: self.clearance_margin_m,
            allowance_m: self.row_end_allowance_m,
            drift_fraction: self.odometry_drift_fraction,
            view_m: self.default_row_end_ahead_m.max(0.0),
        }
    }

    /// The pivots of a turn `side` (+1 left, −1 right) between lanes of rows `spacing_m` apart,
    /// the rows ending `row_end_m(q)` past the row-end line (see [`plan_pivots`]).
    pub(super) fn pivot_plan(&self, spacing_m: f64, side: f64, row_end_m: impl Fn(i32) -> f64) -> PivotPlan {
        let shift = 2.0 * spacing_m * f64::from(self.lane_step) * side;
        plan_pivots(&self.footprint(), &self.clearance(), spacing_m, shift, row_end_m)
    }

    /// Planned largest distance of `base_link` past the row end, m: `turn_start_m + turn_radius_m`.
    pub fn turn_excursion_m(&self) -> f64 {
        self.turn_start_m() + self.turn_radius_m
    }

    /// True when the turn pivots in place (`turn_radius_m` = 0).
    pub fn pivots(&self) -> bool {
        self.turn_radius_m <= 0.0
    }

    /// Number of lanes this mission drives.
    pub fn lane_count(&self) -> u32 {
        if self.lanes > 0 {
            self.lanes
        } else {
            self.field_lanes.saturating_sub(self.start_lane.saturating_add(1)) / self.lane_step.max(1) + 1
        }
    }
}
