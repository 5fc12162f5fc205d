//! The detector's configuration: one struct, two modes, validated once when the detector is built.
//!
//! ```
//! use croprow_core::{DetectorConfig, DetectorMode};
//! let paper = DetectorConfig::paper();
//! assert_eq!(paper.mode, DetectorMode::Paper);
//! assert!(DetectorConfig::default().validate().is_ok());
//! ```

use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, check_range};

/// Which detection pipeline runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum DetectorMode {
    /// The paper's method (Sec. III-A): K-means per depth bin, a centroid map carried by odometry, RANSAC on
    /// the first left and first right row. Kept forever as the yardstick.
    Paper,
    /// Croprow's method: all visible rows fitted jointly as parallel (optionally curved) lines with an
    /// online row spacing, on a short map of per-row centroids carried by odometry.
    #[default]
    Default,
}

impl DetectorMode {
    /// Stable lower-case name (`"paper"`, `"default"`), as the CLI and config files spell it.
    pub fn as_str(&self) -> &'static str {
        match self {
            DetectorMode::Paper => "paper",
            DetectorMode::Default => "default",
        }
    }
}

/// Configuration of the [`RowDetector`](super::RowDetector). Distances are metres in `base_link`
/// unless stated; "depth" is the forward distance from the sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectorConfig {
    /// Pipeline to run. Default `default`; `paper` for the paper's method.
    pub mode: DetectorMode,
    /// Horizontal field of view kept in front of the sensor, degrees. Default 120 (paper Sec. III-A-1).
    pub fov_deg: f64,
    /// Maximum range from the sensor, m. Default 4 (paper Sec. III-A-1).
    pub range_m: f64,
    /// Minimum range from the sensor, m: closer returns are the robot itself. Default 0.3.
    pub min_range_m: f64,
    /// Height the virtual ground plane is raised above the centroid of the cropped points, m.
    /// Default 0 (paper eqs. 1-2); the authors' code uses 0.02.
    pub plane_raise_m: f64,
    /// Depth bins for K-means (paper mode): width of one bin, m. Default 1 (paper Sec. III-A-2);
    /// the authors' code uses a single 2.4 m bin.
    pub depth_bin_m: f64,
    /// Depth beyond which canopy points are not clustered (paper mode), m; at most 64 depth bins.
    /// Default 4 (the range crop); the authors' code uses 2.4.
    pub max_depth_m: f64,
    /// K-means clusters per depth bin before merging (paper mode). Default 10 (the paper's "large n";
    /// the value of the authors' code).
    pub kmeans_k: usize,
    /// K-means (Lloyd) iterations per bin (paper mode). Default 10.
    pub kmeans_iterations: usize,
    /// Centroids closer than this laterally are merged into one row centroid, m. Default 0.3 (paper
    /// Sec. III-A-2).
    pub merge_distance_m: f64,
    /// RANSAC iterations per row (paper mode). Default 1000 (paper Sec. III-A-3).
    pub ransac_iterations: usize,
    /// RANSAC inlier distance, m (paper mode; not given in the paper). Default 0.05.
    pub ransac_inlier_m: f64,
    /// A row is fitted once its centroids span this length along x, m. Default 2 (paper Sec. III-A-3).
    pub min_span_m: f64,
    /// Centroids further behind `base_link` than this are dropped from the fit, m. Default 0.5 (paper
    /// Sec. III-A-3).
    pub behind_m: f64,
    /// Paper mode end of row: fewer canopy points than this ... Default 200 (authors' code).
    pub end_min_points: usize,
    /// ... for this many consecutive scans raises `EndOfRow`. Default 20 (authors' code).
    pub end_scans: usize,
    /// Rows tracked but not updated for this long are reported `Lost`, s. Default 1.
    pub lost_after_s: f64,
    /// Fastest plausible robot motion between two scans, m/s; a faster jump of the odometry is a
    /// teleport and the scan is refused. Default 5.
    pub max_speed_mps: f64,
    /// Largest plausible gap between two scans, s; a longer gap resets the map. Default 2.
    pub max_gap_s: f64,
    /// Default mode: the canopy plane is never lower than this above the ground level (5th height
    /// percentile), m, so that weeds (1-8 cm) and ground noise stay out. Default 0.12.
    pub min_plant_height_m: f64,
    /// Default mode: smallest row spacing searched, m. Default 0.3.
    pub spacing_min_m: f64,
    /// Default mode: largest row spacing searched, m. Default 1.5.
    pub spacing_max_m: f64,
    /// Default mode: largest row heading searched at start-up, degrees. Default 20.
    pub heading_search_deg: f64,
    /// Default mode: a canopy point belongs to a row when it lies within this fraction of the row spacing
    /// from the predicted row centre. Default 0.3.
    pub gate_fraction: f64,
    /// Default mode: half-width, as a fraction of the canopy period, of the window that tests where each
    /// bin's canopy peaks: started at the mean of the bin's gated points, it moves to the mean of the
    /// points it covers until it settles, and a bin whose window then reaches past the gate is left out
    /// of the map (its canopy peaks outside the gate: tall weeds between the rows, the outer leaves of a
    /// field's last row). 0 keeps every bin. Default 0 (off): 0.1 cleans the tall-weed fault lane and soak
    /// seeds 50, 621, 77, 119, but on the soak's 84 weed runs it ran over more plants in all (195 -> 228:
    /// weeds filling the start-up view), and beside the shear term it cost 20 m of grown soybean (1.37 ->
    /// 1.70 cm following) and a gyro-step turn (soak seed 699); 0.15 dropped too many bins of a grown
    /// soybean canopy (detection 1.54 -> 1.67 cm). See docs/faults.md.
    pub core_fraction: f64,
    /// Default mode: the same test as `core_fraction`, applied only to the rows beyond the lane's own
    /// two (the larger of the two fractions applies there). A row the lattice predicts beyond a field's
    /// edge gathers the outer leaves of the last row; the lane's own rows keep every bin. Default 0
    /// (off): 0.1 fixes the squeezed lattice of soak seeds 618 and 1972, and over the 2000 soak seeds it
    /// cut the runs passing a stem under 10 cm from 88 to 64 but ran over 7 plants in 4 runs against
    /// 5 in 3. See docs/faults.md, session 48.
    pub outer_core_fraction: f64,
    /// Default mode: length of the along-row bins whose centroids enter the map, m. Default 0.25.
    pub map_bin_m: f64,
    /// Default mode: fewest canopy points for a bin centroid to enter the map. Default 4.
    pub map_min_points: usize,
    /// Default mode: capacity of the centroid map (ring buffer, allocated once). Default 4096.
    pub map_capacity: usize,
    /// Default mode: fit a curvature term (curved rows). Default true.
    pub fit_curvature: bool,
    /// Default mode: the canopy is declared ended when at least this much visible ground follows the
    /// last canopy in the lane, m. Default 1.
    pub end_empty_m: f64,
    /// Default mode: `EndOfRow` is raised once the row end is this close ahead of `base_link`, m.
    /// Default 0.5.
    pub end_trigger_m: f64,
    /// Default mode: level each scan by the tilt of the surface below the sensor, so that a LiDAR a few
    /// degrees off its configured mount still sees a level ground (`perception::level`). The paper mode
    /// is never levelled. Default true.
    pub level_enabled: bool,
    /// Levelling: side of the square cells whose low return gives the surface height, m. Default 0.5
    /// (several returns per cell at 4 m, narrower than a row gap is long).
    pub level_cell_m: f64,
    /// Levelling: largest roll or pitch corrected, degrees; a larger fitted tilt is clamped to it. Default
    /// 6 (twice the ±3° mount error of issue 6).
    pub level_max_tilt_deg: f64,
    /// Levelling: time constant of the low-pass on the fitted tilt, s. Default 0.5 (a knocked mount is
    /// followed within 1.5 s; one scan's fit moves it by a fifth at 10 Hz).
    pub level_time_constant_s: f64,
    /// Levelling: fewest cells on the fitted surface for a scan's fit to count; fewer holds the previous
    /// estimate (none at all before the first fit). Default 12.
    pub level_min_cells: usize,
    /// Default mode: fit a shear of the centroid map, the sideways motion the odometry did not sense
    /// (a slide on wet soil) per metre driven, so that the lane describes the rows where they are now
    /// rather than where old centroids put them. Default true.
    pub shear_enabled: bool,
    /// Default mode: prior weight drawing the shear towards none, in full-weight centroids times m² (a
    /// centroid at 1 m age moved by the shear). Default 5 (measured, see docs/faults.md).
    pub shear_prior_m2: f64,
    /// Default mode: largest shear fitted, m per metre driven; beyond it the shear is held at the bound.
    /// Default 0.12, chosen with the slide test on (the soak's strongest slides, 0.08 m/s at 0.5 m/s
    /// with 20-40 % slip, are 0.10-0.13 per metre the wheels report): on the soak's 25 slide seeds 0.12
    /// left 136 plants, 0.1 164, 0.15 173, 0.2 324 (the slide test's measured shear overshoots on grown
    /// soybean; see docs/faults.md). 0.2 (a 0.1 m/s slide at 0.5 m/s) suited the shear term alone,
    /// before registration; the session-28 soaks of the slide test off kept 0.12.
    pub shear_max_per_m: f64,
    /// Default mode: a fitted shear within this of none is the fit's own noise and bias and is held at
    /// none; beyond it the shear is shrunk by `d²/k` (continuous), m per metre driven. Default 0.025
    /// (measured: on fields without a slide the fitted shear stays within ±0.021).
    pub shear_deadband_per_m: f64,
    /// Default mode: the field's planted row spacing, m, when known; 0 when not (the spacing is then
    /// learned from the canopy alone). A field parameter, not a crop's: the planter sets it. When known,
    /// the start-up search takes the canopy period (one or two crests per row) nearest to it, and a lane
    /// whose spacing is more than `planted_spacing_tolerance` off it is no lane (searched again).
    /// Default 0, opt-in: on the 17 soak seeds it was built for (a grown canopy's ground read as
    /// repeating every second row gave a doubled spacing: 439, 982, 75) it took 236 plants to 20, but
    /// on the 1000-run soak it gave 14 runs new contacts (317 plants, 4 of them fault-free grown
    /// fields re-entered on the density's lattice: seed 125, 117 plants) against 14 fixed (217 plants).
    /// Since a two-crest lane's centre is the gap where the ground shows (125: 0), the 40 seeds it changed
    /// are at 87 plants in 8 runs (611: 56) against 178 in 16 without it; see docs/faults.md, Start-up.
    pub planted_spacing_m: f64,
    /// Default mode: largest relative difference between a lane's spacing and `planted_spacing_m` for the
    /// lane to be believed (unused while the planted spacing is unknown). Default 0.12: tracked lanes
    /// on the simulated demo field sit 9.5 % under to 1.3 % over the planted spacing (1st-99th
    /// percentile), the wrong lattices the soak followed 12-28 % off (docs/faults.md, Start-up).
    pub planted_spacing_tolerance: f64,
    /// Default mode: weight of a prior that draws the tracked lane's row spacing towards the field's
    /// known spacing (`spacing_prior_m`), in full-weight map centroids (a fit holds hundreds); 0 leaves
    /// the spacing to the canopy alone, as the paper does. Only the tracking fit uses it, and only on a
    /// lane within `planted_spacing_tolerance` of the known spacing; the start-up search and the lane
    /// checks do not (that is `planted_spacing_m`). A closed canopy holds its
    /// lattice weakly: fault-free soak seed 1972 (grown soybean, 0.71 m rows, dense weeds) read 0.62 m
    /// in its second lane, on a lattice centred on the robot, and followed it up to 16 cm off the lane
    /// centre (6.6 cm mean); at 20 it followed at 3.2 cm mean, and Table I over 200 m at or under the
    /// default in every field (grown soybean 1.04 -> 1.01 cm). Default 0, opt-in: at 20 the 1000-run
    /// soaks ran over 62 plants in 8 runs (seeds 0-999) and 41 in 8 (1000-1999) against 9 in 7 and
    /// 30 in 2, several of them at the start, where the prior dragged the start-up search's other
    /// lattice; with the tolerance gate, 15 plants in 4 runs on seeds 0-999, 724 done against 732
    /// (docs/faults.md, session 40).
    pub spacing_prior_weight: f64,
    /// Default mode: the known row spacing the prior draws to, m; 0 takes `planted_spacing_m` when
    /// set, else no prior. The navigator fills a 0 with `lane_switch.row_spacing_m`, the planted
    /// spacing its turns already use; the detector on its own (`croprow detect`) has none.
    pub spacing_prior_m: f64,
    /// Default mode: consecutive scans over which a lane found by the start-up search (after
    /// construction or a reset) must hold still before its rows are reported (until then the status is
    /// `searching`); 0 reports it at once. Default 0 (off): 5 (half a second) took soak seeds 31 and 337
    /// from 9 and 6 plants to 0, but a lattice that holds still at rest and swings once the robot moves
    /// passed it, and the later runs it changed ran over more (451: 4 -> 16, 267: 0 -> 19, 618: 0 -> 12
    /// plants); see docs/faults.md, Start-up.
    pub start_confirmations: usize,
    /// Default mode: where the robot was set down (under 0.1 m driven) over an open canopy (under 45 %
    /// of the cropped returns are canopy: the ground shows), the start-up search takes a lattice only
    /// when the canopy of the view up to 3 m ahead runs along its rows: per lateral bin, how many 0.5 m
    /// slices along x hold canopy; that count's component in phase with the lattice's rows, relative to
    /// the bins and slices holding any (`Lanes::lane_contrast`: 2 for narrow rows with canopy in every
    /// slice, 0 for canopy spread evenly, negative for a lattice on the inter-rows), is at least this.
    /// Crop rows hold canopy along the whole view; weeds taller than the crop in every inter-row make
    /// lattices whose rows do not. Until then the rows are not reported and the robot waits. 0 turns it
    /// off. Default 0.4: the first searches of the soak's young fields without weeds in view measured
    /// 0.69 or more, the lattices of the weed starts -0.26-0.32 (docs/faults.md, session 34).
    pub start_row_contrast: f64,
    /// Default mode: largest change of the searched lane's heading over the confirming scans, degrees.
    /// Default 1.
    pub start_heading_tolerance_deg: f64,
    /// Default mode: largest change of the searched lane's centre offset (and of its spacing) over the
    /// confirming scans, m. Default 0.03.
    pub start_offset_tolerance_m: f64,
    /// Default mode: a searched lane is confirmed only while both its first rows are seen this far ahead
    /// of `base_link`, m: a short stretch of row cannot tell the heading. Default 3 (rows in full view
    /// reach 4.0-4.4 m with the default `range_m`; soak seeds 337, 267 stood 1-2 m before a gap across
    /// every row and took headings 10-28° off from the metre before it).
    pub start_min_reach_m: f64,
    /// Default mode: distance driven over which the slide test pools its evidence, m (see
    /// `perception::lanes`, the slide test: the map's centroids still in view are compared with the
    /// newest scan's rows, and a shear that the last `shear_window_m` all agree on replaces the fitted,
    /// shrunk one, from where the slide began, and the MPC plans from the course over the ground).
    /// 0 turns the test off. Default 0 (off since session 28; 0.5 turns it on, the default before).
    /// Built before canopy registration, it took the soak's 25 slide seeds from 833 plants to 127 with
    /// the shear term alone beside it. With registration on (the default since session 25) it adds
    /// false slides at its threshold (the lane translates sideways with the robot at row ends, among
    /// dust, at lane entries: soak seeds 63, 748, 8): over seeds 0-1999 of the soak, off ran over
    /// 249 plants in 47 runs against 274 in 61 with it on, 1640 missions done against 1623, and 1
    /// fault-free run touched against 6; slides alone went 69 plants in 14 runs -> 72 in 22 (see
    /// docs/faults.md, session 28).
    pub shear_window_m: f64,
    /// Default mode: least shear the slide test takes for a slide, m per metre driven. Default 0.04
    /// (the soak's slides are 0.06-0.13 per metre the wheels report; the tall weed patch of
    /// `fault-weed-patch` reads as a slide of 0.04-0.06 m/m: 13.6 cm off the line at 0.04, 11 at 0.05,
    /// 6.9 at 0.06, 4.4 at 0.07 as with the test off).
    pub shear_test_min_per_m: f64,
    /// Default mode: how much farther than usual a scan's nearest row centroid may start before the
    /// near view counts as empty (a gap across every row ahead) and the slide test makes no
    /// comparisons, m; its pooled comparisons then stand still, so a declared slide is kept. 0 turns
    /// the rule off. Default 0.2 (the view usually starts 1.4-1.5 m ahead over grown corn): in soak seed
    /// 869 (curved grown corn, every row missing over 2.6 m, no slip) the crop past the gap, seen only
    /// at the far end of the view, read as a slide of 0.02-0.06 m/m and then 0.3 as the near rows
    /// returned; a false slide was declared and the robot ran over 19 plants.
    pub shear_near_gap_m: f64,
    /// Default mode: prior weight drawing the lane's heading towards its prediction (carried by
    /// odometry) at each scan, in full-weight centroids times m² (a centroid 1 m from the fit's centre
    /// along x); 0 leaves the heading free. It slows the lane turning towards 1-2 m of crop seen at the
    /// far end of the view past a gap across every row (soak seed 1051). Default 0 (opt-in): on 269
    /// soak seeds (66 with such a gap, 23 of the default's near misses, 180 drawn at random) 20 cut
    /// the runs passing a stem under 8 cm from 29 to 19 and cleaned the three slide contacts, but ran
    /// over 14 plants in 3 other runs (5 in 3 by default) and finished 6 fewer runs (more `sliding`
    /// stops); 50: 20 under 8 cm, 9 plants in 4. See docs/faults.md, session 47.
    pub heading_prior_m2: f64,
    /// Default mode: side of the cubic voxels of the clutter test, m (see `clutter_min_points`).
    /// Default 0.2 (measured on soak seeds 451 and 148, returns more than 0.12 m above the ground): at
    /// 0.1 a young corn canopy lost 12-16 % of its returns (thin leaves crossed by one ring) against 3 %
    /// of a tall weed patch's, and seed 451 ran over 52 plants instead of 4; at 0.2 the crop loses
    /// under 1 % and about a tenth of the dust survives (0.6-0.8 % of a scan's cropped returns, far
    /// under the 5 % that would move the 95th height percentile).
    pub clutter_voxel_m: f64,
    /// Default mode: fewest cropped returns (ground and canopy) a voxel of `clutter_voxel_m` must hold
    /// for them to be kept; returns alone in the air are clutter (dust, insects) and are dropped before
    /// the canopy plane is placed and the rows are fitted. 0 or 1 keeps every return. Default 3: among
    /// 500-585 spurious returns a scan over young corn (soak seeds 148, 307) the 95th height
    /// percentile jumped from the canopy top (0.27 m) into the dust (0.85 m), the plane rose above the
    /// crop, and the fit followed the dust's height-squared weights 0.2 rad off the rows; the test
    /// keeps 9-12 % of the dust (seed 148) and 99 % of a young crop's canopy returns (seed 451).
    pub clutter_min_points: usize,
    /// Default mode: the clutter test drops the lone returns of a scan only when they are at least this
    /// share of its cropped returns (below it every return is kept). Default 0.03 (measured, 0.2 m
    /// voxels): fields without dust have 0.3-0.5 % lone returns (young corn, soak seed 451), up to
    /// 1.2 % (grown corn, seed 8) and 1.6 % (grown soybean, seed 11), the leaves' edges and ring ends;
    /// 585 spurious returns a scan make 5.6-6.4 % (seed 148), and it takes about 5 % above the canopy
    /// to move the 95th height percentile. Young crops keep their thin leaves' returns (dropping them
    /// took seed 451, tall weeds at the start, from 4 plants to 68).
    pub clutter_min_share: f64,
    /// Undo the scan's motion skew before the points are used (see `perception::deskew`): each return
    /// is moved from where the sensor was when it fired to where it is at the scan stamp, with the
    /// body twist the scan carries ([`Scan::twist`](super::Scan::twist); a scan without a finite twist
    /// is used as stamped). Default false (opt-in until a soak measures it).
    pub deskew: bool,
    /// Azimuth at which a sweep starts, degrees counter-clockwise from the sensor's +x, in the sensor
    /// frame; the columns are fired clockwise seen from above. Default 180 (behind the sensor: the
    /// Velodyne driver's cut and the simulator's). Range [-360, 360].
    pub deskew_sweep_start_deg: f64,
    /// Duration of one sweep, s; the scan is stamped at its end. Default 0.1 (a VLP-16 at 10 Hz).
    /// Range [0.01, 1].
    pub deskew_period_s: f64,
    /// Register each keyframe's canopy against the last one's to measure the sideways drift of the
    /// odometry that wheels and gyro cannot sense (a slide), and carry the lane map in `odom` corrected
    /// by it (see `perception::register`). Default true: on the 1000-run soak it halves the plants run
    /// over (218 in 39 runs off, 113 in 36 on), but it reads an unlearnt gyro bias step as a sideways
    /// drift (`fault-gyro-bias-step`: 16.6 cm worst cross-track against 6.1 off, no contact), and a few
    /// more runs stop safely at a row end (docs/faults.md, Canopy registration).
    pub register_enabled: bool,
    /// Register a lane found while the robot stood still (its odometry twist under 0.02 m/s and
    /// 0.02 rad/s: the start of a run, a resume) from its first keyframe, instead of after 1 m of it,
    /// with the increments' noise estimate starting from twice `register_noise_m` (the first pair,
    /// which it otherwise starts from, then comes from the robot setting off).
    /// A lane entered after a turn always waits the metre. Default false: it cleans most slides from
    /// a run's first metre (soak seeds 0-999: 7 plants in 3 runs against 12 in 8 without it, session
    /// 38), but registration fires more often with the true odometry under a closed canopy, and the
    /// 200 m grown-soybean run of Table I follows at 1.27 cm instead of 1.04 (the paper: 1.24), and
    /// a slide under the slide stop's limit in young soybean is missed for longer (soak seed 152).
    /// docs/faults.md, sessions 37 and 38.
    pub register_from_rest: bool,
    /// The slide watch: a lane found while the robot stood still is registered a second time from its
    /// first keyframe, with `register_from_rest`'s noise start, and the slide that registration finds
    /// is reported (`RowDetector::slide_per_m`: the slide stop and the MPC's course over the ground)
    /// while its correction is never applied; the lane keeps the registration that waits its metre.
    /// `register_from_rest` cleaned slides from a run's first metre but moved the lane under the robot
    /// on false drifts (Table I's 200 m grown soybean 1.27 cm instead of 1.04). Default true (since
    /// session 42): the 1000-run soaks ran over 6 plants in 3 runs (seeds 0-999) and 2 in 2
    /// (1000-1999) with it, against 9 in 7 and 30 in 2 without, with 6 fewer runs done over both,
    /// and the 200 m grown soybean followed at 1.17 cm (docs/faults.md, session 41). With it on,
    /// `lane_switch.max_slide_lag_m` stops the robot when the lanes lag the slide it finds.
    pub register_rest_watch: bool,
    /// Compare only the bands of the registered stretch that lie before the row end the lane
    /// pipeline found, with a band (0.25 m) to spare. Where the canopy ends inside a band its
    /// profiles lean to one side with the true odometry, the plants there seen from a changing
    /// distance: fault-free soak seed 662 (the slide test on) took a 7 cm drift 3 m before its row
    /// end and ran over a plant, seed 404 (a gyro bias step) read the last 2 m of its lane as a
    /// slide, and the recovery start registered from rest applied 2.5 cm 2.5 m before the end of
    /// its 12 m of rows. Default true (session 38; docs/faults.md). With false every band is
    /// compared, as before.
    pub register_before_row_end: bool,
    /// When the window's drift becomes significant, apply with it the increments that left the
    /// window unapplied just before, back to the likeliest onset of the drift (the newest of them
    /// that make the sum most significant, at most `register_window`). A slide passes the test some
    /// keyframes after it starts, and its first increments were dropped as noise: soak seed 777 (a
    /// 0.12 m/m slide) kept its lane 2.7 cm off after the correction. Default false: a window that
    /// passes on noise is extended by noise too, and the 200 m grown-soybean run of Table I follows
    /// at 1.33 cm instead of 1.04 with it (the paper: 1.24); with `register_from_rest` and
    /// `mpc.row_clearance_m` = 0.09 as well, 1.20 cm, and soak seeds 0-999 ran over 3 plants in 1
    /// run (session 39, docs/faults.md).
    pub register_from_onset: bool,
    /// Keyframes (one per 0.15 m driven) whose drift increments are summed for the significance test.
    /// Default 6 (0.9 m). Range [2, 60].
    pub register_window: usize,
    /// Least standard deviation of one keyframe's drift increment taken for the test, m: the test uses
    /// the noise the increments show (half the mean squared difference of successive ones, over about
    /// 3 m, starting from the first pair, or from twice this with `register_from_rest`), never less
    /// than this. Default 0.003 (measured on the simulated fields: 2-5 mm a keyframe with the skew
    /// undone). Range [0.0005, 0.1].
    pub register_noise_m: f64,
    /// Standard errors from zero at which the window's summed drift is applied. Default 3. Range
    /// [0.5, 20].
    pub register_z: f64,
    /// Where the canopy ends inside the registered stretch (a row end): the bands past the farthest
    /// one whose weight is at least this share of the fullest band's are not compared; their profiles
    /// lean to one side as the canopy ends (see `perception::register`). Default 0: every band is
    /// compared. 0.3 cleaned 14 of the 50 soak seeds that touch plants with registration on, but on
    /// the whole 1000-run soak it gave 132 plants in 30 runs against 121 in 34 (docs/faults.md).
    /// Range [0, 1].
    pub register_end_fraction: f64,
    /// Default mode: a sector of the sensor's azimuth with no return inside a scan that has returns
    /// on both sides of it (a dropped packet, a blocked window) is a hole. The lane bins it reaches
    /// into are left out of the scan's centroids and held by the map instead (the part of a row seen
    /// beside a hole leans away from it and turned the fit), and a scan whose hole hides both of the
    /// lane's own rows, with the map reaching less than 3 m ahead on one of them, does not count as
    /// seeing the rows (the navigator stops), nor is ground it hides seen empty (no row end there).
    /// See `perception::holes`.
    /// Default true: on the 154 soak seeds 0-1999 with a missing sector, 52 plants in 6 runs -> 31 in 3,
    /// 107 -> 97 done; the other seeds do not change (docs/faults.md, session 33).
    pub hold_scan_holes: bool,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            mode: DetectorMode::Default,
            fov_deg: 120.0,
            range_m: 4.0,
            min_range_m: 0.3,
            plane_raise_m: 0.0,
            depth_bin_m: 1.0,
            max_depth_m: 4.0,
            kmeans_k: 10,
            kmeans_iterations: 10,
            merge_distance_m: 0.3,
            ransac_iterations: 1000,
            ransac_inlier_m: 0.05,
            min_span_m: 2.0,
            behind_m: 0.5,
            end_min_points: 200,
            end_scans: 20,
            lost_after_s: 1.0,
            max_speed_mps: 5.0,
            max_gap_s: 2.0,
            min_plant_height_m: 0.12,
            spacing_min_m: 0.3,
            spacing_max_m: 1.5,
            heading_search_deg: 20.0,
            gate_fraction: 0.3,
            core_fraction: 0.0,
            outer_core_fraction: 0.0,
            map_bin_m: 0.25,
            map_min_points: 4,
            map_capacity: 4096,
            fit_curvature: true,
            end_empty_m: 1.0,
            end_trigger_m: 0.5,
            level_enabled: true,
            level_cell_m: 0.5,
            level_max_tilt_deg: 6.0,
            level_time_constant_s: 0.5,
            level_min_cells: 12,
            shear_enabled: true,
            shear_prior_m2: 5.0,
            shear_max_per_m: 0.12,
            shear_deadband_per_m: 0.025,
            planted_spacing_m: 0.0,
            planted_spacing_tolerance: 0.12,
            spacing_prior_weight: 0.0,
            spacing_prior_m: 0.0,
            start_confirmations: 0,
            start_row_contrast: 0.4,
            start_heading_tolerance_deg: 1.0,
            start_offset_tolerance_m: 0.03,
            start_min_reach_m: 3.0,
            shear_window_m: 0.0,
            shear_test_min_per_m: 0.04,
            shear_near_gap_m: 0.2,
            heading_prior_m2: 0.0,
            clutter_voxel_m: 0.2,
            clutter_min_points: 3,
            clutter_min_share: 0.03,
            deskew: false,
            deskew_sweep_start_deg: 180.0,
            deskew_period_s: 0.1,
            register_enabled: true,
            register_from_rest: false,
            register_rest_watch: true,
            register_before_row_end: true,
            register_from_onset: false,
            register_window: 6,
            register_noise_m: 0.003,
            register_z: 3.0,
            register_end_fraction: 0.0,
            hold_scan_holes: true,
        }
    }
}

impl DetectorConfig {
    /// The paper's method with the values of its text (Sec. III-A).
    pub fn paper() -> Self {
        Self { mode: DetectorMode::Paper, ..Self::default() }
    }

    /// The paper's method with the values of the authors' published code: one 0-2.4 m depth bin,
    /// k = 10, the plane raised 2 cm.
    pub fn paper_code() -> Self {
        Self { depth_bin_m: 2.4, max_depth_m: 2.4, kmeans_k: 10, plane_raise_m: 0.02, ..Self::paper() }
    }

    /// Checks every field, naming the first bad one as `detector.<field>`.
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("detector.fov_deg", self.fov_deg, 10.0, 179.0)?;
        check_range("detector.range_m", self.range_m, 1.0, 100.0)?;
        check_range("detector.min_range_m", self.min_range_m, 0.0, self.range_m - 0.5)?;
        check_range("detector.plane_raise_m", self.plane_raise_m, -1.0, 1.0)?;
        check_range("detector.depth_bin_m", self.depth_bin_m, 0.1, 100.0)?;
        // The paper pipeline sorts points into at most 64 depth bins (a fixed buffer).
        check_range(
            "detector.max_depth_m",
            self.max_depth_m,
            self.depth_bin_m.min(1.0),
            64.0 * self.depth_bin_m,
        )?;
        check_count("detector.kmeans_k", self.kmeans_k, 1, 64)?;
        check_count("detector.kmeans_iterations", self.kmeans_iterations, 1, 1000)?;
        check_range("detector.merge_distance_m", self.merge_distance_m, 0.01, 5.0)?;
        check_count("detector.ransac_iterations", self.ransac_iterations, 1, 1_000_000)?;
        check_range("detector.ransac_inlier_m", self.ransac_inlier_m, 0.001, 1.0)?;
        check_range("detector.min_span_m", self.min_span_m, 0.0, 50.0)?;
        check_range("detector.behind_m", self.behind_m, 0.0, 10.0)?;
        check_count("detector.end_min_points", self.end_min_points, 0, 10_000_000)?;
        check_count("detector.end_scans", self.end_scans, 1, 100_000)?;
        check_range("detector.lost_after_s", self.lost_after_s, 0.01, 3600.0)?;
        check_range("detector.max_speed_mps", self.max_speed_mps, 0.1, 100.0)?;
        check_range("detector.max_gap_s", self.max_gap_s, 0.01, 3600.0)?;
        check_range("detector.min_plant_height_m", self.min_plant_height_m, 0.0, 2.0)?;
        check_range("detector.spacing_min_m", self.spacing_min_m, 0.1, 5.0)?;
        check_range("detector.spacing_max_m", self.spacing_max_m, self.spacing_min_m + 0.05, 5.0)?;
        check_range("detector.heading_search_deg", self.heading_search_deg, 0.0, 45.0)?;
        check_range("detector.gate_fraction", self.gate_fraction, 0.05, 0.5)?;
        // A window as wide as the gate could never settle inside it.
        check_range("detector.core_fraction", self.core_fraction, 0.0, 0.9 * self.gate_fraction)?;
        check_range("detector.outer_core_fraction", self.outer_core_fraction, 0.0, 0.9 * self.gate_fraction)?;
        check_range("detector.map_bin_m", self.map_bin_m, 0.05, 5.0)?;
        check_count("detector.map_min_points", self.map_min_points, 1, 100_000)?;
        check_count("detector.map_capacity", self.map_capacity, 16, 1_000_000)?;
        check_range("detector.end_empty_m", self.end_empty_m, 0.1, 50.0)?;
        check_range("detector.end_trigger_m", self.end_trigger_m, -10.0, 10.0)?;
        // The levelling grid covers range_m ahead and on each side: at most 128 cells a side.
        check_range("detector.level_cell_m", self.level_cell_m, (self.range_m / 128.0).max(0.05), 5.0)?;
        check_range("detector.level_max_tilt_deg", self.level_max_tilt_deg, 0.0, 20.0)?;
        check_range("detector.level_time_constant_s", self.level_time_constant_s, 0.01, 60.0)?;
        check_count("detector.level_min_cells", self.level_min_cells, 3, 100_000)?;
        check_range("detector.shear_prior_m2", self.shear_prior_m2, 1e-3, 1e9)?;
        check_range("detector.shear_max_per_m", self.shear_max_per_m, 0.0, 1.0)?;
        check_range("detector.shear_deadband_per_m", self.shear_deadband_per_m, 0.0, 1.0)?;
        if self.planted_spacing_m != 0.0 {
            check_range(
                "detector.planted_spacing_m",
                self.planted_spacing_m,
                self.spacing_min_m,
                self.spacing_max_m,
            )?;
        }
        check_range("detector.planted_spacing_tolerance", self.planted_spacing_tolerance, 0.01, 1.0)?;
        check_range("detector.spacing_prior_weight", self.spacing_prior_weight, 0.0, 1e6)?;
        if self.spacing_prior_m != 0.0 {
            check_range(
                "detector.spacing_prior_m",
                self.spacing_prior_m,
                self.spacing_min_m,
                self.spacing_max_m,
            )?;
        }
        check_count("detector.start_confirmations", self.start_confirmations, 0, 1000)?;
        check_range("detector.start_row_contrast", self.start_row_contrast, 0.0, 2.0)?;
        check_range("detector.start_heading_tolerance_deg", self.start_heading_tolerance_deg, 0.01, 45.0)?;
        check_range("detector.start_offset_tolerance_m", self.start_offset_tolerance_m, 0.001, 1.0)?;
        check_range("detector.start_min_reach_m", self.start_min_reach_m, 0.0, self.range_m + 11.0)?;
        check_range("detector.shear_window_m", self.shear_window_m, 0.0, 10.0)?;
        check_range("detector.shear_test_min_per_m", self.shear_test_min_per_m, 0.0, 1.0)?;
        check_range("detector.shear_near_gap_m", self.shear_near_gap_m, 0.0, 10.0)?;
        check_range("detector.heading_prior_m2", self.heading_prior_m2, 0.0, 1e6)?;
        check_range("detector.clutter_voxel_m", self.clutter_voxel_m, 0.01, 1.0)?;
        check_count("detector.clutter_min_points", self.clutter_min_points, 0, 1000)?;
        check_range("detector.clutter_min_share", self.clutter_min_share, 0.0, 1.0)?;
        check_range("detector.deskew_sweep_start_deg", self.deskew_sweep_start_deg, -360.0, 360.0)?;
        check_range("detector.deskew_period_s", self.deskew_period_s, 0.01, 1.0)?;
        check_count("detector.register_window", self.register_window, 2, 60)?;
        check_range("detector.register_noise_m", self.register_noise_m, 0.0005, 0.1)?;
        check_range("detector.register_z", self.register_z, 0.5, 20.0)?;
        check_range("detector.register_end_fraction", self.register_end_fraction, 0.0, 1.0)?;
        Ok(())
    }
}

fn check_count(field: &str, value: usize, min: usize, max: usize) -> Result<(), ConfigError> {
    if value < min || value > max {
        return Err(ConfigError::invalid(field, format!("{value} is not in [{min}, {max}]")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid() {
        for c in [DetectorConfig::default(), DetectorConfig::paper(), DetectorConfig::paper_code()] {
            assert!(c.validate().is_ok(), "{c:?}");
        }
    }

    #[test]
    fn absurd_values_name_the_field() {
        let c = DetectorConfig { range_m: -1.0, ..DetectorConfig::default() };
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("detector.range_m"), "{e}");
        let c = DetectorConfig { kmeans_k: 0, ..DetectorConfig::paper() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.kmeans_k"));
        let c = DetectorConfig { depth_bin_m: 0.1, max_depth_m: 10.0, ..DetectorConfig::paper() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.max_depth_m"));
        let c = DetectorConfig { core_fraction: 0.3, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.core_fraction"));
        let c = DetectorConfig { outer_core_fraction: f64::NAN, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.outer_core_fraction"));
        let c = DetectorConfig { spacing_max_m: 0.2, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.spacing_max_m"));
        let c = DetectorConfig { range_m: 100.0, level_cell_m: 0.5, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.level_cell_m"));
        let c = DetectorConfig { planted_spacing_m: 3.0, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.planted_spacing_m"));
        let c = DetectorConfig { heading_prior_m2: -1.0, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.heading_prior_m2"));
        let c = DetectorConfig { planted_spacing_m: f64::NAN, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.planted_spacing_m"));
        let c = DetectorConfig { spacing_prior_m: 3.0, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.spacing_prior_m"));
        let c = DetectorConfig { spacing_prior_weight: f64::NAN, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.spacing_prior_weight"));
        let c = DetectorConfig { start_offset_tolerance_m: 0.0, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.start_offset_tolerance_m"));
        let c = DetectorConfig { level_time_constant_s: f64::NAN, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.level_time_constant_s"));
        let c = DetectorConfig { deskew_period_s: 0.0, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.deskew_period_s"));
        let c = DetectorConfig { deskew_sweep_start_deg: f64::NAN, ..DetectorConfig::default() };
        assert!(c.validate().unwrap_err().to_string().contains("detector.deskew_sweep_start_deg"));
    }

    #[test]
    fn toml_names_only_overrides() {
        let c: DetectorConfig = toml::from_str("mode = \"paper\"\nrange_m = 5.0").unwrap();
        assert_eq!(c.mode, DetectorMode::Paper);
        assert_eq!(c.range_m, 5.0);
        assert!(toml::from_str::<DetectorConfig>("nonsense = 1").is_err());
    }
}
