//! Croprow's default pipeline after preprocessing: every visible row is one member of a family of
//! parallel, optionally curved lines
//!
//! ```text
//! y_j(x) = o + (j + ½)·s + a·x + b·x²        (base_link, j = 0 first row left, j = -1 first row right)
//! ```
//!
//! with the lane-centre offset `o`, the heading slope `a`, the curvature term `b` and the row spacing `s`
//! all estimated together, so a missing or gappy row borrows from its neighbours and the spacing is
//! learned online (crop-agnostic). Each scan:
//!
//! 1. **predict**: the previous lane, carried into the new `base_link` by the odometry (or, at start-up, a
//!    search: the heading that makes the lateral histogram of canopy points sharpest, the spacing from its
//!    autocorrelation, the phase from its circular mean);
//! 2. **measure**: canopy points gated to the predicted rows are binned per row and per `map_bin_m` along
//!    x; each bin centroid enters the [`CentroidMap`] in `odom` (like the paper's centroids, without
//!    K-means);
//! 3. **correct**: a weighted least-squares fit of `(o, s, a, b)` to the map centroids from `behind_m` behind
//!    the robot onwards, regularised towards the prediction (a filter in information form), re-gated once
//!    with Cauchy weights so weeds and stray plants do not pull it;
//! 4. **row end**: the canopy of the lane is declared ended where at least `end_empty_m` of visible ground
//!    follows the last canopy bin; the end is kept in `odom` and cleared if canopy reappears (a gap).
//!
//! The start-up search lives in [`search`], the opt-in slide test in [`slide`].

use std::collections::VecDeque;

use nalgebra::{Matrix3, Matrix4, Matrix5, Vector3, Vector4, Vector5};

use crate::geometry::{Pose2, wrap_angle};

use super::RowEstimate;
use super::config::DetectorConfig;
use super::holes::Holes;
use super::interleave::for_each_interleaved;
use super::map::CentroidMap;

mod search;
mod slide;

use slide::SLIDE_CAPACITY;

/// Offset that keeps row numbers positive for the truncating cast in [`Lane::assign`]; far beyond any
/// row that is tracked.
const ROUND_BIAS: f64 = 1024.0;
/// The map takes a new set of centroids once the robot has moved this far (m) or turned this much (rad)
/// since the last set: at rest it would otherwise fill with copies of one view.
const KEYFRAME_M: f64 = 0.15;
const KEYFRAME_RAD: f64 = 0.035;
/// Distance driven after which a map centroid's weight has halved, m (odometry drift ages it).
const AGE_SCALE_M: f64 = 3.0;
/// Rows tracked: j in `J_MIN..J_MIN + ROWS` (four each side).
const J_MIN: i32 = -4;
const ROWS: usize = 8;
/// The rows whose canopy decides the row end: the lane's two rows and their outer neighbours.
const NEAR_ROWS: [i32; 4] = [-2, -1, 0, 1];
/// Lateral histogram of the start-up search: bin (m) and half-width (m).
const HIST_BIN_M: f64 = 0.02;
const HIST_BINS: usize = 500;
const HIST_HALF_M: f64 = HIST_BIN_M * HIST_BINS as f64 * 0.5;
/// Along-x bins start this far behind `base_link`, m.
const X_LO_M: f64 = -1.0;
/// Bin centroids count fully from this many points on (weight min(n, W)/W).
const FULL_WEIGHT_POINTS: f64 = 20.0;
/// Keeps the height weight of a point right at the plane above zero, m².
const HEIGHT_WEIGHT_FLOOR_M2: f64 = 1e-4;
/// Scale of the Cauchy weight on the lateral residual in the second fit pass, m.
const CAUCHY_M: f64 = 0.05;
/// Prior weights of the correction, in units of one full-weight centroid: the spacing changes slowly;
/// the curvature term is anchored as if by eight centroids 4 m ahead (curvature changes over tens of
/// metres; a freer term trades heading precision at the robot for nothing: measured on the simulated
/// Table I runs, two centroids gave 0.26° mean heading error on straight young corn, eight 0.18°, with
/// curved rows at 0.21°); offset and heading are left free (a heading prior is opt-in:
/// `DetectorConfig::heading_prior_m2`).
const PRIOR_SPACING: f64 = 5.0;
const PRIOR_CURVATURE: f64 = 8.0 * 256.0;
const PRIOR_FREE: f64 = 1e-3;
/// Prior weight that holds a term at its prior value (a term not fitted).
const PINNED: f64 = 1e12;
const ENVELOPE_SLICES: usize = 16;
/// Lateral cells per bin across its gate, for the peak test of [`Lanes::peaks_inside`]: one cell is
/// about 3 cm wide at a 0.75 m spacing.
const CELLS: usize = 16;
/// Most moves of the peak test's window; it settles after two or three.
const PEAK_STEPS: usize = 4;
/// Fewest centroids from the current scan for it to count as seeing the rows.
const MIN_FRESH_CENTROIDS: usize = 2;
/// While a hole hides the lane's own rows, the map holds them as long as it reaches this far ahead
/// of `base_link` on both, m.
const HOLE_MAP_REACH_M: f64 = 3.0;
/// Least total centroid weight (full-weight centroids) for a correction to be accepted.
const MIN_FIT_WEIGHT: f64 = 3.0;

/// The row family in `base_link`: centre line `o + a·x + b·x²` and canopy period `s`, m. The canopy
/// repeats `crests` times per row spacing: 1, or 2 for a grown canopy whose leaves crest either side of
/// the row (see [`Lanes::search`]). The fit tracks the canopy's own period, whose crests are the stable
/// features; the rows it reports are `crests · s` apart about the same centre line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Lane {
    pub(crate) o: f64,
    pub(crate) a: f64,
    pub(crate) b: f64,
    pub(crate) s: f64,
    pub(crate) crests: f64,
}

impl Lane {
    fn centre(&self, x: f64) -> f64 {
        self.o + self.a * x + self.b * x * x
    }

    /// Row spacing, m.
    pub(crate) fn spacing_m(&self) -> f64 {
        self.crests * self.s
    }

    /// Canopy crest `j` (the lattice's own index, as [`Lane::assign`] gives it) at `x`, m.
    fn crest_y(&self, j: i32, x: f64) -> f64 {
        self.centre(x) + (j as f64 + 0.5) * self.s
    }

    /// Reported row `j` (not a canopy crest) at `x`, m.
    fn row_y(&self, j: i32, x: f64) -> f64 {
        self.centre(x) + (j as f64 + 0.5) * self.spacing_m()
    }

    /// Row index and signed lateral residual of a point, m.
    fn assign(&self, x: f64, y: f64) -> (i32, f64) {
        let r = ((y - self.centre(x)) / self.s - 0.5).clamp(-ROUND_BIAS, ROUND_BIAS);
        // Rounding by a biased truncating cast: `f64::round` is a libm call on baseline x86-64, and this
        // runs for every canopy point.
        let j = (r + ROUND_BIAS + 0.5) as i32 - ROUND_BIAS as i32;
        (j, (r - j as f64) * self.s)
    }

    /// The same lane with its centre moved by whole spacings to the one nearest the robot, so that
    /// j = 0 / -1 stay the first rows left / right after the robot crosses a row. Whole row spacings,
    /// not canopy periods: with two crests per spacing a period would put the centre on a row.
    fn normalised(self) -> Self {
        let spacing = self.spacing_m();
        Self { o: self.o - spacing * (self.o / spacing).round(), ..self }
    }

    fn is_sane(&self, config: &DetectorConfig) -> bool {
        [self.o, self.a, self.b, self.s].iter().all(|v| v.is_finite())
            && self.a.abs() < 1.0
            && self.b.abs() < 0.5
            && self.s >= config.spacing_min_m
            && self.spacing_m() <= config.spacing_max_m
            && self.near_planted(config)
    }

    /// True unless the planted spacing is known and this lane's spacing is more than
    /// `planted_spacing_tolerance` off it: rows at another spacing are not this field's.
    fn near_planted(&self, config: &DetectorConfig) -> bool {
        let planted = config.planted_spacing_m;
        planted <= 0.0 || (self.spacing_m() - planted).abs() <= config.planted_spacing_tolerance * planted
    }

    /// The lane seen from `to`, given in the `base_link` of `from` (both poses in `odom`): three points of
    /// the centre line are moved and the quadratic through them is solved exactly.
    fn transport(&self, from: &Pose2, to: &Pose2) -> Option<Self> {
        let mut m = Matrix3::zeros();
        let mut v = Vector3::zeros();
        for (i, x) in [0.0, 2.0, 4.0].into_iter().enumerate() {
            let (ox, oy) = from.transform_point(x, self.centre(x));
            let (bx, by) = to.inverse_transform_point(ox, oy);
            m[(i, 0)] = 1.0;
            m[(i, 1)] = bx;
            m[(i, 2)] = bx * bx;
            v[i] = by;
        }
        let p = m.lu().solve(&v)?;
        Some(Self { o: p[0], a: p[1], b: p[2], ..*self }.normalised())
    }

    /// Row `j` as the detector reports it, from the robot to `x_far_m`.
    pub(crate) fn row(&self, j: i32, x_far_m: f64, confidence: f64) -> RowEstimate {
        let x2 = x_far_m.max(1.0);
        RowEstimate {
            line: [0.0, self.row_y(j, 0.0), x2, self.row_y(j, x2)],
            offset_m: self.row_y(j, 0.0),
            heading_rad: self.a.atan(),
            curvature_per_m: 2.0 * self.b / (1.0 + self.a * self.a).powf(1.5),
            confidence: confidence.clamp(0.0, 1.0),
        }
    }
}

/// One per-row, per-x bin of canopy points: count and sums, `base_link`.
#[derive(Debug, Clone, Copy, Default)]
struct Bin {
    n: u32,
    w: f64,
    sx: f64,
    sy: f64,
}

/// One lateral cell of a bin: the height weight of its points and that weight times their residual
/// from the predicted row, m.
#[derive(Debug, Clone, Copy, Default)]
struct Cell {
    w: f64,
    wd: f64,
}

/// What the default pipeline knows after a scan.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct LaneOutput {
    /// The row family in `base_link`, when one is tracked.
    pub(crate) lane: Option<Lane>,
    /// True when this scan's evidence corrected the lane.
    pub(crate) updated: bool,
    /// Centroid weight supporting the first row left and right (full-weight centroids).
    pub(crate) support: [f64; 2],
    /// Farthest supporting centroid of the first row left and right, m along x.
    pub(crate) far_x_m: [f64; 2],
    /// Distance from `base_link` along the rows to the canopy end, m, once seen.
    pub(crate) row_end_ahead_m: Option<f64>,
}

/// State and buffers of the default pipeline, allocated once.
#[derive(Debug, Clone)]
pub(crate) struct Lanes {
    model: Option<(Lane, Pose2)>,
    last_update_s: f64,
    bins: Vec<Bin>,
    /// Lateral profile of every bin across its gate, bin-major ([`CELLS`] per bin).
    cells: Vec<Cell>,
    visible: Vec<u32>,
    /// Bins a hole of this scan reaches into (see [`Lanes::mark_holes`]), and whether any does.
    in_hole: Vec<bool>,
    any_in_hole: bool,
    /// This scan's centroids on the lane's own rows (the first left and right).
    own_rows_fresh: usize,
    x_bins: usize,
    hist: Vec<f64>,
    /// Lateral histograms of the start-up search: ground returns (cropped, not canopy), then their
    /// share of all returns; all returns.
    ground: Vec<f64>,
    returns: Vec<f64>,
    /// Upper envelope of the start-up search: the highest canopy point per lateral bin, demeaned, and
    /// whether the bin holds canopy at all.
    envelope: Vec<f64>,
    filled: Vec<bool>,
    /// Highest canopy point per along-x slice and lateral bin, slice-major (0: none).
    slices: Vec<f64>,
    /// Per lateral bin, how many of those slices hold canopy (see [`Lanes::lane_contrast`]).
    occupancy: Vec<f64>,
    /// Centroids of the fit, `[x, y, weight, age]` in `base_link`, the age in metres driven since the
    /// centroid was stored.
    local: Vec<[f64; 4]>,
    /// This scan's centroids, `[x, y, weight]` in `base_link`.
    current: Vec<[f64; 3]>,
    /// Pose of the last centroids stored in the map.
    last_key: Option<Pose2>,
    /// Distance driven (odometry), m, and the pose it was last updated at.
    odometer_m: f64,
    /// Counts the lane hypotheses started, so that a caller can tell a new lane from the one before.
    generation: u32,
    last_pose: Option<Pose2>,
    /// Row end in `odom`: point on the lane centre and the row direction, rad.
    end: Option<[f64; 3]>,
    /// Shear of the map found by the last correction, m per metre driven (see [`Lanes::correct`]).
    shear_per_m: f64,
    /// Start-up confirmation of a searched lane (see [`Lanes::confirm`]): the lane and pose the current
    /// run of agreeing scans started from, and how many scans agreed; `None` once confirmed.
    unconfirmed: Option<(Lane, Pose2, usize)>,
    /// True from construction or [`Lanes::reset`] until a searched lane is confirmed: only such a start
    /// is confirmed (a lane searched again while driving, after the rows were lost, is not held back:
    /// the lane switcher's blind distance already bounds it).
    fresh: bool,
    /// The slide test's comparisons over the last `shear_window_m`: odometer reading (m), the shear
    /// they measured (m/m), its weight (inverse variance) and the robot's heading in `odom` (rad).
    slide: VecDeque<[f64; 4]>,
    /// The shear the slide test agreed on at the last correction, m/m.
    slide_found: Option<f64>,
    /// Odometer reading where the declared slide began, m: where it was declared, less the window
    /// that showed it. Centroids stored before it have moved by the shear times the distance since
    /// it, not times their age (see [`Lanes::correct`]).
    slide_onset_m: Option<f64>,
    /// Odometer reading when the lane was found, m.
    lane_since_m: f64,
    /// Where this lane's scans usually start to see the rows, m along `base_link` x: a running level
    /// of the nearest fresh centroid that follows slow changes (a canopy growing or thinning) and
    /// ignores a near view left empty (`DetectorConfig::shear_near_gap_m`); `None` until the lane's
    /// first comparison.
    near_view_m: Option<f64>,
    /// Odometer reading where the near view was last seen empty, m, while it stays so.
    near_gap_since_m: Option<f64>,
    /// Scans in a row whose near view was empty.
    near_gap_scans: u32,
}

/// A correction's result.
#[derive(Debug, Clone, Copy)]
struct Fit {
    lane: Lane,
    /// Centroid weight supporting the first row left and right (full-weight centroids).
    support: [f64; 2],
    /// Farthest supporting centroid of the first row left and right, m along x.
    far_x_m: [f64; 2],
    /// Lateral motion of the map per metre driven, m/m, `base_link` y.
    shear_per_m: f64,
}

impl Lanes {
    pub(crate) fn new(config: &DetectorConfig) -> Self {
        // x bins cover the sensor's reach from any valid mount (|x| <= 10 m) plus its range.
        let x_bins =
            (((config.range_m + 11.0 - X_LO_M) / config.map_bin_m).ceil() as usize).clamp(1, 100_000);
        Self {
            model: None,
            last_update_s: f64::NEG_INFINITY,
            bins: vec![Bin::default(); ROWS * x_bins],
            cells: vec![Cell::default(); ROWS * x_bins * CELLS],
            visible: vec![0; x_bins],
            in_hole: vec![false; ROWS * x_bins],
            any_in_hole: false,
            own_rows_fresh: 0,
            x_bins,
            hist: vec![0.0; HIST_BINS],
            ground: vec![0.0; HIST_BINS],
            returns: vec![0.0; HIST_BINS],
            envelope: vec![0.0; HIST_BINS],
            filled: vec![false; HIST_BINS],
            slices: vec![0.0; ENVELOPE_SLICES * HIST_BINS],
            occupancy: vec![0.0; HIST_BINS],
            local: Vec::with_capacity(config.map_capacity + ROWS * x_bins),
            current: Vec::with_capacity(ROWS * x_bins),
            last_key: None,
            odometer_m: 0.0,
            generation: 0,
            last_pose: None,
            end: None,
            shear_per_m: 0.0,
            unconfirmed: None,
            fresh: true,
            slide: VecDeque::with_capacity(SLIDE_CAPACITY),
            slide_found: None,
            slide_onset_m: None,
            lane_since_m: 0.0,
            near_view_m: None,
            near_gap_since_m: None,
            near_gap_scans: 0,
        }
    }

    pub(crate) fn reset(&mut self) {
        self.model = None;
        self.last_key = None;
        self.last_pose = None;
        self.end = None;
        self.last_update_s = f64::NEG_INFINITY;
        self.shear_per_m = 0.0;
        self.unconfirmed = None;
        self.fresh = true;
        self.slide.clear();
        self.slide_found = None;
        self.slide_onset_m = None;
    }

    /// One scan: `canopy` and `cropped` points in `base_link`, the scan's `holes`, `odom` its pose at
    /// `t_s`.
    pub(crate) fn step(
        &mut self,
        canopy: &[[f32; 3]],
        cropped: &[[f32; 3]],
        holes: &Holes,
        odom: &Pose2,
        t_s: f64,
        config: &DetectorConfig,
        map: &mut CentroidMap,
        centroids: &mut Vec<[f64; 2]>,
    ) -> LaneOutput {
        centroids.clear();
        if let Some(p) = self.last_pose {
            self.odometer_m += (odom.x - p.x).hypot(odom.y - p.y);
        }
        self.last_pose = Some(*odom);
        if self.model.is_some() && t_s - self.last_update_s > config.lost_after_s {
            self.model = None;
            self.last_key = None;
            self.shear_per_m = 0.0;
            self.slide.clear();
            self.slide_found = None;
            self.slide_onset_m = None;
            map.clear();
        }
        let predicted = match self.model {
            Some((lane, pose)) => lane.transport(&pose, odom).filter(|l| l.is_sane(config)),
            None => self.search(canopy, cropped, config),
        };
        let Some(predicted) = predicted else {
            self.model = None;
            return LaneOutput { row_end_ahead_m: self.end_ahead(odom), ..LaneOutput::default() };
        };
        if self.model.is_none() {
            // A new lane hypothesis: evidence stored against an older one would only confuse it.
            map.clear();
            self.last_key = None;
            self.shear_per_m = 0.0;
            self.unconfirmed =
                (self.fresh && config.start_confirmations > 0).then_some((predicted, *odom, 0));
            self.slide.clear();
            self.slide_found = None;
            self.slide_onset_m = None;
            self.lane_since_m = self.odometer_m;
            self.generation = self.generation.wrapping_add(1);
            self.near_view_m = None;
            self.near_gap_since_m = None;
            self.near_gap_scans = 0;
        }
        self.measure(canopy, cropped, &predicted, config);
        self.mark_holes(&predicted, holes, config);
        let fresh = self.store_centroids(&predicted, odom, config, map);
        let fitted = self.correct(&predicted, odom, config, map, centroids);
        // Only this scan's own centroids count as seeing the rows: the map alone would keep a lane alive
        // for as long as its centroids stay ahead of the robot.
        // A hole that hides the lane's own rows leaves the lane to the map alone, which runs out
        // ahead: such a scan does not see the rows (soak seed 1454: a 51° sector straight ahead over
        // 5 m; the map's rows shortened to 1 m ahead and the fit swung onto a row).
        let own_rows_hidden = self.any_in_hole
            && self.own_rows_fresh == 0
            && fitted.is_none_or(|f| f.far_x_m.iter().any(|&x| x < HOLE_MAP_REACH_M));
        let updated = fitted.is_some() && fresh >= MIN_FRESH_CENTROIDS && !own_rows_hidden;
        let (lane, support, far_x_m) = match fitted {
            Some(fit) => {
                self.shear_per_m = fit.shear_per_m;
                (fit.lane, fit.support, fit.far_x_m)
            }
            None => (predicted, [0.0; 2], [0.0; 2]),
        };
        if updated {
            self.last_update_s = t_s;
        } else if self.model.is_none() {
            // A search hit that the map cannot confirm is not a lane yet.
            return LaneOutput { row_end_ahead_m: self.end_ahead(odom), ..LaneOutput::default() };
        }
        self.model = Some((lane, *odom));
        self.update_end(&lane, odom, config);
        let believed =
            if updated { self.confirm(&lane, far_x_m, odom, config) } else { self.unconfirmed.is_none() };
        if !believed {
            // Tracked but not yet believed: no rows to report.
            return LaneOutput { row_end_ahead_m: self.end_ahead(odom), ..LaneOutput::default() };
        }
        LaneOutput { lane: Some(lane), updated, support, far_x_m, row_end_ahead_m: self.end_ahead(odom) }
    }

    /// Start-up confirmation: true once the lane found by a search has held still, seen from `odom`, for
    /// `start_confirmations` consecutive updated scans (heading within `start_heading_tolerance_deg` and
    /// offset within `start_offset_tolerance_m` of where the run of scans started, the spacing within
    /// the same offset tolerance); a scan that moved it further starts the run again from it. A search
    /// can lock onto a lattice that is not the crop's (tall weeds in every inter-row, a closed canopy, a
    /// short view over relief), and the fit then wanders from scan to scan even while the robot stands
    /// still (soak seeds 31, 337, 451: 11-26° first headings that drifted by degrees per scan); the
    /// crop's own lattice holds still. Reporting nothing until then keeps a robot that is unsure from
    /// moving (the lane switcher waits in `acquiring`).
    fn confirm(&mut self, lane: &Lane, far_x_m: [f64; 2], odom: &Pose2, config: &DetectorConfig) -> bool {
        let Some((anchor, pose, count)) = self.unconfirmed else { return true };
        let reach = far_x_m[0].min(far_x_m[1]) >= config.start_min_reach_m;
        let held = reach
            && anchor.transport(&pose, odom).is_some_and(|then| {
                (lane.a.atan() - then.a.atan()).abs() <= config.start_heading_tolerance_deg.to_radians()
                    && (lane.o - then.o).abs() <= config.start_offset_tolerance_m
                    && (lane.spacing_m() - then.spacing_m()).abs() <= config.start_offset_tolerance_m
            });
        let count = if held { count + 1 } else { 1 };
        if count >= config.start_confirmations {
            self.unconfirmed = None;
            self.fresh = false;
            return true;
        }
        self.unconfirmed = if held { Some((anchor, pose, count)) } else { Some((*lane, *odom, count)) };
        false
    }

    /// The measure stage alone (predict, bin, store), for the per-stage benchmark; returns the number of
    /// centroids stored. Needs a tracked lane.
    pub(crate) fn measure_stage(
        &mut self,
        canopy: &[[f32; 3]],
        cropped: &[[f32; 3]],
        odom: &Pose2,
        config: &DetectorConfig,
        map: &mut CentroidMap,
    ) -> usize {
        let Some(predicted) = self.model.and_then(|(lane, pose)| lane.transport(&pose, odom)) else {
            return 0;
        };
        self.measure(canopy, cropped, &predicted, config);
        self.clear_holes();
        self.store_centroids(&predicted, odom, config, map)
    }

    /// Direction of the tracked rows in the frame of the poses given to [`Lanes::step`], rad, when a lane
    /// is tracked.
    pub(crate) fn row_direction(&self) -> Option<f64> {
        self.model.map(|(lane, pose)| pose.yaw + lane.a.atan())
    }

    /// Where the tracked lane's canopy ends, `(x, y)` in the frame of the poses given to
    /// [`Lanes::step`], when the last scan saw the end.
    pub(crate) fn row_end(&self) -> Option<[f64; 2]> {
        self.end.filter(|_| self.model.is_some()).map(|[x, y, _]| [x, y])
    }

    /// Which lane hypothesis is tracked: a number that changes whenever a new one is started (a search
    /// after a reset or after the rows were lost).
    pub(crate) fn generation(&self) -> u32 {
        self.generation
    }

    /// Distance driven since the tracked lane was found, m (0 without a lane).
    pub(crate) fn tracked_for_m(&self) -> f64 {
        if self.model.is_some() { self.odometer_m - self.lane_since_m } else { 0.0 }
    }

    /// The slide the slide test found at the last correction, m per metre driven, `base_link` y
    /// (positive: the robot slides left, so its map moves left too); see [`Lanes::observe_slide`].
    pub(crate) fn slide_per_m(&self) -> Option<f64> {
        self.slide_found
    }

    /// The correct stage alone (least squares on the map), for the per-stage benchmark; returns the
    /// number of centroids used.
    pub(crate) fn correct_stage(
        &mut self,
        odom: &Pose2,
        config: &DetectorConfig,
        map: &CentroidMap,
        centroids: &mut Vec<[f64; 2]>,
    ) -> usize {
        let Some(predicted) = self.model.and_then(|(lane, pose)| lane.transport(&pose, odom)) else {
            return 0;
        };
        self.correct(&predicted, odom, config, map, centroids).map_or(0, |_| centroids.len())
    }

    /// Bins the canopy points gated to the predicted rows (with each bin's lateral profile across the
    /// gate), and the visible (any) points near the lane.
    fn measure(&mut self, canopy: &[[f32; 3]], cropped: &[[f32; 3]], lane: &Lane, config: &DetectorConfig) {
        self.bins.iter_mut().for_each(|b| *b = Bin::default());
        // The lateral profiles serve only the opt-in bin test (a core fraction > 0): skip them otherwise.
        let profiles = config.core_fraction > 0.0 || config.outer_core_fraction > 0.0;
        if profiles {
            self.cells.iter_mut().for_each(|c| *c = Cell::default());
        }
        self.visible.iter_mut().for_each(|v| *v = 0);
        let gate = config.gate_fraction * lane.s;
        let inv_cell = CELLS as f64 / (2.0 * gate);
        let inv_bin = 1.0 / config.map_bin_m;
        for p in canopy {
            let (x, y) = (p[0] as f64, p[1] as f64);
            let (j, d) = lane.assign(x, y);
            if d.abs() > gate {
                continue;
            }
            // Weighting by height squared favours the crest: a row seen from one side shows more of its
            // near flank, and the flank would pull a plain mean towards the sensor.
            let w = (p[2] as f64).powi(2) + HEIGHT_WEIGHT_FLOOR_M2;
            let Some(i) = self.bin_index(j, x, inv_bin) else { continue };
            if let Some(b) = self.bins.get_mut(i) {
                b.n += 1;
                b.w += w;
                b.sx += w * x;
                b.sy += w * y;
            }
            if !profiles {
                continue;
            }
            // |d| <= gate, so the cell is in 0..=CELLS; the last edge joins the last cell.
            let k = (((d + gate) * inv_cell) as usize).min(CELLS - 1);
            if let Some(c) = self.cells.get_mut(i * CELLS + k) {
                c.w += w;
                c.wd += w * d;
            }
        }
        let reach = 2.0 * lane.s;
        let visible = &mut self.visible;
        for_each_interleaved(cropped, |p| {
            let (x, y) = (p[0] as f64, p[1] as f64);
            let xi = (x - X_LO_M) * inv_bin;
            // Counted by adding 0 or 1 rather than behind a branch on the reach: returns near its edge
            // go in and out, and the branch mispredicted there.
            if xi >= 0.0
                && let Some(v) = visible.get_mut(bin_of(xi))
            {
                *v += u32::from((y - lane.centre(x)).abs() < reach);
            }
        });
    }

    /// Marks the bins of `lane` that a hole of the scan reaches into: the canopy of such a bin is
    /// seen in part, and its centroid leans away from the hole (see [`super::holes`]).
    fn mark_holes(&mut self, lane: &Lane, holes: &Holes, config: &DetectorConfig) {
        self.clear_holes();
        if !holes.any() {
            return;
        }
        self.any_in_hole = true;
        let gate = config.gate_fraction * lane.s;
        for (row, j) in (J_MIN..J_MIN + ROWS as i32).enumerate() {
            for xi in 0..self.x_bins {
                let x0 = X_LO_M + xi as f64 * config.map_bin_m;
                let x1 = x0 + config.map_bin_m;
                let (y0, y1) = (lane.crest_y(j, x0), lane.crest_y(j, x1));
                let y = [y0.min(y1) - gate, y0.max(y1) + gate];
                if let Some(h) = self.in_hole.get_mut(row * self.x_bins + xi) {
                    *h = holes.touches([x0, x1], y);
                }
            }
        }
    }

    /// Marks no bin as reached by a hole.
    fn clear_holes(&mut self) {
        if self.any_in_hole {
            self.in_hole.iter_mut().for_each(|h| *h = false);
            self.any_in_hole = false;
        }
    }

    /// True when the point (`base_link`) falls in a bin of `lane` that a hole of the scan reaches into.
    fn in_hole_at(&self, lane: &Lane, x: f64, y: f64, inv_bin: f64) -> bool {
        if !self.any_in_hole {
            return false;
        }
        let (j, _) = lane.assign(x, y);
        self.bin_index(j, x, inv_bin).and_then(|i| self.in_hole.get(i).copied()).unwrap_or(false)
    }

    /// Whether the canopy of bin `i` peaks inside its gate (half-width `gate`, m). A window `core` m either
    /// side, started at the mean residual of the whole gate, moves to the mean of the cells it covers
    /// until it settles (a flat-kernel mean shift on the bin's lateral profile): on a row it settles on
    /// the row; where the mass of the gate lies at one edge it walks there. Settled so far out that it
    /// reaches past the gate, the canopy's peak lies outside the gate: the points belong to something
    /// else, seen through the edge of the gate. Two such things pulled the row fit: a tall weed clump
    /// between the rows that reaches into a row's gate (`fault-weed-patch`, soak seed 50: weeds as tall
    /// as young corn, 0.3 m wide, coming within 0.12 m of the rows), and, at a field's edge, the outer
    /// leaves of the last row in the gate of a row beyond it that the lattice predicts but that does not
    /// exist (seed 119, grown soybean: the fit took their centroids for that row and shrank the spacing
    /// by a fifth on re-entering the field). `core` = 0 keeps every bin.
    fn peaks_inside(&self, i: usize, gate: f64, core: f64) -> bool {
        let Some(cells) = self.cells.get(i * CELLS..(i + 1) * CELLS) else { return false };
        if core <= 0.0 {
            return true;
        }
        let cell_m = 2.0 * gate / CELLS as f64;
        let (w, wd) = cells.iter().fold((0.0, 0.0), |(w, wd), c| (w + c.w, wd + c.wd));
        if w <= 0.0 {
            return false;
        }
        let mut centre = wd / w;
        for _ in 0..PEAK_STEPS {
            let (w, wd) = cells
                .iter()
                .enumerate()
                .filter(|(k, _)| (-gate + (*k as f64 + 0.5) * cell_m - centre).abs() <= core)
                .fold((0.0, 0.0), |(w, wd), (_, c)| (w + c.w, wd + c.wd));
            if w <= 0.0 {
                // Nothing within the window around the mean: two clumps at the gate's two edges.
                return false;
            }
            let next = wd / w;
            let settled = (next - centre).abs() < 0.5 * cell_m;
            centre = next;
            if settled {
                break;
            }
        }
        centre.abs() <= gate - core
    }

    fn bin_index(&self, j: i32, x: f64, inv_bin: f64) -> Option<usize> {
        let row = usize::try_from(j - J_MIN).ok().filter(|&r| r < ROWS)?;
        let xi = (x - X_LO_M) * inv_bin;
        (xi >= 0.0 && bin_of(xi) < self.x_bins).then(|| row * self.x_bins + bin_of(xi))
    }

    /// Collects this scan's bin centroids with enough points whose canopy peaks inside the gate of
    /// `lane` (the predicted lane) into `current` (`base_link`), and stores
    /// them in the map when the robot has moved a keyframe distance since the last stored set. Returns
    /// how many there are.
    fn store_centroids(
        &mut self,
        lane: &Lane,
        odom: &Pose2,
        config: &DetectorConfig,
        map: &mut CentroidMap,
    ) -> usize {
        self.current.clear();
        self.own_rows_fresh = 0;
        let gate = config.gate_fraction * lane.s;
        let own_core = config.core_fraction * lane.s;
        let outer_core = config.core_fraction.max(config.outer_core_fraction) * lane.s;
        let crests = lane.crests as i32;
        for (i, b) in self.bins.iter().enumerate() {
            let in_hole = self.in_hole.get(i).copied().unwrap_or(false);
            let j = (i / self.x_bins) as i32 + J_MIN;
            let own = (-crests..crests).contains(&j);
            let core = if own { own_core } else { outer_core };
            if b.n as usize >= config.map_min_points && !in_hole && self.peaks_inside(i, gate, core) {
                let n = b.n as f64;
                self.current.push([b.sx / b.w, b.sy / b.w, n.min(FULL_WEIGHT_POINTS) / FULL_WEIGHT_POINTS]);
                self.own_rows_fresh += usize::from(own);
            }
        }
        let keyframe = self.last_key.is_none_or(|k| {
            (odom.x - k.x).hypot(odom.y - k.y) >= KEYFRAME_M
                || wrap_angle(odom.yaw - k.yaw).abs() >= KEYFRAME_RAD
        });
        if keyframe {
            for c in &self.current {
                map.push(odom, c[0], c[1], c[2], self.odometer_m);
            }
            self.last_key = Some(*odom);
        }
        self.current.len()
    }

    /// Two-pass weighted least squares of `(o, s, a, b, k)` on the map, regularised towards `predicted`
    /// (and `k` towards 0). Returns the lane, the support and the farthest centroid of the first left
    /// and right rows, and the shear `k`.
    ///
    /// The shear `k` (m per metre driven, `base_link` y) models motion the odometry did not sense: a
    /// sideways slide moves the robot but not the centroids it stored in `odom`, so a centroid stored
    /// `d` metres of driving ago sits `k·d` off the row it was measured on. The same stretch of row is
    /// stored once per keyframe while it crosses the view, at ages spread over the view's length, so
    /// `k` separates from the heading `a`. The lane the fit returns describes the rows at age 0: where
    /// they are now.
    fn correct(
        &mut self,
        predicted: &Lane,
        odom: &Pose2,
        config: &DetectorConfig,
        map: &CentroidMap,
        centroids: &mut Vec<[f64; 2]>,
    ) -> Option<Fit> {
        let x_max = config.range_m + 11.0;
        let gate = config.gate_fraction * predicted.s;
        // This scan's centroids, plus the map where this scan does not reach (near and behind the robot,
        // which the tilted sensor no longer sees), in base_link, gathered once for both passes.
        let view_start = self.current.iter().map(|c| c[0]).fold(x_max, f64::min);
        let slide = self.observe_slide(predicted, odom, config, map, view_start);
        self.slide_found = slide;
        self.slide_onset_m = match (slide, self.slide_onset_m) {
            (None, _) => None,
            (Some(_), Some(onset)) => Some(onset),
            (Some(_), None) => Some(self.odometer_m - config.shear_window_m),
        };
        // A declared slide moves a centroid by its shear times the distance driven since the slide
        // began or since the centroid was stored, whichever is shorter; the joint fit's own shear
        // (no slide declared) moves every centroid by its age.
        let slid_m = self.slid_m();
        let (sin, cos) = odom.yaw.sin_cos();
        self.local.clear();
        self.local.extend(self.current.iter().map(|&[x, y, w]| [x, y, w, 0.0]));
        let inv_bin = 1.0 / config.map_bin_m;
        for p in map.points() {
            let (dx, dy) = (p[0] - odom.x, p[1] - odom.y);
            let (x, y) = (cos * dx + sin * dy, cos * dy - sin * dx);
            // The map also holds the bins a hole of this scan reaches into, whose fresh centroids
            // were left out.
            if x >= -config.behind_m && (x < view_start || self.in_hole_at(predicted, x, y, inv_bin)) {
                // Odometry drift grows with the distance driven since the centroid was stored.
                let age_m = (self.odometer_m - p[3]).max(0.0);
                let age = age_m / AGE_SCALE_M;
                self.local.push([x, y, p[2] / (1.0 + age * age), age_m]);
            }
        }
        // The shear is an unknown only when enabled; otherwise it is fixed at 0.
        let shear_max = if config.shear_enabled { config.shear_max_per_m } else { 0.0 };
        let curvature_weight = if config.fit_curvature { PRIOR_CURVATURE } else { PINNED };
        let b_prior = if config.fit_curvature { predicted.b } else { 0.0 };
        let mut lane = *predicted;
        let mut shear = slide.unwrap_or(self.shear_per_m).clamp(-shear_max, shear_max);
        let mut support = [0.0; 2];
        let mut far = [0.0f64; 2];
        let crests = predicted.crests as i32;
        let spacing_prior = spacing_prior(predicted, config);
        for pass in 0..2 {
            // Sums of the symmetric normal matrix of φ = [1, q, x, x², d] (q = j + ½, d the age) and
            // of φ·y.
            let [mut sw, mut sq, mut sx, mut sxx, mut sqq, mut sqx, mut sqxx, mut sxxx, mut sx4] = [0.0; 9];
            let [mut sy, mut sqy, mut sxy, mut sxxy] = [0.0; 4];
            let [mut sd, mut sqd, mut sxd, mut sxxd, mut sdd, mut syd] = [0.0; 6];
            support = [0.0; 2];
            far = [0.0; 2];
            let last = pass == 1;
            if last {
                centroids.clear();
            }
            for &[x, y, weight, age_m] in &self.local {
                let age_m = age_m.min(slid_m);
                let (j, d) = lane.assign(x, y - shear * age_m);
                if d.abs() > gate || !(J_MIN..J_MIN + ROWS as i32).contains(&j) {
                    continue;
                }
                let robust = if pass == 0 { 1.0 } else { 1.0 / (1.0 + (d / CAUCHY_M).powi(2)) };
                let w = weight * robust;
                let (q, xx) = (j as f64 + 0.5, x * x);
                sw += w;
                sq += w * q;
                sx += w * x;
                sxx += w * xx;
                sqq += w * q * q;
                sqx += w * q * x;
                sqxx += w * q * xx;
                sxxx += w * xx * x;
                sx4 += w * xx * xx;
                sy += w * y;
                sqy += w * q * y;
                sxy += w * x * y;
                sxxy += w * xx * y;
                let wd = w * age_m;
                sd += wd;
                sqd += wd * q;
                sxd += wd * x;
                sxxd += wd * xx;
                sdd += wd * age_m;
                syd += wd * y;
                // The first row left is crests 0..c of the canopy lattice, the first right -c..0.
                if (-crests..crests).contains(&j) {
                    let k = usize::from(j < 0);
                    support[k] += w;
                    far[k] = far[k].max(x);
                }
                if last {
                    centroids.push([x, y]);
                }
            }
            if sw < MIN_FIT_WEIGHT {
                return None;
            }
            let mut n = Matrix5::new(
                sw, sq, sx, sxx, sd, //
                sq, sqq, sqx, sqxx, sqd, //
                sx, sqx, sxx, sxxx, sxd, //
                sxx, sqxx, sxxx, sx4, sxxd, //
                sd, sqd, sxd, sxxd, sdd,
            );
            let mut r = Vector5::new(sy, sqy, sxy, sxxy, syd);
            // Priors (information form): a lone row cannot tell the spacing, a short stretch cannot tell
            // the curvature; both then stay at their prediction. The shear is drawn towards none.
            let priors = [
                (PRIOR_FREE, predicted.o),
                (PRIOR_SPACING, predicted.s),
                (PRIOR_FREE.max(config.heading_prior_m2), predicted.a),
                (curvature_weight, b_prior),
            ];
            for (i, (w, v)) in priors.into_iter().enumerate() {
                n[(i, i)] += w;
                r[i] += w * v;
            }
            if let Some((w, known)) = spacing_prior {
                n[(1, 1)] += w;
                r[1] += w * known / predicted.crests;
            }
            let p = if let Some(k) = slide {
                // The slide test has found a slide: its shear is measured on the newest scan directly,
                // not drawn from the map's ages through the heading, and is neither shrunk nor delayed.
                with_shear(&n, &r, k.clamp(-shear_max, shear_max))?
            } else if config.shear_enabled {
                let mut with_prior = n;
                with_prior[(4, 4)] += config.shear_prior_m2;
                let free = with_prior.cholesky()?.solve(&r);
                // A small shear is the fit's own noise and bias and is held at none; a large one is held
                // at its bound; the rest is refitted with the shear fixed.
                let held = shrink(free[4], config.shear_deadband_per_m).clamp(-shear_max, shear_max);
                if held == free[4] { free } else { with_shear(&n, &r, held)? }
            } else {
                with_shear(&n, &r, 0.0)?
            };
            lane = Lane { o: p[0], s: p[1], a: p[2], b: p[3], crests: predicted.crests };
            shear = p[4];
            if !lane.is_sane(config) || !shear.is_finite() {
                return None;
            }
        }
        Some(Fit { lane: lane.normalised(), support, far_x_m: far, shear_per_m: shear })
    }

    /// Locates where the canopy of the lane ends, from this scan's bins.
    fn update_end(&mut self, lane: &Lane, odom: &Pose2, config: &DetectorConfig) {
        let min = config.map_min_points as u32;
        let mut last_canopy = None;
        let mut last_seen = None;
        for xi in 0..self.x_bins {
            let canopy: u32 = NEAR_ROWS
                .iter()
                .filter_map(|&j| usize::try_from(j - J_MIN).ok())
                .filter_map(|row| self.bins.get(row * self.x_bins + xi))
                .map(|b| b.n)
                .sum();
            if canopy >= min {
                last_canopy = Some(xi);
            }
            // Where a hole hides the lane's rows the ground was not seen empty: a canopy cut off by
            // a hole is no row end (soak seed 605: a 70° sector ahead read as the end 2 m on, and the
            // robot drove on blind towards it, 4 m before the true end).
            if self.visible.get(xi).is_some_and(|&v| v >= min) && !self.near_rows_in_hole(xi) {
                last_seen = Some(xi);
            }
        }
        let upper = |xi: usize| X_LO_M + (xi + 1) as f64 * config.map_bin_m;
        let (Some(c), Some(s)) = (last_canopy, last_seen) else { return };
        if upper(s) - upper(c) >= config.end_empty_m {
            let x = upper(c);
            let (ex, ey) = odom.transform_point(x, lane.centre(x));
            let dir = odom.yaw + (lane.a + 2.0 * lane.b * x).atan();
            self.end = Some([ex, ey, dir]);
        } else {
            self.end = None;
        }
    }

    /// True when a hole of the scan reaches into a bin of the rows that decide the row end at
    /// along-x bin `xi`.
    fn near_rows_in_hole(&self, xi: usize) -> bool {
        self.any_in_hole
            && NEAR_ROWS
                .iter()
                .filter_map(|&j| usize::try_from(j - J_MIN).ok())
                .any(|row| self.in_hole.get(row * self.x_bins + xi).copied().unwrap_or(false))
    }

    fn end_ahead(&self, odom: &Pose2) -> Option<f64> {
        self.end.map(|[ex, ey, dir]| (ex - odom.x) * dir.cos() + (ey - odom.y) * dir.sin())
    }
}

/// Solves the normal equations `n·p = r` of `(o, s, a, b, k)` with the shear `k` fixed: its column
/// moves to the right-hand side and the lane's four unknowns are solved alone.
fn with_shear(n: &Matrix5<f64>, r: &Vector5<f64>, k: f64) -> Option<Vector5<f64>> {
    let n4: Matrix4<f64> = n.fixed_view::<4, 4>(0, 0).into();
    let r4: Vector4<f64> = r.fixed_rows::<4>(0) - n.fixed_view::<4, 1>(0, 4) * k;
    let p = n4.cholesky()?.solve(&r4);
    Some(Vector5::new(p[0], p[1], p[2], p[3], k))
}

/// Shrinks a fitted shear `k` towards 0 by the non-negative garrote `k − d²/k` (0 within `±d`): continuous,
/// so the lane does not jump as the shear crosses the deadband, and nearly `k` for a shear well beyond it.
fn shrink(k: f64, deadband: f64) -> f64 {
    if k.abs() <= deadband { 0.0 } else { k - deadband * deadband / k }
}

/// The bin `xi` (≥ 0) falls in, as `xi as usize` gives it up to 2⁶³, beyond every bin: `as i64` is one
/// instruction where `as usize` is a dozen (x86 has no unsigned 64-bit conversion), and this runs for
/// every cropped return.
fn bin_of(xi: f64) -> usize {
    xi as i64 as usize
}

/// Histogram bin of lateral coordinate `u`, m, if inside.
fn hist_index(u: f64) -> Option<usize> {
    let i = ((u + HIST_HALF_M) / HIST_BIN_M).floor();
    (i >= 0.0 && i < HIST_BINS as f64).then_some(i as usize)
}

fn hist_centre(i: usize) -> f64 {
    -HIST_HALF_M + (i as f64 + 0.5) * HIST_BIN_M
}

/// The prior on the lane's row spacing, `(weight, known spacing in m)`, or none.
///
/// The planted spacing, known, holds a closed canopy's lattice from shrinking onto its crests (soak
/// seed 1972: 0.62 m read for 0.71 m rows, the lane 15 cm off). A lattice further than
/// `planted_spacing_tolerance` off is not at the planted spacing, and the prior would only drag it
/// across the rows: without this gate soak seeds 577 and 1901 ran over plants at the start.
fn spacing_prior(predicted: &Lane, config: &DetectorConfig) -> Option<(f64, f64)> {
    let known = if config.spacing_prior_m > 0.0 { config.spacing_prior_m } else { config.planted_spacing_m };
    let near_known = (predicted.spacing_m() - known).abs() <= config.planted_spacing_tolerance * known;
    (known > 0.0 && config.spacing_prior_weight > 0.0 && near_known)
        .then_some((config.spacing_prior_weight, known))
}

#[cfg(test)]
mod tests {
    use super::search::*;
    use super::slide::*;
    use super::*;

    /// One step of `lanes` on a whole scan (no hole).
    #[allow(clippy::too_many_arguments)]
    fn step_whole(
        lanes: &mut Lanes,
        canopy: &[[f32; 3]],
        cropped: &[[f32; 3]],
        odom: &Pose2,
        t: f64,
        config: &DetectorConfig,
        map: &mut CentroidMap,
        centroids: &mut Vec<[f64; 2]>,
    ) -> LaneOutput {
        lanes.step(canopy, cropped, &Holes::default(), odom, t, config, map, centroids)
    }

    fn rows_of_points(offsets: &[f64], heading: f64) -> Vec<[f32; 3]> {
        let mut pts = Vec::new();
        for i in 0..250 {
            let x = 1.5 + 0.012 * i as f64;
            for &o in offsets {
                for dy in [-0.06, -0.02, 0.02, 0.06] {
                    pts.push([x as f32, (o + dy + heading.tan() * x) as f32, 0.1]);
                }
            }
        }
        pts
    }

    #[test]
    fn search_finds_spacing_heading_and_phase() {
        // Rows 0.75 m apart, lane centre at +0.1 m, heading 5°: spacing within 2 cm, heading within 1°,
        // centre within 3 cm (one scan, no map yet).
        let cfg = DetectorConfig::default();
        let pts = rows_of_points(&[-1.025, -0.275, 0.475, 1.225], 5f64.to_radians());
        let lane = Lanes::new(&cfg).search(&pts, &pts, &cfg).unwrap();
        assert!((lane.s - 0.75).abs() < 0.02, "{lane:?}");
        assert!((lane.a.atan() - 5f64.to_radians()).abs() < 1f64.to_radians(), "{lane:?}");
        assert!((lane.o - 0.1).abs() < 0.03, "{lane:?}");
    }

    /// One scan of a young crop over bare ground seen from where the robot was set down: rows 0.76 m
    /// apart (a whole number of histogram bins) with the lane centre at `centre_m` (`base_link`),
    /// canopy 0.1 m high along the whole view (x = 1.5-4.5 m), ground returns every 2 cm across it,
    /// and `weeds` clumps 0.3 m wide and 0.3 m high (taller than the crop) scattered over the
    /// inter-rows by a generator seeded with `seed`, as the soak's tall weed patch lays them (up to 30
    /// returns each). Returns (canopy, cropped ⊇ canopy).
    fn young_scan(centre_m: f64, weeds: usize, seed: u64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let (mut canopy, mut cropped) = (Vec::new(), Vec::new());
        let rows: Vec<f64> = (-3..3).map(|k| centre_m + (k as f64 + 0.5) * 0.76).collect();
        for i in 0..150 {
            let x = 1.5 + 0.02 * i as f64;
            for r in &rows {
                for dy in [-0.06, -0.02, 0.02, 0.06] {
                    canopy.push([x as f32, (r + dy) as f32, 0.1]);
                }
            }
            for j in 0..200 {
                cropped.push([x as f32, (-2.0 + 0.02 * j as f64) as f32, -0.3]);
            }
        }
        let mut rng = crate::perception::rng::Rng::new(seed);
        for _ in 0..weeds {
            // Clear of the rows by their own radius (0.15 m) and 0.05 m more, like the simulator's.
            let lane = rows[rng.below(rows.len() - 1)] + 0.38;
            let (x, y) = (1.5 + 3.0 * rng.unit(), lane + 0.18 * (2.0 * rng.unit() - 1.0));
            for _ in 0..30 {
                let (dx, dy) = (0.15 * (2.0 * rng.unit() - 1.0), 0.15 * (2.0 * rng.unit() - 1.0));
                if dx.hypot(dy) <= 0.15 {
                    canopy.push([(x + dx) as f32, (y + dy) as f32, 0.3]);
                }
            }
        }
        cropped.extend_from_slice(&canopy);
        (canopy, cropped)
    }

    #[test]
    fn a_young_crop_runs_along_its_rows_and_tall_weeds_do_not() {
        // Set down in a young crop, the search takes the rows (centre within 3 cm), their canopy held
        // along x in every slice; 0.4 spacings off the centre too (the `recovery` start). Tall weed
        // clumps over the inter-rows (3 per m², the soak's patch) outweigh the rows in the search, whose
        // lattice then has no contrast along x: the search waits. With the test off it takes a lattice
        // at half the spacing in four of ten such scans (the other six give two crests per row, crop
        // and weeds, and come out at the crop's spacing, centred on the robot).
        let cfg = DetectorConfig::default();
        for centre in [0.0, 0.3] {
            let (canopy, cropped) = young_scan(centre, 0, 1);
            let mut lanes = Lanes::new(&cfg);
            let lane = lanes.search(&canopy, &cropped, &cfg).expect("rows alone are a start");
            assert!((lane.o - centre).abs() < 0.03 && (lane.spacing_m() - 0.76).abs() < 0.03, "{lane:?}");
            let contrast = lanes.lane_contrast(&lane, 3.0);
            assert!(contrast > 1.0, "{contrast}");
        }
        let off = DetectorConfig { start_row_contrast: 0.0, ..cfg.clone() };
        let mut wrong = 0;
        for seed in 1..=10 {
            let (canopy, cropped) = young_scan(0.0, 34, seed);
            assert_eq!(Lanes::new(&cfg).search(&canopy, &cropped, &cfg), None, "weeds {seed}");
            let lane = Lanes::new(&off).search(&canopy, &cropped, &off);
            wrong += usize::from(lane.is_some_and(|l| (l.spacing_m() - 0.76).abs() > 0.1 || l.o.abs() > 0.1));
        }
        assert!(wrong >= 4, "{wrong} of 10 weed scans give the test-less search a wrong lattice");
        // A robot that has driven off where it was set down is not held back (its searches come after
        // it lost rows it followed, bounded by the blind distance): weed scan 2's lattice.
        let (canopy, cropped) = young_scan(0.0, 34, 2);
        let mut moved = Lanes::new(&cfg);
        moved.odometer_m = 1.0;
        assert!(moved.search(&canopy, &cropped, &cfg).is_some());
    }

    /// One scan of a grown canopy, `base_link` at lateral offset `y0_m` from the lane centre: rows 0.75 m
    /// apart, the canopy cresting a quarter spacing either side of each row (leaves arching into the
    /// inter-row), so the canopy alone repeats every 0.375 m; low leaf tips meet over the inter-row and
    /// the ground shows along the row lines only. Returns (canopy, cropped).
    fn two_crest_scan(y0_m: f64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        crests_scan(y0_m, |x, r, canopy, cropped| {
            canopy.push([x as f32, (r + 0.375) as f32, 0.05]);
            cropped.push([x as f32, r as f32, -0.4]);
        })
    }

    /// Scan slices 1.5-4.5 m ahead (`x`), rows 0.75 m apart at `r` (`base_link` at lateral offset
    /// `y0_m` from the lane centre), the canopy cresting a quarter spacing either side of each row
    /// (0.3 m), and what `per_row(x, r, canopy, cropped)` adds. Returns (canopy, cropped ⊇ canopy).
    fn crests_scan(
        y0_m: f64,
        mut per_row: impl FnMut(f64, f64, &mut Vec<[f32; 3]>, &mut Vec<[f32; 3]>),
    ) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let (mut canopy, mut cropped) = (Vec::new(), Vec::new());
        for i in 0..250 {
            let x = 1.5 + 0.012 * i as f64;
            for r in (-3..3).map(|k| (k as f64 + 0.5) * 0.75 - y0_m) {
                for dy in [-0.1875, 0.1875] {
                    for e in [-0.02, 0.0, 0.02] {
                        canopy.push([x as f32, (r + dy + e) as f32, 0.3]);
                    }
                }
                per_row(x, r, &mut canopy, &mut cropped);
            }
        }
        cropped.extend_from_slice(&canopy);
        (canopy, cropped)
    }

    #[test]
    fn spacing_does_not_lock_to_half_on_grown_canopy() {
        // Spacing within 3 cm of 0.75, centre within 3 cm of 0 (one scan).
        let cfg = DetectorConfig::default();
        let (canopy, cropped) = two_crest_scan(0.0);
        let lane = Lanes::new(&cfg).search(&canopy, &cropped, &cfg).unwrap();
        assert!((lane.spacing_m() - 0.75).abs() < 0.03, "{lane:?}");
        assert!(lane.o.abs() < 0.03, "{lane:?}");
    }

    /// One scan of a grown corn canopy, rows 0.73 m apart with `base_link` `y0_m` left of its lane
    /// centre: the plant tops crest over each row (0.55 m), the arching leaves of two rows meet in a
    /// lower, denser crest over the middle of each inter-row (0.5 m), and the ground shows either side
    /// of that crest, where the leaves thin out. The canopy alone repeats every 0.365 m (the soak's
    /// grown corn of seed 1390 does). Returns (canopy, cropped).
    fn grown_corn_scan(y0_m: f64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let (mut canopy, mut cropped) = (Vec::new(), Vec::new());
        for i in 0..250 {
            let x = 1.5 + 0.012 * i as f64;
            for k in -3..3 {
                let row = (k as f64 + 0.5) * 0.73 - y0_m;
                let middle = row + 0.365;
                for e in [-0.03, -0.01, 0.01, 0.03] {
                    canopy.push([x as f32, (row + e) as f32, 0.55]);
                }
                for e in [-0.05, -0.03, -0.01, 0.01, 0.03, 0.05] {
                    canopy.push([x as f32, (middle + e) as f32, 0.5]);
                }
                for side in [-0.12, 0.12] {
                    cropped.push([x as f32, (middle + side) as f32, -0.4]);
                }
            }
        }
        cropped.extend_from_slice(&canopy);
        (canopy, cropped)
    }

    #[test]
    fn a_two_crest_lane_is_centred_between_the_plant_tops() {
        // The canopy crests over the rows and over the middle of the inter-rows: the lane centre is a
        // crest, not a gap between crests (those lie a quarter spacing off, on the wheels' way to the
        // rows). Spacing within 3 cm of 0.73 with two crests per row, centre within 3 cm, from 3 cm
        // and 8 cm either side of it.
        let cfg = DetectorConfig::default();
        for y0 in [-0.08, -0.03, 0.03, 0.08] {
            let (canopy, cropped) = grown_corn_scan(y0);
            let lane = Lanes::new(&cfg).search(&canopy, &cropped, &cfg).unwrap();
            assert!(lane.crests == 2.0 && (lane.spacing_m() - 0.73).abs() < 0.03, "{y0}: {lane:?}");
            assert!((lane.o + y0).abs() < 0.03, "{y0}: {lane:?}");
        }
    }

    #[test]
    fn two_crest_lane_keeps_its_rows_while_tracking() {
        // The robot drives 4 m along the lane, 0.1 m per scan, drifting 0.15 m left: the lane keeps the
        // full spacing and its centre stays at the true one, within 3 cm.
        let cfg = DetectorConfig::default();
        let mut lanes = Lanes::new(&cfg);
        let mut map = CentroidMap::new(cfg.map_capacity);
        let mut centroids = Vec::new();
        for k in 0..40 {
            let y0 = 0.15 * k as f64 / 40.0;
            let (canopy, cropped) = two_crest_scan(y0);
            let odom = Pose2::new(0.1 * k as f64, y0, 0.0);
            let out = step_whole(
                &mut lanes,
                &canopy,
                &cropped,
                &odom,
                0.1 * k as f64,
                &cfg,
                &mut map,
                &mut centroids,
            );
            let lane = out.lane.unwrap();
            assert!((lane.spacing_m() - 0.75).abs() < 0.03, "scan {k}: {lane:?}");
            assert!((lane.o + y0).abs() < 0.03, "scan {k}: {lane:?}");
        }
    }

    /// One scan of a closed canopy seen from the lane centre: rows 0.75 m apart whose leaves crest a
    /// quarter spacing either side of the row (dense, 0.25 m above the plane), under the plant tops
    /// over the row (sparse, 0.32 m), with low leaves filling the rest (0.1 m), and no ground in view.
    fn closed_canopy_scan() -> Vec<[f32; 3]> {
        let mut canopy = Vec::new();
        for i in 0..250 {
            let x = 1.5 + 0.012 * i as f64;
            for r in (-3..3).map(|k| (k as f64 + 0.5) * 0.75) {
                for dy in [-0.1875, 0.1875] {
                    for e in [-0.03, -0.01, 0.01, 0.03] {
                        canopy.push([x as f32, (r + dy + e) as f32, 0.25]);
                    }
                }
                canopy.push([x as f32, r as f32, 0.32]);
                canopy.extend((0..38).map(|k| [x as f32, (r - 0.375 + 0.02 * k as f64) as f32, 0.1]));
            }
        }
        canopy
    }

    #[test]
    fn closed_canopy_spacing_follows_the_plant_tops() {
        // The canopy density repeats every 0.375 m (its own autocorrelation says so, within 3 cm) and
        // the ground cannot break the tie; the plant tops give the spacing within 3 cm and the lane
        // centre within 3 cm.
        let cfg = DetectorConfig::default();
        let canopy = closed_canopy_scan();
        let mut lanes = Lanes::new(&cfg);
        lanes.fill_hist(&canopy, 0.0, 1);
        let density = spacing(&mut lanes.hist, &cfg).unwrap();
        assert!((density - 0.375).abs() < 0.03, "{density}");
        let lane = lanes.search(&canopy, &canopy, &cfg).unwrap();
        assert!((lane.spacing_m() - 0.75).abs() < 0.03, "{lane:?}");
        assert!(lane.o.abs() < 0.03, "{lane:?}");
    }

    #[test]
    fn a_broad_crest_is_not_a_period() {
        // A profile that only falls off from lag 0 (one wide hump) has no local maximum in the searched
        // range: no spacing.
        let cfg = DetectorConfig::default();
        let mut hist: Vec<f64> = (0..HIST_BINS).map(|i| (-(hist_centre(i) / 2.0).powi(2)).exp()).collect();
        assert_eq!(spacing(&mut hist, &cfg), None);
    }

    #[test]
    fn narrow_rows_keep_their_spacing_when_the_ground_agrees() {
        // Rows truly 0.375 m apart with the ground showing in every inter-row: no doubling, spacing
        // within 2 cm.
        let cfg = DetectorConfig::default();
        let rows: Vec<f64> = (-6..6).map(|k| (k as f64 + 0.5) * 0.375).collect();
        let canopy = rows_of_points(&rows, 0.0);
        let mut cropped = canopy.clone();
        for i in 0..250 {
            let x = 1.5 + 0.012 * i as f64;
            cropped.extend(rows.iter().map(|r| [x as f32, (r + 0.1875) as f32, -0.4]));
        }
        let lane = Lanes::new(&cfg).search(&canopy, &cropped, &cfg).unwrap();
        assert!((lane.spacing_m() - 0.375).abs() < 0.02, "{lane:?}");
    }

    #[test]
    fn the_planted_spacing_picks_one_or_two_crests_per_row() {
        // The same canopy, crests 0.7 m apart: planted at 0.7 m it is one crest per row, planted at
        // 1.4 m two (spacing within 2 cm either way, centre within 3 cm); a two-crest canopy planted at
        // 0.75 m keeps its two crests.
        let pts = rows_of_points(&[-1.05, -0.35, 0.35, 1.05], 0.0);
        for (planted, crests) in [(0.7, 1.0), (1.4, 2.0)] {
            let cfg = DetectorConfig { planted_spacing_m: planted, ..DetectorConfig::default() };
            let lane = Lanes::new(&cfg).search(&pts, &pts, &cfg).unwrap();
            assert!((lane.spacing_m() - planted).abs() < 0.02 && lane.crests == crests, "{lane:?}");
            assert!(lane.o.abs() < 0.03, "{lane:?}");
        }
        let cfg = DetectorConfig { planted_spacing_m: 0.75, ..DetectorConfig::default() };
        let (canopy, cropped) = two_crest_scan(0.0);
        let lane = Lanes::new(&cfg).search(&canopy, &cropped, &cfg).unwrap();
        assert!((lane.spacing_m() - 0.75).abs() < 0.03 && lane.crests == 2.0, "{lane:?}");
    }

    /// One scan of a grown canopy, rows 0.75 m apart with the robot `y0_m` left of its lane centre: the
    /// leaves crest a quarter spacing either side of each row (0.3 m), over a sparse plant top on the row
    /// (0.34 m, every fourth slice), and with `ground` the ground shows through in the middle of each inter-row.
    fn grown_scan(y0_m: f64, ground: bool) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let mut slice = 0;
        crests_scan(y0_m, |x, r, canopy, cropped| {
            // Six rows per slice: a top on every row of every fourth slice.
            if slice % 24 < 6 {
                canopy.push([x as f32, r as f32, 0.34]);
            }
            slice += 1;
            if ground {
                cropped.extend([[x as f32, (r + 0.375) as f32, -0.4]; 2]);
            }
        })
    }

    /// The lane the search finds in [`grown_scan`] with the robot 0.22 m left of its lane centre,
    /// planted at 0.75 m: two crests per row (spacing within 3 cm).
    fn search_grown(ground: bool) -> Lane {
        let cfg = DetectorConfig { planted_spacing_m: 0.75, ..DetectorConfig::default() };
        let (canopy, cropped) = grown_scan(0.22, ground);
        let lane = Lanes::new(&cfg).search(&canopy, &cropped, &cfg).unwrap();
        assert!(lane.crests == 2.0 && (lane.spacing_m() - 0.75).abs() < 0.03, "{lane:?}");
        lane
    }

    #[test]
    fn a_two_crest_lane_is_centred_where_the_ground_shows() {
        // The gap between crests nearest the robot is the dip over the row at +0.155 m; the lane
        // centre is the inter-row at -0.22 m, within 3 cm.
        let lane = search_grown(true);
        assert!((lane.o + 0.22).abs() < 0.03, "{lane:?}");
    }

    #[test]
    fn a_two_crest_lane_without_ground_in_view_takes_the_nearest_gap() {
        // No ground return: nothing tells the row's dip from the inter-row, and the gap nearest the
        // robot is taken (+0.155 m, within 3 cm).
        let lane = search_grown(false);
        assert!((lane.o - 0.155).abs() < 0.03, "{lane:?}");
    }

    #[test]
    fn rows_far_from_the_planted_spacing_are_no_lane() {
        // Rows 0.75 m apart in a field planted at 0.5 m (50 % off, tolerance 12 %): no lane at all.
        let cfg = DetectorConfig { planted_spacing_m: 0.5, ..DetectorConfig::default() };
        let pts = rows_of_points(&[-1.125, -0.375, 0.375, 1.125], 0.0);
        assert_eq!(Lanes::new(&cfg).search(&pts, &pts, &cfg), None);
        let lane = Lane { o: 0.0, a: 0.0, b: 0.0, s: 0.75, crests: 1.0 };
        assert!(!lane.is_sane(&cfg));
        assert!(lane.is_sane(&DetectorConfig { planted_spacing_m: 0.7, ..cfg }));
    }

    /// Steps `scans` scans of `pts` at rest; returns whether each reported a lane.
    fn reports_at_rest(pts: &[[f32; 3]], scans: usize, cfg: &DetectorConfig) -> Vec<bool> {
        let mut lanes = Lanes::new(cfg);
        let mut map = CentroidMap::new(cfg.map_capacity);
        let mut centroids = Vec::new();
        (0..scans)
            .map(|k| {
                let t = 0.1 * k as f64;
                step_whole(&mut lanes, pts, pts, &Pose2::default(), t, cfg, &mut map, &mut centroids)
                    .lane
                    .is_some()
            })
            .collect()
    }

    #[test]
    fn a_searched_lane_is_reported_once_it_held_still_for_the_confirmations() {
        // Three confirmations: the same scan three times gives the lane on the third, not before.
        let cfg = DetectorConfig { start_confirmations: 3, ..DetectorConfig::default() };
        let pts = rows_of_points(&[-1.125, -0.375, 0.375, 1.125], 0.0);
        assert_eq!(reports_at_rest(&pts, 4, &cfg), [false, false, true, true]);
        let off = DetectorConfig { start_confirmations: 0, ..cfg };
        assert_eq!(reports_at_rest(&pts, 2, &off), [true, true]);
    }

    #[test]
    fn rows_seen_over_too_short_a_stretch_are_never_confirmed() {
        // Rows from 1.5 to 2.5 m only (a gap across every row beyond): never reported with the
        // confirmation on, however long the robot waits.
        let cfg = DetectorConfig { start_confirmations: 3, ..DetectorConfig::default() };
        let pts: Vec<[f32; 3]> =
            rows_of_points(&[-1.125, -0.375, 0.375, 1.125], 0.0).into_iter().filter(|p| p[0] < 2.5).collect();
        assert!(reports_at_rest(&pts, 10, &cfg).iter().all(|r| !r));
    }

    #[test]
    fn search_finds_nothing_when_the_sharpest_heading_is_the_edge() {
        // Rows at 25°, beyond the 20° searched: the edge scores best, and that is no peak.
        let cfg = DetectorConfig::default();
        let pts = rows_of_points(&[-1.025, -0.275, 0.475, 1.225], 25f64.to_radians());
        assert_eq!(Lanes::new(&cfg).search(&pts, &pts, &cfg), None);
    }

    /// Canopy points of one along-x bin (x in 2.0-2.25 m) around the first row left of a straight lane
    /// (o = 0, s = 0.75 m, the row at y = 0.375 m): `row` points at the row, 0.3 m high, spread ±2 cm,
    /// and `weed` points of a clump 0.15-0.2 m beside it (inside the row's ±0.225 m gate), 0.4 m high.
    fn row_and_clump(row: usize, weed: usize) -> Vec<[f32; 3]> {
        let row_pts = (0..row).map(|i| {
            let f = i as f64 / row.max(1) as f64;
            [(2.0 + 0.24 * f) as f32, (0.375 + 0.04 * (f - 0.5)) as f32, 0.3]
        });
        let weed_pts = (0..weed).map(|i| {
            let f = i as f64 / weed.max(1) as f64;
            [(2.0 + 0.24 * f) as f32, (0.375 + 0.15 + 0.05 * f) as f32, 0.4]
        });
        row_pts.chain(weed_pts).collect()
    }

    /// This scan's centroids of the first row left (y > 0) after measuring `canopy` against the lane
    /// of [`row_and_clump`].
    fn first_left_centroids(canopy: &[[f32; 3]], cfg: &DetectorConfig) -> Vec<[f64; 3]> {
        let mut lanes = Lanes::new(cfg);
        let mut map = CentroidMap::new(cfg.map_capacity);
        let lane = Lane { o: 0.0, a: 0.0, b: 0.0, s: 0.75, crests: 1.0 };
        lanes.measure(canopy, canopy, &lane, cfg);
        lanes.store_centroids(&lane, &Pose2::default(), cfg, &mut map);
        lanes.current.iter().copied().filter(|c| c[1] > 0.0).collect()
    }

    #[test]
    fn a_bin_whose_canopy_peaks_at_the_gate_edge_is_left_out() {
        // A sparse row and a heavy weed clump at the edge of its gate (soak seeds 919, 451): the
        // window walks to the clump and reaches past the gate, so the bin gives no centroid.
        let cfg = DetectorConfig { core_fraction: 0.1, ..DetectorConfig::default() };
        assert!(first_left_centroids(&row_and_clump(6, 40), &cfg).is_empty());
    }

    #[test]
    fn a_row_with_a_smaller_clump_beside_it_keeps_its_bin() {
        // The row outweighs the clump: the window settles on the row and the bin stays (its centroid is
        // the gate's plain mean, as before).
        let cfg = DetectorConfig { core_fraction: 0.1, ..DetectorConfig::default() };
        let c = first_left_centroids(&row_and_clump(40, 6), &cfg);
        assert_eq!(c.len(), 1, "{c:?}");
        assert!((c[0][1] - 0.375).abs() < 0.05, "{c:?}");
    }

    #[test]
    fn no_core_window_keeps_every_bin() {
        let cfg = DetectorConfig { core_fraction: 0.0, ..DetectorConfig::default() };
        assert_eq!(first_left_centroids(&row_and_clump(6, 40), &cfg).len(), 1);
    }

    /// Drives 6 m, 0.1 m per scan, down a field's last lane: straight rows 0.75 m apart with a broad
    /// canopy (returns up to 0.3 m either side of each row, 0.4 m high at the row and lower outwards),
    /// the lane centre at `odom` y = 0, and the field's last row on the left (y = 0.375 m), whose
    /// outer leaves spread `outer_leaves_m` from it with nothing beyond. Returns the last lane.
    fn drive_down_a_field_edge(outer_leaves_m: f64, config: &DetectorConfig) -> Lane {
        let mut canopy = Vec::new();
        for i in 0..250 {
            let x = 0.05 * i as f64;
            for row in [-1.875, -1.125, -0.375, 0.375] {
                let outer = if row > 0.0 { outer_leaves_m } else { 0.3 };
                let mut dy = -0.3;
                while dy <= outer + 1e-9 {
                    canopy.push([x, row + dy, 0.4 - 0.5 * dy.abs().min(0.6)]);
                    dy += 0.03;
                }
            }
        }
        let mut lanes = Lanes::new(config);
        let mut map = CentroidMap::new(config.map_capacity);
        let mut centroids = Vec::new();
        let mut last = None;
        for k in 0..60 {
            let x = 0.1 * k as f64;
            let pts: Vec<[f32; 3]> = canopy
                .iter()
                .filter(|p| (1.5..4.5).contains(&(p[0] - x)))
                .map(|p| [(p[0] - x) as f32, p[1] as f32, p[2] as f32])
                .collect();
            let odom = Pose2::new(x, 0.0, 0.0);
            let out =
                step_whole(&mut lanes, &pts, &pts, &odom, 0.1 * k as f64, config, &mut map, &mut centroids);
            last = out.lane.or(last);
        }
        last.expect("the lane is found")
    }

    #[test]
    fn the_outer_leaves_of_a_fields_last_row_do_not_squeeze_the_spacing() {
        // Leaves spreading 0.6 m outwards from the last row reach into the gate of the row the lattice
        // predicts beyond it (1.125 m ± 0.225 m): taken for that row, they shrink the spacing to 0.68 m
        // and pull the lane 0.13 m off centre. The bin test on the rows beyond the lane's own leaves them
        // out, and the lane reads as it does where the leaves stay within the row's gate (soak seeds 618
        // and 1972, grown soybean, the field's last lane: 0.71 m rows read 0.64 m).
        let squeezed = drive_down_a_field_edge(0.6, &DetectorConfig::default());
        assert!(squeezed.s < 0.7 && squeezed.o < -0.1, "the case no longer provokes a squeeze: {squeezed:?}");
        let within_gate = drive_down_a_field_edge(0.3, &DetectorConfig::default());
        assert!((within_gate.s - 0.75).abs() < 0.02 && within_gate.o.abs() < 0.02, "{within_gate:?}");
        let cfg = DetectorConfig { outer_core_fraction: 0.1, ..DetectorConfig::default() };
        let tested = drive_down_a_field_edge(0.6, &cfg);
        let agree = (tested.s - within_gate.s).abs() < 0.005 && (tested.o - within_gate.o).abs() < 0.005;
        assert!(agree, "{tested:?} against {within_gate:?}");
    }

    /// Drives 6 m along straight rows 0.75 m apart (lane centre at `odom` y = 0), 0.1 m per scan,
    /// while the robot slides `slide_per_m` to the left per metre unseen by the odometry (its pose
    /// stays on y = 0). Returns the last lane, the shear fitted and the robot's true lateral offset.
    fn drive_with_slide(slide_per_m: f64, config: &DetectorConfig) -> (Lane, f64, f64) {
        let (lane, shear, y_true, _) = drive_with_slide_test(slide_per_m, config);
        (lane, shear, y_true)
    }

    /// [`drive_with_slide`], also returning the slide test's verdict at each scan: `(x, found)`.
    fn drive_with_slide_test(
        slide_per_m: f64,
        config: &DetectorConfig,
    ) -> (Lane, f64, f64, Vec<(f64, Option<f64>)>) {
        drive_with_row_slides([slide_per_m; 6], config)
    }

    /// [`drive_with_slide_test`] where each of the six rows (right to left) moves by its own amount per
    /// metre driven: all alike is a slide, one row alone is a clump growing beside it.
    fn drive_with_row_slides(
        slides_per_m: [f64; 6],
        config: &DetectorConfig,
    ) -> (Lane, f64, f64, Vec<(f64, Option<f64>)>) {
        let mut verdicts = Vec::new();
        let mut lanes = Lanes::new(config);
        let mut map = CentroidMap::new(config.map_capacity);
        let mut centroids = Vec::new();
        let mut last = None;
        let mut y_true = 0.0;
        for k in 0..60 {
            let x = 0.1 * k as f64;
            y_true = slides_per_m[3] * x;
            let rows: Vec<f64> =
                (-3..3).zip(slides_per_m).map(|(j, k)| (j as f64 + 0.5) * 0.75 - k * x).collect();
            let pts = rows_of_points(&rows, 0.0);
            let odom = Pose2::new(x, 0.0, 0.0);
            let out =
                step_whole(&mut lanes, &pts, &pts, &odom, 0.1 * k as f64, config, &mut map, &mut centroids);
            last = out.lane.or(last);
            verdicts.push((x, lanes.slide_per_m()));
        }
        (last.unwrap(), lanes.shear_per_m, y_true, verdicts)
    }

    #[test]
    fn the_slide_test_finds_a_slide_within_its_window_and_measures_it() {
        // A slide of 0.1 m per metre from the start: the test starts 1 m into the lane and has pooled
        // half its 0.5 m window 0.25 m later; it declares the slide by 1.4 m driven and, from 2 m on,
        // measures it within 0.02 m/m at every scan.
        let (_, _, _, verdicts) = drive_with_slide_test(0.1, &slide_test_on());
        assert_slide_found(&verdicts, 1.4, 0.1, 0.02);
    }

    /// Asserts the slide test declared a slide by `by_m` driven and, from 2 m on, measured it within
    /// `tolerance` of `slide_per_m` at every scan.
    fn assert_slide_found(verdicts: &[(f64, Option<f64>)], by_m: f64, slide_per_m: f64, tolerance: f64) {
        let first = verdicts.iter().find(|(_, k)| k.is_some()).map(|(x, _)| *x);
        assert!(first.is_some_and(|x| x <= by_m), "{verdicts:?}");
        for (x, k) in verdicts.iter().filter(|(x, _)| *x >= 2.0) {
            assert!(k.is_some_and(|k| (k - slide_per_m).abs() < tolerance), "{x}: {k:?}");
        }
    }

    #[test]
    fn the_slide_test_finds_no_slide_where_there_is_none() {
        let (_, _, _, verdicts) = drive_with_slide_test(0.0, &slide_test_on());
        assert!(verdicts.iter().all(|(_, k)| k.is_none()), "{verdicts:?}");
    }

    #[test]
    fn the_slide_test_ignores_a_slide_under_its_threshold() {
        // 0.015 m/m, under half the 0.04 m/m the test takes for a slide.
        let (_, _, _, verdicts) = drive_with_slide_test(0.015, &slide_test_on());
        assert!(verdicts.iter().all(|(_, k)| k.is_none()), "{verdicts:?}");
    }

    /// Drives 6 m along straight rows 0.75 m apart, 0.1 m per scan, on a true straight line, while the
    /// odometry turns by `turn_rad_per_m` per metre driven (a gyro bias the EKF has not learned) and
    /// the robot slides `slide_per_m` to the left from `slide_from_m` driven on. Returns the slide
    /// test's verdict at each scan, `(x, found)`, and the last lane's centre error at the robot, m.
    fn drive_with_turn_and_slide(
        turn_rad_per_m: f64,
        slide_per_m: f64,
        slide_from_m: f64,
        config: &DetectorConfig,
    ) -> (Vec<(f64, Option<f64>)>, f64) {
        let mut verdicts = Vec::new();
        let mut lanes = Lanes::new(config);
        let mut map = CentroidMap::new(config.map_capacity);
        let mut centroids = Vec::new();
        let mut odom = Pose2::default();
        let mut error = f64::NAN;
        for k in 0..60 {
            let x = 0.1 * k as f64;
            if k > 0 {
                let yaw = odom.yaw + 0.5 * 0.1 * turn_rad_per_m;
                odom = Pose2::new(
                    odom.x + 0.1 * yaw.cos(),
                    odom.y + 0.1 * yaw.sin(),
                    odom.yaw + 0.1 * turn_rad_per_m,
                );
            }
            let y_true = slide_per_m * (x - slide_from_m).max(0.0);
            let rows: Vec<f64> = (-3..3).map(|j| (j as f64 + 0.5) * 0.75 - y_true).collect();
            let pts = rows_of_points(&rows, 0.0);
            let out =
                step_whole(&mut lanes, &pts, &pts, &odom, 0.1 * k as f64, config, &mut map, &mut centroids);
            if let Some(lane) = out.lane {
                error = lane.o + y_true;
            }
            verdicts.push((x, lanes.slide_per_m()));
        }
        (verdicts, error)
    }

    #[test]
    fn a_turn_of_odom_is_no_slide() {
        // 0.04 rad per metre: `fault-gyro-bias-step`'s 0.02 rad/s step at 0.5 m/s. Each stored centroid
        // moves by its age times its distance ahead (2-4 m), a shear of 0.08-0.16 m/m without the turn
        // term. Asserted over the first 4 m (0.16 rad of heading error; the EKF's bias check finds such
        // a step within 2 m): beyond 5 m the test declared a slide of 0.04 m/m.
        let (verdicts, _) = drive_with_turn_and_slide(0.04, 0.0, 0.0, &slide_test_on());
        assert!(verdicts.iter().filter(|(x, _)| *x <= 4.0).all(|(_, k)| k.is_none()), "{verdicts:?}");
    }

    #[test]
    fn a_slide_under_a_turn_of_odom_is_still_a_slide() {
        // The same turn with a slide of 0.1 m/m from the start: declared by 1.5 m driven and, from 2 m
        // on, within 0.04 m/m of the slide (measured 0.065-0.08: the turn term takes up a part).
        let (verdicts, _) = drive_with_turn_and_slide(0.04, 0.1, 0.0, &slide_test_on());
        assert_slide_found(&verdicts, 1.5, 0.1, 0.04);
    }

    #[test]
    fn a_slide_declared_late_moves_only_the_centroids_it_moved() {
        // 0.1 m/m from 3 m driven on, after 3 m of map: the centroids stored before the slide began
        // moved by the slide since then, not by their age; at 6 m the lane at the robot is within
        // 1.5 cm of the rows (measured 0.4 cm; with the slide applied to every age, 4.1 cm off).
        let (verdicts, error) = drive_with_turn_and_slide(0.0, 0.1, 3.0, &slide_test_on());
        assert!(verdicts.iter().any(|(_, k)| k.is_some()), "{verdicts:?}");
        assert!(error.abs() < 0.015, "{error}");
    }

    #[test]
    fn rows_turning_with_their_distance_ahead_give_no_shear() {
        // Every row moved by 0.04 · x · age (a turn of odom), one row on each side: the turn is taken
        // out and the comparison is within 1e-6 of none; a plain shear of 0.08 is kept.
        let turned = |m: f64, k: f64| {
            let mut row = RowFit::default();
            for a in 0..6 {
                let age = 0.15 * a as f64;
                for i in 0..12 {
                    let x = 2.0 + 0.25 * i as f64;
                    row.add(x, (k + m * x) * age, 1.0, age);
                }
            }
            row
        };
        let (k, _) = slide_consensus_of_rows(&[turned(0.04, 0.0), turned(0.04, 0.0)], -1).unwrap();
        assert!(k.abs() < 1e-6, "{k}");
        let (k, _) = slide_consensus_of_rows(&[turned(0.0, 0.08), turned(0.0, 0.08)], -1).unwrap();
        assert!((k - 0.08).abs() < 1e-6, "{k}");
    }

    /// Drives 6 m along straight rows 0.75 m apart (`odom` heading 0, the odometry true), 0.1 m per scan,
    /// through a gap across every row over `odom` x 3.5-5.5 m, while the robot slides `slide_per_m` to
    /// the left unseen by the odometry. `shift(x, point_x)` moves a return of the scan taken at `x`
    /// sideways, m, given the return's `odom` x; `each(x, lanes, output)` sees every scan's result.
    fn drive_through_a_gap(
        slide_per_m: f64,
        shift: impl Fn(f64, f64) -> f64,
        config: &DetectorConfig,
        mut each: impl FnMut(f64, &Lanes, &LaneOutput),
    ) {
        let mut lanes = Lanes::new(config);
        let mut map = CentroidMap::new(config.map_capacity);
        let mut centroids = Vec::new();
        for k in 0..60 {
            let x = 0.1 * k as f64;
            let y_true = slide_per_m * x;
            let rows: Vec<f64> = (-3..3).map(|j| (j as f64 + 0.5) * 0.75 - y_true).collect();
            let pts: Vec<[f32; 3]> = rows_of_points(&rows, 0.0)
                .into_iter()
                .filter(|p| !(3.5..5.5).contains(&(x + f64::from(p[0]))))
                .map(|[px, py, pz]| [px, py + shift(x, x + f64::from(px)) as f32, pz])
                .collect();
            let odom = Pose2::new(x, 0.0, 0.0);
            let out =
                step_whole(&mut lanes, &pts, &pts, &odom, 0.1 * k as f64, config, &mut map, &mut centroids);
            each(x, &lanes, &out);
        }
    }

    /// [`drive_through_a_gap`] where, from 2 m to 4 m driven, the near part of the view is empty and the
    /// rows past the gap read further left by `far_drift_per_m` times the distance driven since 2 m
    /// (the canopy where a gap ends, seen side-on at the far end of the view: soak seed 869). Returns
    /// the slide test's verdict at each scan.
    fn drive_towards_a_gap(
        far_drift_per_m: f64,
        slide_per_m: f64,
        config: &DetectorConfig,
    ) -> Vec<(f64, Option<f64>)> {
        let drift = |x: f64, _| if (2.0..=4.0).contains(&x) { far_drift_per_m * (x - 2.0) } else { 0.0 };
        let mut verdicts = Vec::new();
        drive_through_a_gap(slide_per_m, drift, config, |x, lanes, _| {
            verdicts.push((x, lanes.slide_per_m()))
        });
        verdicts
    }

    #[test]
    fn rows_past_a_gap_are_not_compared_while_the_near_view_is_empty() {
        // 0.06 m/m of drift in the rows past the gap, and no slide: nothing is declared up to the end
        // of the empty near view. With the rule off a slide of 0.06 m/m is declared from 2.8 m on.
        let before_end =
            |v: &[(f64, Option<f64>)]| v.iter().filter(|(x, _)| *x <= 4.0).any(|(_, k)| k.is_some());
        let verdicts = drive_towards_a_gap(0.06, 0.0, &slide_test_on());
        assert!(!before_end(&verdicts), "{verdicts:?}");
        let off = DetectorConfig { shear_near_gap_m: 0.0, ..slide_test_on() };
        assert!(
            before_end(&drive_towards_a_gap(0.06, 0.0, &off)),
            "the case no longer provokes a false slide"
        );
    }

    #[test]
    fn a_slide_declared_before_a_gap_is_kept_through_it() {
        // A slide of 0.1 m/m from the start, declared before the gap comes into view, is still
        // declared at every scan while the near view is empty (its comparisons stay pooled).
        let verdicts = drive_towards_a_gap(0.0, 0.1, &slide_test_on());
        assert_slide_found(&verdicts[..=40], 1.4, 0.1, 0.02);
    }

    /// [`drive_through_a_gap`] where the crop's first metre past the gap reads 8 cm further left, as
    /// the canopy where rows begin does seen side-on from off the lane centre (soak seed 1051). Returns
    /// the largest heading of the lane, rad, while the robot is in the gap.
    fn heading_in_a_gap(config: &DetectorConfig) -> f64 {
        let side_on = |_, point_x: f64| if (5.5..6.5).contains(&point_x) { 0.08 } else { 0.0 };
        let mut worst = 0.0f64;
        drive_through_a_gap(0.0, side_on, config, |x, _, out| {
            if let Some(lane) = out.lane.filter(|_| (3.5..5.5).contains(&x)) {
                worst = worst.max(lane.a.abs());
            }
        });
        worst
    }

    #[test]
    fn a_heading_prior_slows_the_lane_turning_to_the_askew_crop_past_a_gap() {
        // The free fit turns the lane by 0.024 rad towards the askew crop; the prior, which draws the
        // heading towards its prediction at each scan, slows that turn (0.017 at 50, 0.012 at 200).
        let with_prior =
            |w: f64| heading_in_a_gap(&DetectorConfig { heading_prior_m2: w, ..DetectorConfig::default() });
        let free = heading_in_a_gap(&DetectorConfig::default());
        assert!(free > 0.02, "the case no longer provokes a skewed heading: {free}");
        let (held, firm) = (with_prior(50.0), with_prior(200.0));
        assert!(held < 0.8 * free && firm < 0.6 * free, "free {free}, prior 50 {held}, prior 200 {firm}");
    }

    #[test]
    fn a_clump_moving_one_row_is_no_slide() {
        // The first row left alone moves by 0.25 m per metre (a clump growing beside it), the others
        // stand: the rows right of the robot disagree, so the test never declares a slide (pooled over
        // all six rows, as before the per-row test, it read as one of about 0.04).
        let mut slides = [0.0; 6];
        slides[3] = 0.25;
        let (_, _, _, verdicts) = drive_with_row_slides(slides, &slide_test_on());
        assert!(verdicts.iter().all(|(_, k)| k.is_none()), "{verdicts:?}");
    }

    #[test]
    fn a_clump_between_the_lane_rows_is_no_slide() {
        // A clump in the lane's inter-row pulls its two rows towards each other: opposite shifts.
        let mut slides = [0.0; 6];
        slides[2] = -0.1;
        slides[3] = 0.1;
        let (_, _, _, verdicts) = drive_with_row_slides(slides, &slide_test_on());
        assert!(verdicts.iter().all(|(_, k)| k.is_none()), "{verdicts:?}");
    }

    /// One row's comparison: this scan's centroids (age 0) and stored ones (ages 0.15-0.75 m) over
    /// x = 2-5 m, each displaced by `shear · age`.
    fn row_fit(shear: f64) -> RowFit {
        let mut row = RowFit::default();
        for a in 0..6 {
            let age = 0.15 * a as f64;
            for i in 0..12 {
                row.add(2.0 + 0.25 * i as f64, shear * age, 1.0, age);
            }
        }
        row
    }

    #[test]
    fn rows_shifting_alike_give_their_shear() {
        // Rows j = -2..2 (two each side), all at 0.08 m/m: their shear, to 1e-9.
        let rows = [row_fit(0.08), row_fit(0.08), row_fit(0.08), row_fit(0.08)];
        let (k, _) = slide_consensus_of_rows(&rows, -2).unwrap();
        assert!((k - 0.08).abs() < 1e-9, "{k}");
    }

    #[test]
    fn rows_disagreeing_across_the_robot_give_no_shear() {
        // Left rows at +0.08, right rows at -0.02 and 0: the sides disagree in sign, the comparison is 0.
        let rows = [row_fit(-0.02), row_fit(0.0), row_fit(0.08), row_fit(0.08)];
        assert_eq!(slide_consensus_of_rows(&rows, -2).map(|(k, _)| k), Some(0.0));
        // Both sides positive, with equal weights: all rows pooled, to 1e-9.
        let rows = [row_fit(0.03), row_fit(0.03), row_fit(0.09), row_fit(0.09)];
        let (k, _) = slide_consensus_of_rows(&rows, -2).unwrap();
        assert!((k - 0.06).abs() < 1e-9, "{k}");
    }

    #[test]
    fn rows_on_one_side_only_give_no_comparison() {
        let rows = [RowFit::default(), RowFit::default(), row_fit(0.08), row_fit(0.08)];
        assert_eq!(slide_consensus_of_rows(&rows, -2), None);
    }

    /// The slide test on, as measured in docs/faults.md (opt-in since session 28).
    fn slide_test_on() -> DetectorConfig {
        DetectorConfig { shear_window_m: 0.5, shear_max_per_m: 0.12, ..DetectorConfig::default() }
    }

    /// The joint fit's shear term alone: the slide test off, the shear term's own bound.
    fn shear_term_alone() -> DetectorConfig {
        DetectorConfig { shear_window_m: 0.0, shear_max_per_m: 0.2, ..DetectorConfig::default() }
    }

    #[test]
    fn a_zero_window_turns_the_slide_test_off() {
        let cfg = DetectorConfig { shear_window_m: 0.0, ..slide_test_on() };
        let (_, _, _, verdicts) = drive_with_slide_test(0.1, &cfg);
        assert!(verdicts.iter().all(|(_, k)| k.is_none()), "{verdicts:?}");
    }

    #[test]
    fn a_sheared_map_gives_the_shear_and_the_rows_where_they_are_now() {
        // A slide of 0.1 m per metre with a weak prior and no deadband, the joint fit's shear term alone
        // (the slide test off): the shear is found within 0.005 m/m and the lane centre (0.6 m to the
        // robot's right by now) within 1 cm, heading within 0.1°.
        let cfg = DetectorConfig { shear_prior_m2: 0.1, shear_deadband_per_m: 0.0, ..shear_term_alone() };
        let (lane, shear, y_true) = drive_with_slide(0.1, &cfg);
        assert!((shear - 0.1).abs() < 0.005, "{shear}");
        assert!((lane.o + y_true).abs() < 0.01, "{lane:?} vs {y_true}");
        assert!(lane.a.atan().abs() < 0.1f64.to_radians(), "{lane:?}");
    }

    #[test]
    fn the_default_shear_prior_halves_the_lean_of_a_slide() {
        // The same slide with the shear term's defaults (prior and deadband shrink the shear; the slide
        // test off) and with the shear pinned at 0: the lane centre is off by less than half as much
        // (measured 6 cm vs 27 cm).
        let (lane, _, y_true) = drive_with_slide(0.1, &shear_term_alone());
        let pinned = DetectorConfig { shear_enabled: false, ..shear_term_alone() };
        let (lane_pinned, shear, _) = drive_with_slide(0.1, &pinned);
        assert_eq!(shear, 0.0);
        let (err, err_pinned) = ((lane.o + y_true).abs(), (lane_pinned.o + y_true).abs());
        assert!(2.0 * err < err_pinned, "{err} vs {err_pinned}");
    }

    #[test]
    fn no_slide_fits_no_shear() {
        // Odometry that tells the truth: shear below 0.002 m/m, centre within 5 mm.
        let cfg = DetectorConfig::default();
        let (lane, shear, _) = drive_with_slide(0.0, &cfg);
        assert!(shear.abs() < 0.002, "{shear}");
        assert!(lane.o.abs() < 0.005, "{lane:?}");
    }

    #[test]
    fn the_shear_stays_within_its_bound() {
        // A slide of 0.3 m/m against a bound of 0.05: the fit holds the shear at the bound.
        let cfg = DetectorConfig { shear_max_per_m: 0.05, ..DetectorConfig::default() };
        let (_, shear, _) = drive_with_slide(0.3, &cfg);
        assert!(shear.abs() <= 0.05 + 1e-9, "{shear}");
    }

    #[test]
    fn transport_moves_the_lane_with_the_robot() {
        let lane = Lane { o: 0.1, a: 0.0, b: 0.0, s: 0.75, crests: 1.0 };
        let from = Pose2::new(0.0, 0.0, 0.0);
        let to = Pose2::new(1.0, 0.05, 0.1);
        let t = lane.transport(&from, &to).unwrap();
        // The centre line y = 0.1 seen from (1, 0.05) yawed 0.1 rad: slope -tan 0.1, offset 0.05/cos 0.1.
        assert!((t.a + 0.1f64.tan()).abs() < 1e-9, "{t:?}");
        assert!((t.o - 0.05 / 0.1f64.cos()).abs() < 1e-9, "{t:?}");
    }

    #[test]
    fn crossing_a_row_renumbers_the_rows() {
        let lane = Lane { o: 0.5, a: 0.0, b: 0.0, s: 0.75, crests: 1.0 }.normalised();
        assert!((lane.o + 0.25).abs() < 1e-12);
    }
}
