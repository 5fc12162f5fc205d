//! Canopy registration (default mode, `detector.register_enabled`, on by default): the sideways drift
//! of the odometry that the wheels and the gyro cannot sense, measured from the canopy itself.
//!
//! It sits between preprocessing and the lane pipeline ([`super::lanes`]). The lane pipeline keeps its
//! map of row centroids in `odom`, carried by the odometry, and a tilted LiDAR never sees the rows under
//! the robot: there the fit rests on centroids stored 1.5-4.5 m of driving ago. A slide the odometry
//! does not sense (wet soil on a side slope) moves the robot but not those centroids, so the fitted rows
//! at the robot follow the odometry, not the crop: a slide of 0.05 m per metre driven put the lane
//! 17 cm off in grown corn, 15 cm on average (`examples/slide_response.rs` in the simulator crate).
//! The gated centroids cannot tell: they are measured in gates around the prediction, and over a
//! closed canopy a windowed centroid follows its window.
//!
//! Registration measures the drift without any gate: every [`KEYFRAME_M`] of driving, the canopy's
//! lateral profile (height-squared weight per 5 mm across the rows, in nine bands of 0.25 m along
//! them, smoothed) is cross-correlated with the profile of the previous keyframe over the stretch
//! both see, in that keyframe's row frame. The lag of the peak is how far this scan's canopy sits
//! beside where the odometry puts it: the odometry's sideways drift since the keyframe. With the true
//! odometry the increments scatter about zero (±1.5 mm on the unit tests' synthetic canopy, about
//! ±1 cm on the weedy young soybean of soak seed 662, and leaning to one side where the canopy ends
//! inside the bands: the bands past a row end that the lane pipeline found are not compared, and
//! `register_end_fraction` also leaves out the emptier far bands when set: docs/faults.md). Under a
//! slide they lean to one side by the slide times the keyframe distance (a little less: the sensor
//! sees the plants from where it truly is, so their visible flanks move less than the plants).
//!
//! Only significant drift is applied: the increments of the last `register_window` keyframes are
//! summed (once there are at least [`MIN_TESTED`]), and when the sum lies more than `register_z`
//! standard errors from zero (the per-keyframe noise is `register_noise_m`) every increment of the
//! window not yet applied moves the correction at once.
//! Increments that leave the window unapplied were noise and are dropped, so the fault-free odometry is
//! left as it is. The correction is a translation of `odom` (the `nav` frame of the lane pipeline:
//! `nav = odom + correction`), across the rows; it never rotates it.

use std::collections::VecDeque;

use crate::geometry::{Mount, Point3, Pose2};

use super::config::DetectorConfig;
use super::deskew::Deskew;

/// Driving between two keyframes, m (the lane map's keyframe distance).
pub(crate) const KEYFRAME_M: f64 = 0.15;
/// Largest change of the row direction between two keyframes for a comparison, rad: past it the view
/// has swung (a turn), not drifted.
const MAX_TURN_RAD: f64 = 0.05;
/// Lateral bin of the profiles, m, and their half-width across the rows, m.
const BIN_M: f64 = 0.005;
const HALF_WIDTH_M: f64 = 2.5;
const BINS: usize = (2.0 * HALF_WIDTH_M / BIN_M) as usize;
/// Half-width of the triangular smoothing kernel, bins (1.5 cm: a row's crest is 5-20 cm wide).
const SMOOTH_BINS: usize = 3;
/// The bands along the rows, m ahead of the keyframe's `base_link`: the stretch every keyframe and the
/// next one both see (the view starts about 1.5 m ahead and ends near 4 m), cut in bands so that a
/// band the next scan does not see well (a gap, a missing sector) drops out alone.
const BAND_START_M: f64 = 1.9;
const BAND_M: f64 = 0.25;
const NBANDS: usize = 9;
/// Largest increment taken for drift, m: a slide of 0.25 m per metre over a 0.2 m keyframe.
const MAX_INCREMENT_M: f64 = 0.05;
/// Fewest increments in the window for its sum to be tested (fewer when `register_window` is
/// smaller): with two or three, the noise estimate rests on one or two differences, and with true
/// odometry under a closed canopy three increments of -4, -2 and -11 mm once passed as a drift. Four,
/// not a full window of 6: waiting for six let a wheel slide from the first metres of a lane take 3
/// plants (soak seed 8).
const MIN_TESTED: usize = 4;
/// Where the noise estimate of a lane registered from a standstill starts, in `register_noise_m`: 6 mm
/// by default, the increments' scatter with the true odometry (standard deviations of 4.9-7.3 mm by
/// crop over 20,000 keyframes of 144 soak runs without a slip patch). Starting from
/// `register_noise_m` itself, two increments of -13 and -14 mm 1.4 m into 20 m of grown soybean
/// passed as a drift, and the robot swung onto the correction (1.69 cm cross-track mean instead of
/// 1.35).
const FROM_REST_NOISE: f64 = 2.0;
/// Weight of a new increment in the running noise estimate (a memory of about 20 keyframes, 3 m).
const NOISE_GAIN: f64 = 0.05;
/// Lags searched, bins either side: 6 cm, the drift of 0.4 m per metre over a keyframe; and in the
/// refining pass, 1.5 cm.
const MAX_LAG_BINS: i64 = 12;
const REFINE_LAG_BINS: i64 = 3;
/// Lowest return registered, m above the canopy plane: the ground and stubble between the rows
/// carry no lateral structure.
const MIN_HEIGHT_M: f32 = 0.08;
/// Distance kept from the row end the lane pipeline found to the far edge of the last band compared,
/// m: one band.
const ROW_END_MARGIN_M: f64 = 0.25;
/// Least summed height-squared weight of a band's profile in both scans for it to be compared, m²:
/// about 50 canopy returns 0.3 m high.
const MIN_BAND_WEIGHT_M2: f64 = 1.0;
/// Least normalised correlation at the peak for a band's lag to count: a profile that does not look
/// like the last one (the canopy ended, a sector of the scan is missing) tells nothing.
const MIN_CORRELATION: f64 = 0.5;

/// One keyframe: where it was (the `nav` pose and the row direction there) and its bands' weights;
/// its profiles live in [`Register::key_profiles`].
#[derive(Debug, Clone, Copy)]
struct Keyframe {
    pose: Pose2,
    direction: f64,
    weights: [f64; NBANDS],
}

/// What registration did at the last scan, for diagnostics.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Drift {
    /// The correction `nav - odom`, m in `odom`.
    pub(crate) correction: [f64; 2],
    /// The drift the window holds per metre driven, m/m (positive: the robot slides to its left unseen
    /// by the odometry), while it is significant.
    pub(crate) slide_per_m: Option<f64>,
}

/// The registration stage: the last keyframe, the window of increments and the correction. Its
/// profile buffers (150 KB) are allocated at its first keyframe, so a detector that does not register
/// does not carry them.
#[derive(Debug, Clone)]
pub(crate) struct Register {
    key: Option<Keyframe>,
    key_profiles: Vec<Vec<f64>>,
    scratch: Vec<Vec<f64>>,
    smoothed: Vec<f64>,
    /// The scan's returns to register, `(x, y, h²)` in `base_link` (see [`Register::gather`]).
    points: Vec<[f64; 3]>,
    /// Increments of the last keyframes, m across the rows, the distance driven since the keyframe
    /// before each, m, and whether each has been applied.
    window: VecDeque<(f64, f64, bool)>,
    /// Increments that left the window unapplied, oldest first, at most `register_window` of them:
    /// where a drift the window finds significant began (see [`Register::push`]).
    lead: VecDeque<f64>,
    /// Running mean of half the squared difference of successive increments, m²: their noise, blind to
    /// a steady drift (which moves every increment alike). None until the first pair.
    noise2: Option<f64>,
    drift: Drift,
}

impl Register {
    pub(crate) fn new() -> Self {
        Self {
            key: None,
            key_profiles: Vec::new(),
            scratch: Vec::new(),
            smoothed: Vec::new(),
            points: Vec::new(),
            window: VecDeque::with_capacity(64),
            lead: VecDeque::with_capacity(64),
            noise2: None,
            drift: Drift::default(),
        }
    }

    /// Forgets the keyframe and the window (a new lane): the correction is kept, so `nav` stays
    /// continuous.
    pub(crate) fn reset(&mut self) {
        self.key = None;
        self.clear_window();
    }

    /// Forgets the increments not yet applied and the drift's rate: what follows is not compared with
    /// what went before.
    fn clear_window(&mut self) {
        self.window.clear();
        self.lead.clear();
        self.drift.slide_per_m = None;
    }

    /// The pose of `base_link` in `nav` for odometry pose `odom`.
    pub(crate) fn nav(&self, odom: &Pose2) -> Pose2 {
        let [dx, dy] = self.drift.correction;
        Pose2::new(odom.x + dx, odom.y + dy, odom.yaw)
    }

    pub(crate) fn drift(&self) -> Drift {
        self.drift
    }

    /// One scan: `canopy` points `(x, y, h)` in `base_link`, the odometry pose, the direction of the
    /// tracked rows in `nav` (none: no lane, nothing to register against), where the lane's canopy
    /// ends, `(x, y)` in `nav`, when the lane pipeline has found it, and the scan's motion skew with the
    /// sensor mount when the points still carry it. Returns the `nav` pose.
    pub(crate) fn step(
        &mut self,
        canopy: &[[f32; 3]],
        odom: &Pose2,
        direction: Option<f64>,
        row_end: Option<[f64; 2]>,
        skew: Option<(Deskew, &Mount)>,
        config: &DetectorConfig,
    ) -> Pose2 {
        let nav = self.nav(odom);
        let Some(direction) = direction.filter(|d| d.is_finite()) else {
            self.reset();
            return nav;
        };
        let due = self.key.as_ref().is_none_or(|k| (nav.x - k.pose.x).hypot(nav.y - k.pose.y) >= KEYFRAME_M);
        if !due {
            return nav;
        }
        self.gather(canopy, skew);
        let turned = self
            .key
            .as_ref()
            .is_some_and(|k| crate::geometry::wrap_angle(direction - k.direction).abs() > MAX_TURN_RAD);
        if let Some(key) = self.key.take().filter(|_| !turned) {
            let weights = self.fill(&nav, &key.pose, key.direction, 0.0);
            // A second pass on the residual, with the profile moved by the first estimate: one pass
            // reads a drift 10-20 % short (the parabola through a broad correlation peak), two within
            // 1-4 % (measured on the simulated fields, 15 mm increments).
            let end = config.register_end_fraction;
            let bands = bands_before(row_end, &key);
            let refined = self.compare(&key, weights, bands, MAX_LAG_BINS, end).and_then(|first| {
                let weights = self.fill(&nav, &key.pose, key.direction, first);
                self.compare(&key, weights, bands, REFINE_LAG_BINS, end).map(|rest| first + rest)
            });
            // A drift of more than the largest plausible slide over one keyframe is a view that changed
            // (a lane hypothesis that jumped, the canopy ending), not drift: it also empties the window.
            let refined = refined.filter(|s| s.abs() <= MAX_INCREMENT_M);
            if refined.is_none() {
                self.clear_window();
            }
            if let Some(shift) = refined {
                // The canopy sits `shift` to the left of where the odometry puts it: the robot is that
                // much further right than the odometry says.
                let driven = (nav.x - key.pose.x).hypot(nav.y - key.pose.y);
                self.push(-shift, driven, key.direction, config);
            }
        }
        let nav = self.nav(odom);
        let weights = self.fill(&nav, &nav, direction, 0.0);
        std::mem::swap(&mut self.key_profiles, &mut self.scratch);
        self.key = Some(Keyframe { pose: nav, direction, weights });
        nav
    }

    /// Keeps the canopy returns high enough to register, `(x, y, h²)` in `base_link` at the scan's
    /// stamp: the three profiles of a keyframe are filled from them.
    fn gather(&mut self, canopy: &[[f32; 3]], skew: Option<(Deskew, &Mount)>) {
        self.points.clear();
        let mount_yaw = skew.as_ref().map_or((0.0, 1.0), |(_, mount)| (mount.yaw_rad as f32).sin_cos());
        for q in canopy {
            // While the robot turns, the returns of a sweep are placed as if all fired at its stamp:
            // the view swings by ω·τ, 3 cm at 3 m while turning at 0.2 rad/s, which reads as drift
            // (measured: 10 mm increments instead of 5 on young soybean while following). Each
            // return's firing time comes from its bearing about the sensor (the bearing in the sensor
            // frame differs by a few degrees under its pitch: under a millisecond of the sweep).
            let q = match &skew {
                Some((d, mount)) => {
                    let (bx, by) = (q[0] - mount.x_m as f32, q[1] - mount.y_m as f32);
                    let (sy, cy) = mount_yaw;
                    d.apply(&Point3::new(cy * bx + sy * by, cy * by - sy * bx, 0.0), *q)
                }
                None => *q,
            };
            if q[2] >= MIN_HEIGHT_M {
                self.points.push([q[0] as f64, q[1] as f64, (q[2] as f64).powi(2)]);
            }
        }
    }

    /// Fills the scratch profiles with the gathered returns (in the `base_link` of `nav`) in the row
    /// frame at `frame` with rows along `direction`; returns each band's summed weight.
    fn fill(&mut self, nav: &Pose2, frame: &Pose2, direction: f64, v_shift_m: f64) -> [f64; NBANDS] {
        let mut weights = [0.0; NBANDS];
        self.scratch.resize_with(NBANDS, Vec::new);
        self.smoothed.resize(BINS, 0.0);
        for p in &mut self.scratch {
            p.resize(BINS, 0.0);
            p.iter_mut().for_each(|v| *v = 0.0);
        }
        let (s, c) = direction.sin_cos();
        let (ns, nc) = nav.yaw.sin_cos();
        for &[x, y, w] in &self.points {
            let (ox, oy) = (nav.x + nc * x - ns * y, nav.y + ns * x + nc * y);
            let (dx, dy) = (ox - frame.x, oy - frame.y);
            let (u, v) = (c * dx + s * dy, -s * dx + c * dy - v_shift_m);
            let b = (u - BAND_START_M) / BAND_M;
            if !(b >= 0.0 && b < NBANDS as f64) {
                continue;
            }
            let band = b as usize;
            let i = (v + HALF_WIDTH_M) / BIN_M;
            if i >= 0.0 && i < BINS as f64 {
                self.scratch[band][i as usize] += w;
                weights[band] += w;
            }
        }
        for band in 0..NBANDS {
            smooth(&self.scratch[band], &mut self.smoothed);
            std::mem::swap(&mut self.scratch[band], &mut self.smoothed);
        }
        weights
    }

    /// The lateral shift of the scratch profiles against the keyframe's, m (positive: this scan's canopy
    /// lies to the left of the keyframe's), the mean over the first `bands` bands that can be compared,
    /// up to the farthest band whose weight is at least `end_fraction` of the fullest band's: the bands
    /// past it hold where the canopy ends, and profiles of a canopy ending inside the bands lean to one
    /// side (increments of +1 to +2 cm a keyframe on the fault-free soak seed 662, where they scatter
    /// ±1 cm elsewhere, applied as a 7 cm drift 3 m before the row end).
    fn compare(
        &self,
        key: &Keyframe,
        weights: [f64; NBANDS],
        bands: usize,
        max_lag: i64,
        end_fraction: f64,
    ) -> Option<f64> {
        let (mut sum, mut n) = (0.0, 0.0);
        // A band's weight is the lesser of the two scans'. The bands run away from the robot: the
        // canopy ends (a row end) past the farthest one that is not much emptier than the fullest.
        let least: [f64; NBANDS] = std::array::from_fn(|b| weights[b].min(key.weights[b]));
        let fullest = least.iter().copied().fold(0.0, f64::max);
        let compared =
            least.iter().rposition(|&w| w >= end_fraction * fullest).map_or(0, |b| b + 1).min(bands);
        let bands = weights.iter().zip(&key.weights).zip(self.key_profiles.iter().zip(&self.scratch));
        for ((&weight, &key_weight), (key_profile, profile)) in bands.take(compared) {
            if weight < MIN_BAND_WEIGHT_M2 || key_weight < MIN_BAND_WEIGHT_M2 {
                continue;
            }
            if let Some((lag, r)) = peak_lag(key_profile, profile, max_lag) {
                sum += r * lag * BIN_M;
                n += r;
            }
        }
        (n > 0.0).then(|| sum / n)
    }

    /// Adds an increment (m along the left normal of rows running along `direction`) to the window and,
    /// once it holds [`MIN_TESTED`] increments, applies its unapplied ones when their sum is significant.
    fn push(&mut self, increment: f64, driven_m: f64, direction: f64, config: &DetectorConfig) {
        if let Some(&(last, _, _)) = self.window.back() {
            let d2 = 0.5 * (increment - last).powi(2);
            // After a metre of following, the first pair is a fair start for the mean. Registering
            // from a standstill, it comes from the robot setting off: a first pair of 11 and -9 mm
            // (soak seed 322) held the test deaf to a slide 5 m later, the mean still twice the
            // noise there. The mean then starts from the scatter the increments show over the
            // canopies (see [`FROM_REST_NOISE`]).
            let start = if config.register_from_rest {
                (FROM_REST_NOISE * config.register_noise_m).powi(2)
            } else {
                d2
            };
            let n = self.noise2.unwrap_or(start);
            self.noise2 = Some(n + NOISE_GAIN * (d2 - n));
        }
        self.window.push_back((increment, driven_m, false));
        while self.window.len() > config.register_window {
            match self.window.pop_front() {
                Some((left, _, false)) => self.lead.push_back(left),
                // The lead runs back from the window unbroken: past an applied increment it is over.
                _ => self.lead.clear(),
            }
            if self.lead.len() > config.register_window {
                self.lead.pop_front();
            }
        }
        let n = self.window.len();
        let (total, driven) = self.window.iter().fold((0.0, 0.0), |(t, d), e| (t + e.0, d + e.1));
        let sigma = self.noise2.map_or(config.register_noise_m, |n| n.sqrt().max(config.register_noise_m));
        if n < MIN_TESTED.min(config.register_window)
            || total.abs() <= config.register_z * sigma * (n as f64).sqrt()
        {
            self.drift.slide_per_m = None;
            return;
        }
        self.drift.slide_per_m = (driven > 0.0).then(|| total / driven);
        let onset = if config.register_from_onset { self.lead_in(total, n) } else { 0.0 };
        self.lead.clear();
        let unapplied: f64 = onset
            + self
                .window
                .iter_mut()
                .filter(|e| !e.2)
                .map(|e| {
                    e.2 = true;
                    e.0
                })
                .sum::<f64>();
        let (s, c) = direction.sin_cos();
        self.drift.correction[0] -= s * unapplied;
        self.drift.correction[1] += c * unapplied;
    }

    /// The drift of the lead-in to a window of `n` increments summing to `total` that is significant:
    /// the sum of the newest increments of the lead that makes the whole the most significant
    /// (`|sum| / √count` largest, the likeliest onset of a steady drift in noise of one scatter),
    /// or 0 when none adds to it. A slide reaches significance some keyframes after it starts, and
    /// its first increments have left the window unapplied by then: soak seed 777 (a 0.12 m/m slide
    /// in young soybean) read -10, -12 and -6 mm before its window passed, and dropping them left the
    /// lane 2.7 cm off after the correction.
    fn lead_in(&self, total: f64, n: usize) -> f64 {
        let score = |sum: f64, count: usize| if sum * total > 0.0 { sum * sum / count as f64 } else { 0.0 };
        let (mut best, mut best_score, mut sum) = (0.0, score(total, n), total);
        for (k, increment) in self.lead.iter().rev().enumerate() {
            sum += increment;
            let s = score(sum, n + k + 1);
            if s > best_score {
                (best, best_score) = (sum - total, s);
            }
        }
        best
    }
}

/// How many bands of keyframe `key` lie wholly before the row end `row_end` (`(x, y)` in `nav`) with
/// [`ROW_END_MARGIN_M`] to spare: the profiles of the band where the canopy ends lean to one side,
/// the plants there seen from a changing distance (increments of -9, -9 and -5 mm with the true
/// odometry 2.5-3 m before a young-corn row end, summed into a 2.5 cm correction that the robot
/// followed off the centre line: the recovery start on 12 m of rows, registered from its first
/// keyframe, session 38). All of them when the lane pipeline has not found the end.
fn bands_before(row_end: Option<[f64; 2]>, key: &Keyframe) -> usize {
    let Some([ex, ey]) = row_end else { return NBANDS };
    let (s, c) = key.direction.sin_cos();
    let ahead = c * (ex - key.pose.x) + s * (ey - key.pose.y) - ROW_END_MARGIN_M - BAND_START_M;
    if ahead.is_nan() || ahead <= 0.0 {
        return 0;
    }
    ((ahead / BAND_M) as usize).min(NBANDS)
}

/// `out` = `profile` smoothed with a triangular kernel of half-width [`SMOOTH_BINS`], the terms past
/// the profile's ends left out. Written tap by tap over the whole profile (each bin still sums its
/// taps in order), so that the compiler can vectorise it.
fn smooth(profile: &[f64], out: &mut [f64]) {
    let n = profile.len().min(out.len());
    let (profile, out) = (&profile[..n], &mut out[..n]);
    out.iter_mut().for_each(|o| *o = 0.0);
    let k = SMOOTH_BINS;
    for tap in 0..=2 * k {
        let weight = (k + 1).abs_diff(tap.abs_diff(k)) as f64;
        // Bin i takes profile[i + tap - k], for the bins where that lies in the profile.
        let (first_out, first_in) = if tap < k { (k - tap, 0) } else { (0, tap - k) };
        let len = n.saturating_sub(first_out.max(first_in));
        for (o, &v) in out[first_out..first_out + len].iter_mut().zip(&profile[first_in..first_in + len]) {
            *o += weight * v;
        }
    }
}

/// Profiles [`peak_lag`] can compare: at most [`BINS`] bins, at most 31 lags either side.
const MAX_PROFILE: usize = BINS;
const MAX_LAGS: usize = 63;

/// The lag (bins, sub-bin by a parabola through the peak) at which `b` best matches `a`, both demeaned,
/// within `±max_lag`; `None` at the edge of the search, when the match is poor, or for profiles
/// longer than [`MAX_PROFILE`].
fn peak_lag(a: &[f64], b: &[f64], max_lag: i64) -> Option<(f64, f64)> {
    let n = a.len().min(b.len());
    let lags = usize::try_from(2 * max_lag + 1).ok().filter(|&l| l <= MAX_LAGS)?;
    let half = lags / 2;
    if n > MAX_PROFILE || n == 0 {
        return None;
    }
    let (a, b) = (&a[..n], &b[..n]);
    let ma = a.iter().sum::<f64>() / n as f64;
    let mb = b.iter().sum::<f64>() / n as f64;
    // `b` demeaned and padded with `half` zeros at each end: every lag then runs over all of `a`, the
    // terms past `b`'s ends adding zero, and the lags accumulate side by side (each in the order of
    // `a`), which the compiler vectorises.
    let mut padded = [0.0f64; MAX_PROFILE + MAX_LAGS];
    for (p, &v) in padded[half..half + n].iter_mut().zip(b) {
        *p = v - mb;
    }
    let mut cc = [0.0f64; MAX_LAGS];
    let cc = &mut cc[..lags];
    for (i, &va) in a.iter().enumerate() {
        let da = va - ma;
        for (slot, &db) in cc.iter_mut().zip(&padded[i..i + lags]) {
            *slot += da * db;
        }
    }
    let (best, &peak) = cc.iter().enumerate().max_by(|x, y| x.1.total_cmp(y.1))?;
    if best == 0 || best + 1 == lags {
        return None;
    }
    let energy = |p: &[f64], m: f64| p.iter().map(|v| (v - m) * (v - m)).sum::<f64>();
    let norm = (energy(a, ma) * energy(b, mb)).sqrt();
    // (`norm` is 0 for a flat profile and NaN never: the profiles are sums of finite weights.)
    if norm <= 0.0 || peak / norm < MIN_CORRELATION {
        return None;
    }
    let (ym, yp) = (cc[best - 1], cc[best + 1]);
    let den = ym - 2.0 * peak + yp;
    let sub = if den < 0.0 { 0.5 * (ym - yp) / den } else { 0.0 };
    Some((best as f64 - half as f64 + sub, peak / norm))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Canopy returns `(x, y, h)` in the `base_link` of a robot truly at `truth` (field frame), over
    /// straight rows along the field's x, 0.75 m apart with the robot's lane centre at y = 0: a grid of
    /// returns every 2 cm from 1.5 to 4.2 m ahead, each as high as the canopy there (a crest 0.4 m high
    /// over each row, 0.15 m wide, and plants every 0.2 m along it).
    fn canopy(truth: &Pose2) -> Vec<[f32; 3]> {
        let mut out = Vec::new();
        for i in 0..135 {
            for k in 0..250 {
                // Each line of returns is offset by a golden-ratio share of the grid, as a sweep's
                // returns are not aligned from ring to ring: aligned, the profile is a 2 cm comb.
                let offset = 0.02 * (0.618_034 * i as f64).fract();
                let (x, y) = (1.5 + 0.02 * i as f64, -2.5 + 0.02 * k as f64 + offset);
                let (fx, fy) = truth.transform_point(x, y);
                let across = (fy / 0.75 - 0.5 - (fy / 0.75 - 0.5).round()) * 0.75;
                let along = ((fx / 0.2).fract() - 0.5).abs();
                let h = 0.4 * (-(across / 0.15).powi(2)).exp() * (1.0 - 0.3 * along);
                if h > 0.05 {
                    out.push([x as f32, y as f32, h as f32]);
                }
            }
        }
        out
    }

    /// Drives 6 m down the lane centre in 5 cm steps, the odometry drifting sideways by `slide` m per
    /// metre from 1 m on; returns the largest error of the `nav` pose across the rows after `settle_m`
    /// and the correction at the end.
    fn drive(slide: f64, settle_m: f64) -> (f64, [f64; 2]) {
        let config = DetectorConfig { register_enabled: true, ..DetectorConfig::default() };
        let mut register = Register::new();
        let mut worst: f64 = 0.0;
        for step in 0..120 {
            let x = 0.05 * step as f64;
            let truth = Pose2::new(x, 0.0, 0.0);
            let odom = Pose2::new(x, slide * (x - 1.0).max(0.0), 0.0);
            let nav = register.step(&canopy(&truth), &odom, Some(0.0), None, None, &config);
            if x >= settle_m {
                worst = worst.max(nav.y.abs());
            }
        }
        (worst, register.drift().correction)
    }

    #[test]
    fn true_odometry_is_left_as_it_is() {
        let (worst, correction) = drive(0.0, 0.0);
        assert_eq!(worst, 0.0);
        assert_eq!(correction, [0.0, 0.0]);
    }

    #[test]
    fn a_sideways_drift_is_taken_out_of_the_nav_pose() {
        // 0.1 m per metre: 0.5 m of drift over the run. After the window has seen it (1 m), `nav` stays
        // within 1 cm of the truth (a keyframe's 15 mm of drift is taken out when it is measured).
        let (worst, correction) = drive(0.1, 2.0);
        assert!(worst < 0.01, "nav off the truth by {worst} m");
        assert!((correction[1] + 0.5).abs() < 0.03, "{correction:?}");
    }

    #[test]
    fn a_drift_under_the_noise_is_not_applied() {
        // 2 mm per metre: 0.3 mm per keyframe, far under the 3 sigma of the test.
        let (_, correction) = drive(0.002, 0.0);
        assert_eq!(correction, [0.0, 0.0]);
    }

    #[test]
    fn three_increments_are_never_tested_for_drift() {
        // The increments true odometry gave under a closed canopy (docs: `MIN_TESTED`): their sum,
        // 16.7 mm, passed 3 sigma of a noise estimate made of one difference. Only a fourth increment
        // lets the window be tested, and with it the sum is no longer significant.
        let config = DetectorConfig { register_enabled: true, ..DetectorConfig::default() };
        let mut register = Register::new();
        for increment in [0.0036, 0.0023, 0.0108, -0.0045] {
            register.push(increment, 0.15, 0.0, &config);
            assert_eq!(register.drift().correction, [0.0, 0.0], "{increment}");
        }
        // Four increments of a true slide are applied: 4 x 12 mm against 3 x 3 mm x 2.
        let mut register = Register::new();
        for _ in 0..3 {
            register.push(0.012, 0.15, 0.0, &config);
        }
        assert_eq!(register.drift().correction, [0.0, 0.0]);
        register.push(0.012, 0.15, 0.0, &config);
        assert!((register.drift().correction[1] - 0.048).abs() < 1e-12, "{:?}", register.drift());
    }

    #[test]
    fn one_noisy_pair_of_increments_does_not_deafen_the_test() {
        // A run's first two keyframes read 11.4 and -9.1 mm (soak seed 322), then the odometry was
        // true for 4.5 m (±1 mm), then the wheels slid 8 cm per metre (12 mm a keyframe). Registering
        // from a standstill, the noise estimate starts from the increments' usual scatter
        // ([`FROM_REST_NOISE`]), so the slide is applied at its third keyframe; started from the
        // first pair (after a metre of following, the default), the estimate still held that pair
        // and the test waited for a fourth.
        let slide_applied_after = |register_from_rest| {
            let config =
                DetectorConfig { register_enabled: true, register_from_rest, ..DetectorConfig::default() };
            let mut register = Register::new();
            register.push(0.0114, 0.15, 0.0, &config);
            register.push(-0.0091, 0.15, 0.0, &config);
            for k in 0..30 {
                register.push(if k % 2 == 0 { 0.001 } else { -0.001 }, 0.15, 0.0, &config);
            }
            assert_eq!(register.drift().slide_per_m, None);
            (1..=6).find(|_| {
                register.push(0.012, 0.15, 0.0, &config);
                register.drift().slide_per_m.is_some()
            })
        };
        assert_eq!(slide_applied_after(true), Some(3));
        assert_eq!(slide_applied_after(false), Some(4));
    }

    #[test]
    fn a_slide_is_applied_back_to_where_it_began() {
        // Three metres of increments scattering ±5 mm, then a slide of 7 mm a keyframe: the window of
        // six passes the test at the slide's ninth keyframe, when its first three have left it (soak
        // seed 777 read -10, -11.5 and -5.8 mm before its window passed). Applied from its onset, the
        // correction holds them too, and the last increment of the scatter before it, which leans the
        // same way (-5 mm); without, they are dropped as noise.
        let applied = |register_from_onset| {
            let config =
                DetectorConfig { register_enabled: true, register_from_onset, ..DetectorConfig::default() };
            let mut register = Register::new();
            for k in 0..20 {
                register.push(if k % 2 == 0 { 0.005 } else { -0.005 }, 0.15, 0.0, &config);
            }
            for k in 1..=8 {
                register.push(-0.007, 0.15, 0.0, &config);
                assert_eq!(register.drift().correction, [0.0, 0.0], "slide keyframe {k}");
            }
            register.push(-0.007, 0.15, 0.0, &config);
            register.drift().correction[1]
        };
        assert!((applied(false) + 0.042).abs() < 1e-12, "{}", applied(false));
        assert!((applied(true) + 0.068).abs() < 1e-12, "{}", applied(true));
    }

    #[test]
    fn noise_before_a_drift_is_not_applied_with_it() {
        // Increments of +3 and -5 mm by turns, then a slide of 12 mm a keyframe: the window passes at
        // the slide's fourth keyframe, holding +3 and -5 mm before it. The lead-in before those (three
        // of each, -6 mm in all) leans against the slide and makes it no more significant: nothing of
        // it is applied.
        let config =
            DetectorConfig { register_enabled: true, register_from_onset: true, ..DetectorConfig::default() };
        let mut register = Register::new();
        for k in 0..12 {
            register.push(if k % 2 == 0 { 0.003 } else { -0.005 }, 0.15, 0.0, &config);
        }
        for k in 1..=3 {
            register.push(0.012, 0.15, 0.0, &config);
            assert_eq!(register.drift().correction, [0.0, 0.0], "slide keyframe {k}");
        }
        register.push(0.012, 0.15, 0.0, &config);
        let correction = register.drift().correction[1];
        assert!((correction - 0.046).abs() < 1e-12, "{correction}");
    }

    #[test]
    fn a_turn_between_keyframes_compares_nothing() {
        let config = DetectorConfig { register_enabled: true, ..DetectorConfig::default() };
        let mut register = Register::new();
        for step in 0..40 {
            let x = 0.05 * step as f64;
            let truth = Pose2::new(x, 0.0, 0.0);
            // The odometry drifts by 5 cm a keyframe, but the rows' direction swings by 0.1 rad each
            // keyframe: every comparison is refused.
            let odom = Pose2::new(x, 0.3 * x, 0.0);
            register.step(&canopy(&truth), &odom, Some(0.1 * (step / 3) as f64), None, None, &config);
        }
        assert_eq!(register.drift().correction, [0.0, 0.0]);
    }

    #[test]
    fn a_band_where_the_canopy_ends_is_left_out() {
        // Six full bands agree on no drift; the seventh holds the canopy's last plants, 20 % as heavy,
        // and its profile leans 3 cm to the left; the last two are empty.
        let crest = |shift: f64| -> Vec<f64> {
            (0..BINS).map(|i| (-((i as f64 - 500.0 - shift) / 8.0).powi(2)).exp()).collect()
        };
        let mut register = Register::new();
        let mut weights = [0.0; NBANDS];
        for (band, weight) in weights.iter_mut().enumerate() {
            let (band_weight, shift) = match band {
                0..6 => (10.0, 0.0),
                6 => (2.0, 6.0),
                _ => (0.0, 0.0),
            };
            *weight = band_weight;
            register.key_profiles.push(crest(0.0));
            register.scratch.push(crest(shift));
        }
        let key = Keyframe { pose: Pose2::new(0.0, 0.0, 0.0), direction: 0.0, weights };
        let all = register.compare(&key, weights, NBANDS, MAX_LAG_BINS, 0.0).expect("bands to compare");
        assert!(all > 0.003, "the leaning band counts when every band is compared: {all}");
        let up_to_end = register.compare(&key, weights, NBANDS, MAX_LAG_BINS, 0.3).expect("bands to compare");
        assert!(up_to_end.abs() < 1e-9, "{up_to_end}");
    }

    #[test]
    fn the_bands_past_the_row_end_the_lanes_found_are_left_out() {
        // The lanes found the canopy's end 3 m ahead of the keyframe, along its rows: with a band to
        // spare, the bands up to 2.75 m ahead are compared (the first three: 1.9-2.65 m). The fourth
        // holds the end and leans 3 cm to the left.
        let direction = 0.3_f64;
        let pose = Pose2::new(1.0, 2.0, direction + 0.05);
        let ahead = |d: f64| [pose.x + d * direction.cos(), pose.y + d * direction.sin()];
        let crest = |shift: f64| -> Vec<f64> {
            (0..BINS).map(|i| (-((i as f64 - 500.0 - shift) / 8.0).powi(2)).exp()).collect()
        };
        let mut register = Register::new();
        for band in 0..NBANDS {
            register.key_profiles.push(crest(0.0));
            register.scratch.push(crest(if band == 3 { 6.0 } else { 0.0 }));
        }
        let weights = [10.0; NBANDS];
        let key = Keyframe { pose, direction, weights };
        assert_eq!(bands_before(None, &key), NBANDS, "no end found: every band");
        assert_eq!(bands_before(Some(ahead(3.0)), &key), 3);
        assert_eq!(bands_before(Some(ahead(2.3)), &key), 0, "the end inside the first band");
        assert_eq!(bands_before(Some(ahead(-1.0)), &key), 0, "the end behind the keyframe");
        assert_eq!(bands_before(Some(ahead(40.0)), &key), NBANDS);
        assert_eq!(bands_before(Some([f64::NAN, 0.0]), &key), 0, "a non-finite end compares nothing");
        let all = register.compare(&key, weights, NBANDS, MAX_LAG_BINS, 0.0).expect("bands to compare");
        assert!(all > 0.002, "the band holding the end leans: {all}");
        let bands = bands_before(Some(ahead(3.0)), &key);
        let before_end = register.compare(&key, weights, bands, MAX_LAG_BINS, 0.0).expect("bands to compare");
        assert!(before_end.abs() < 1e-9, "{before_end}");
        assert_eq!(register.compare(&key, weights, 0, MAX_LAG_BINS, 0.0), None, "no band: no increment");
    }

    #[test]
    fn peak_lag_finds_a_shift_between_bins() {
        let a: Vec<f64> = (0..400).map(|i| (-((i as f64 - 200.0) / 12.0).powi(2)).exp()).collect();
        let b: Vec<f64> = (0..400).map(|i| (-((i as f64 - 203.4) / 12.0).powi(2)).exp()).collect();
        let (lag, r) = peak_lag(&a, &b, 12).expect("a peak");
        assert!((lag - 3.4).abs() < 0.2, "{lag}");
        assert!(r > 0.9, "{r}");
        assert!(peak_lag(&a, &b, 2).is_none(), "a peak at the edge of the search is no peak");
    }
}
