//! The start-up search of [`Lanes`](super::Lanes): with no lane tracked, one scan's canopy gives the
//! rows' heading (the one that makes the lateral histogram of canopy points sharpest), their spacing
//! (the histogram's autocorrelation, or the canopy's upper envelope under a closed canopy) and their
//! phase (the circular mean), and so a first lane hypothesis in `base_link`. See [`Lanes::search`].

use super::*;

/// Fewest canopy points for the start-up search, and the weakest normalised autocorrelation peak
/// accepted as a row pattern.
const MIN_SEARCH_POINTS: usize = 30;
const MIN_PERIODICITY: f64 = 0.15;

/// Distance from the robot, in canopy periods, within which the gap between a two-crest canopy's
/// crests nearest it is its lane centre without asking the ground (see [`Lanes::two_crest_centre`]):
/// a quarter period, an eighth of a spacing, 9 cm at 0.75 m rows, beyond the soak's ±6 cm starts.
const NEAR_GAP: f64 = 0.25;

/// Fewest ground returns (cropped points below the canopy plane) for the start-up search to consult
/// them, and the ratio of their autocorrelation at one spacing to that at two spacings below which the
/// ground is taken to repeat only every second canopy period (see [`Lanes::search`]).
const MIN_GROUND_POINTS: f64 = 200.0;
const GROUND_HALF_PERIOD_RATIO: f64 = 0.5;

/// Largest distance of the lane centre from the robot for a start-up hypothesis, in row spacings: a
/// wider one puts the robot's centre on a row (within a twentieth of a spacing). Not tighter: a robot
/// may start well off its lane centre (the `recovery` runs start 0.4 spacings off).
const MAX_START_OFFSET: f64 = 0.45;

/// Fewest pairs of canopy bins (2 cm each) for the envelope's autocorrelation at a lag to count: half a
/// metre of canopy seen at both ends of the lag.
const MIN_ENVELOPE_PAIRS: usize = 25;

/// Largest relative difference between the canopy density's and the envelope's periods for the two to
/// be taken as agreeing (see [`Lanes::search`]).
const PERIODS_AGREE: f64 = 0.15;

/// Share of the lateral bins between the outermost canopy that must hold canopy for the canopy to
/// count as closed (measured on the soak's fields: 0.95-1.0 grown, 0.5-0.75 young).
const CLOSED_CANOPY_SHARE: f64 = 0.85;

/// Length (m) and number of the along-x slices of the envelope, from `X_LO_M` on; farther points go in
/// the last slice.
const ENVELOPE_SLICE_M: f64 = 0.5;

/// Distance driven (odometry) within which the robot still stands where it was set down, m: the
/// start-up search there asks the canopy to run along the rows (`DetectorConfig::start_row_contrast`).
const SET_DOWN_M: f64 = 0.1;

/// Reach of the view (`base_link` x, m) whose canopy must run along a start-up lattice's rows: the
/// stretch the robot drives into first (the default `start_min_reach_m` of the start-up
/// confirmation). A weed patch farther ahead is met while tracking, where the fit's gates hold it off.
const NEAR_VIEW_M: f64 = 3.0;

/// Largest share of the cropped returns that are canopy for the ground to show between the rows: the
/// soak's young fields measured 0.03-0.26 at their start, 0.18-0.40 with tall weeds in view, its grown
/// ones 0.49-0.88 (0.32 with every row missing over half the view).
const OPEN_CANOPY_RETURNS: f64 = 0.45;

/// Fewest returns in a lateral bin for its ground share to count.
const MIN_BIN_RETURNS: f64 = 3.0;

impl Lanes {
    /// Start-up search for heading, spacing and phase from one scan's canopy (`cropped` gives the
    /// ground returns).
    ///
    /// A grown canopy can repeat twice per row spacing: leaves arching into the inter-row make two
    /// crests per spacing, and the canopy alone then cannot tell them from rows at half the spacing (a
    /// common 0.38 m soybean spacing looks the same). The ground breaks the tie: where it shows through
    /// differs between the row and the inter-row, so its share of the returns repeats once per true
    /// spacing. When it repeats at about twice the canopy's period and not at the period itself, there
    /// are two crests per row, and the canopy's upper envelope tells whether the lane centre is a
    /// crest or a gap between crests (see [`two_crest_lane_centre`]); with one crest per row it is the
    /// gap between crests. Of those, the search takes the one nearest the robot: it assumes the robot
    /// starts within a quarter spacing of its lane centre (between its two rows), and finds nothing
    /// when the nearest one is more than [`MAX_START_OFFSET`] spacings away or the sharpest heading is
    /// at the edge of the search. When the planted spacing is known, it settles the tie instead of the
    /// ground (see [`Lanes::nearest_planted`]), and a lattice too far from it is no lane. Where the
    /// robot was set down over an open canopy, a lattice whose rows the canopy ahead does not run
    /// along is no lane either (see [`Lanes::lane_contrast`], `DetectorConfig::start_row_contrast`).
    pub(super) fn search(
        &mut self,
        canopy: &[[f32; 3]],
        cropped: &[[f32; 3]],
        config: &DetectorConfig,
    ) -> Option<Lane> {
        if canopy.len() < MIN_SEARCH_POINTS {
            return None;
        }
        let stride = (canopy.len() / 3000).max(1);
        let steps = config.heading_search_deg.round() as i32;
        let mut best = (f64::NEG_INFINITY, 0.0, 0);
        for k in -steps..=steps {
            let a = (k as f64).to_radians().tan();
            self.fill_hist(canopy, a, stride);
            let score: f64 = self.hist.iter().map(|c| c * c).sum();
            if score > best.0 {
                best = (score, a, k);
            }
        }
        if steps > 0 && best.2.abs() == steps {
            // The sharpest heading at the edge of the range is no peak: the rows lie beyond the search,
            // or (under a closed canopy, soak seed 92) no heading is sharper than another and the edge
            // won by noise. Either way there is no heading to report.
            return None;
        }
        let a = best.1;
        self.fill_hist(canopy, a, 1);
        let density = spacing(&mut self.hist, config);
        // Only a closed canopy has an envelope with one crest per row; an open one is canopy over the
        // rows and nothing between, which the density already shows.
        let crest = (self.fill_envelope(canopy, a) >= CLOSED_CANOPY_SHARE)
            .then(|| envelope_spacing(&self.envelope, &self.filled, config))
            .flatten();
        let lane = match (density, crest) {
            _ if config.planted_spacing_m > 0.0 => {
                self.nearest_planted(a, density, crest, canopy, cropped, config)?
            }
            (Some(s), Some(e)) if (e - s).abs() > PERIODS_AGREE * s => {
                // The density and the envelope disagree: the envelope's crests are the plants' tops,
                // one per row, wherever the leaves spread (see the method's docs).
                let o = circular_mean(&self.envelope, e) + 0.5 * e;
                Lane { o, a, b: 0.0, s: e, crests: 1.0 }
            }
            (Some(s), _) => {
                let ground_points = self.fill_ground(canopy, cropped, a);
                if ground_repeats_every_other_crest(&self.ground, ground_points, s, config) {
                    // The canopy's own period and phase, measured over every crest in view (the
                    // envelope was filled above at this heading): the ground only tells that there
                    // are two crests per row (its period, found within ±20 % and mostly from the
                    // robot's own inter-row, read 0.82 m for 0.73 m rows in soak seed 1390).
                    let o = two_crest_lane_centre(&self.hist, &self.envelope, s);
                    Lane { o, a, b: 0.0, s, crests: 2.0 }
                } else {
                    // The lane centre lies between two canopy crests; of those gaps the one nearest
                    // the robot (`normalised` below).
                    Lane { o: circular_mean(&self.hist, s) + 0.5 * s, a, b: 0.0, s, crests: 1.0 }
                }
            }
            (None, Some(e)) => {
                let o = circular_mean(&self.envelope, e) + 0.5 * e;
                Lane { o, a, b: 0.0, s: e, crests: 1.0 }
            }
            (None, None) => return None,
        }
        .normalised();
        // A lattice whose nearest gap is not under the robot is the wrong one: a robot standing among
        // the plants has its centre between two rows, and tall weeds in every inter-row make a second
        // lattice half a spacing off the crop's (soak seed 451: the lane centre was put on a row).
        let centred = lane.o.abs() <= MAX_START_OFFSET * lane.spacing_m();
        // Where the robot was set down, the canopy of an open crop must run along the lattice's rows
        // in the view ahead: tall weeds in every inter-row make lattices of their own that wander from
        // scan to scan (soak seeds 31, 451, 596, 837, 1641, 1951 started on one and ran over plants).
        // Waiting is safe; a robot that has moved has followed rows, and its later searches are
        // bounded by the blind distance.
        let ground_shows = (canopy.len() as f64) < OPEN_CANOPY_RETURNS * cropped.len() as f64;
        let runs_along = !ground_shows
            || self.odometer_m > SET_DOWN_M
            || config.start_row_contrast <= 0.0
            || self.lane_contrast(&lane, NEAR_VIEW_M) >= config.start_row_contrast;
        (centred && runs_along && lane.is_sane(config)).then_some(lane)
    }

    /// The start-up lane when the planted spacing is known: of the canopy density's period with one or
    /// two crests per row and the envelope's period, the one whose row spacing is nearest the planted
    /// one. The ground's period is not consulted: it only breaks the one-or-two-crests tie, which the
    /// planted spacing breaks for sure (in grown corn the ground, seen mostly in the robot's own
    /// inter-row, read as repeating every second row and doubled the spacing: soak seeds 439, 75).
    /// With two crests per row, the gaps between crests alternate between the inter-rows and the rows
    /// themselves (leaves arching either side of a row dip over its stems): see
    /// [`Lanes::two_crest_centre`] for which is the lane's.
    fn nearest_planted(
        &mut self,
        a: f64,
        density: Option<f64>,
        crest: Option<f64>,
        canopy: &[[f32; 3]],
        cropped: &[[f32; 3]],
        config: &DetectorConfig,
    ) -> Option<Lane> {
        let off = |spacing_m: f64| (spacing_m - config.planted_spacing_m).abs();
        let from_density = density.map(|s| {
            // The lane centre lies between two canopy crests; of those gaps the one nearest the robot.
            let o =
                Lane { o: circular_mean(&self.hist, s) + 0.5 * s, a, b: 0.0, s, crests: 1.0 }.normalised().o;
            if off(2.0 * s) < off(s) {
                Lane { o: self.two_crest_centre(o, s, a, canopy, cropped), a, b: 0.0, s, crests: 2.0 }
            } else {
                Lane { o, a, b: 0.0, s, crests: 1.0 }
            }
        });
        let from_envelope = crest.map(|e| Lane {
            o: circular_mean(&self.envelope, e) + 0.5 * e,
            a,
            b: 0.0,
            s: e,
            crests: 1.0,
        });
        from_density
            .into_iter()
            .chain(from_envelope)
            .min_by(|l, m| off(l.spacing_m()).total_cmp(&off(m.spacing_m())))
    }

    /// The lane centre of a canopy with two crests per row spacing (canopy period `s`, heading slope
    /// `a`), from the gap `o` between crests nearest the robot: the gaps alternate between the
    /// inter-rows and the rows themselves (leaves arching either side of a row dip over its stems). A
    /// robot within [`NEAR_GAP`] periods of `o` stands in that gap's lane (the soak starts within 6 cm of
    /// the centre line). Farther off, which gap is nearer is a coin toss (soak seed 125 re-entered 14 cm
    /// off its lane centre, took the gap over the row half a spacing off and ran over 117 plants), so
    /// the ground settles it: of `o` and `o + s`, the gap nearer where its share of the returns peaks
    /// once per spacing (in the simulated grown canopies the ground shows through in the inter-row).
    /// With too few ground returns to say, `o`.
    fn two_crest_centre(&mut self, o: f64, s: f64, a: f64, canopy: &[[f32; 3]], cropped: &[[f32; 3]]) -> f64 {
        let spacing = 2.0 * s;
        if o.abs() <= NEAR_GAP * s || self.fill_ground(canopy, cropped, a) < MIN_GROUND_POINTS {
            return o;
        }
        let centre = circular_mean(&self.ground, spacing);
        // Distance on the circle of one spacing.
        let apart = |y: f64| {
            let d = (y - centre).rem_euclid(spacing);
            d.min(spacing - d)
        };
        if apart(o + s) < apart(o) { o + s } else { o }
    }

    /// How strongly the canopy runs along `lane`'s rows in the view nearer than `near_m` (`base_link`
    /// x): per lateral bin, the number of the along-x slices of [`Lanes::fill_envelope`] (which must
    /// have run at the lane's heading) that hold canopy; returned is that count's component in phase
    /// with the lane's rows (a cosine of the lattice's period peaking on them), relative to the bins
    /// holding canopy and the slices holding any. 2 for narrow rows with canopy in every slice right
    /// on the lane's rows, 0 for canopy spread evenly across, negative for a lattice whose rows lie
    /// where the canopy does not run (on the inter-rows).
    pub(super) fn lane_contrast(&mut self, lane: &Lane, near_m: f64) -> f64 {
        let occupancy = &mut self.occupancy;
        occupancy.iter_mut().for_each(|o| *o = 0.0);
        let mut slices = 0.0;
        let near = (((near_m - X_LO_M) / ENVELOPE_SLICE_M).ceil() as usize).min(ENVELOPE_SLICES);
        for slice in self.slices.chunks_exact(HIST_BINS).take(near) {
            if slice.iter().any(|&v| v > 0.0) {
                slices += 1.0;
                for (o, &v) in occupancy.iter_mut().zip(slice) {
                    if v > 0.0 {
                        *o += 1.0;
                    }
                }
            }
        }
        if slices == 0.0 {
            return 0.0;
        }
        let holding = occupancy.iter().filter(|&&o| o > 0.0).count() as f64;
        let mean = occupancy.iter().sum::<f64>() / occupancy.len() as f64;
        // The first row left of the lane centre, across the heading like the bins.
        let (spacing, first_row_m) = (lane.spacing_m(), lane.o + 0.5 * lane.spacing_m());
        let mut c = 0.0;
        for (i, o) in occupancy.iter().enumerate() {
            c += (o - mean) * (std::f64::consts::TAU * (hist_centre(i) - first_row_m) / spacing).cos();
        }
        2.0 * c / (holding * slices)
    }

    /// The canopy's upper envelope across the rows along heading slope `a`: per lateral bin, the mean
    /// over [`ENVELOPE_SLICE_M`] slices along x of the highest canopy point in the slice, demeaned over
    /// the bins that hold canopy (the others are 0 and not `filled`). Slices, not one maximum over the
    /// whole view: a leaf arching nearly as high as the plant top somewhere along the row would
    /// otherwise flatten it. Returns the share of the bins between the outermost canopy bins that
    /// hold canopy: near 1 under a closed canopy.
    fn fill_envelope(&mut self, canopy: &[[f32; 3]], a: f64) -> f64 {
        self.slices.iter_mut().for_each(|h| *h = 0.0);
        for p in canopy {
            let slice = ((p[0] as f64 - X_LO_M) / ENVELOPE_SLICE_M).clamp(0.0, (ENVELOPE_SLICES - 1) as f64);
            if let Some(i) = hist_index(p[1] as f64 - a * p[0] as f64)
                && let Some(h) = self.slices.get_mut(slice as usize * HIST_BINS + i)
            {
                // Canopy heights are above the plane (> 0): 0 marks a cell without canopy.
                *h = h.max(p[2] as f64);
            }
        }
        let (mut sum, mut n) = (0.0, 0.0);
        let (mut first, mut last) = (None, 0);
        for (i, (h, f)) in self.envelope.iter_mut().zip(self.filled.iter_mut()).enumerate() {
            let (top, cells) = (0..ENVELOPE_SLICES)
                .filter_map(|k| self.slices.get(k * HIST_BINS + i))
                .filter(|&&v| v > 0.0)
                .fold((0.0, 0.0), |(t, c), v| (t + v, c + 1.0));
            *f = cells > 0.0;
            *h = if *f { top / cells } else { 0.0 };
            if *f {
                sum += *h;
                n += 1.0;
                first.get_or_insert(i);
                last = i;
            }
        }
        let mean = if n > 0.0 { sum / n } else { 0.0 };
        for (h, f) in self.envelope.iter_mut().zip(&self.filled) {
            *h = if *f { *h - mean } else { 0.0 };
        }
        first.map_or(0.0, |first| n / (last + 1 - first) as f64)
    }

    /// Lateral profile of the share of returns that reach the ground (cropped points that are not
    /// canopy), along heading slope `a`, demeaned; bins with too few returns are 0. A share, not a count:
    /// the sensor sees far more of its own inter-row than of the others, and counts would carry that
    /// envelope. Returns the number of ground returns. The canopy is a subset of the cropped points with
    /// the same `x, y`.
    fn fill_ground(&mut self, canopy: &[[f32; 3]], cropped: &[[f32; 3]], a: f64) -> f64 {
        self.ground.iter_mut().for_each(|h| *h = 0.0);
        self.returns.iter_mut().for_each(|h| *h = 0.0);
        for p in cropped {
            if let Some(i) = hist_index(p[1] as f64 - a * p[0] as f64)
                && let (Some(g), Some(r)) = (self.ground.get_mut(i), self.returns.get_mut(i))
            {
                *g += 1.0;
                *r += 1.0;
            }
        }
        for p in canopy {
            if let Some(g) = hist_index(p[1] as f64 - a * p[0] as f64).and_then(|i| self.ground.get_mut(i)) {
                *g -= 1.0;
            }
        }
        let total = self.ground.iter().sum::<f64>();
        let (mut sum, mut n) = (0.0, 0.0);
        for (g, &r) in self.ground.iter_mut().zip(&self.returns) {
            if r >= MIN_BIN_RETURNS {
                *g /= r;
                sum += *g;
                n += 1.0;
            }
        }
        let mean = if n > 0.0 { sum / n } else { 0.0 };
        for (g, &r) in self.ground.iter_mut().zip(&self.returns) {
            *g = if r >= MIN_BIN_RETURNS { *g - mean } else { 0.0 };
        }
        total
    }

    pub(super) fn fill_hist(&mut self, canopy: &[[f32; 3]], a: f64, stride: usize) {
        self.hist.iter_mut().for_each(|h| *h = 0.0);
        for p in canopy.iter().step_by(stride) {
            if let Some(h) = hist_index(p[1] as f64 - a * p[0] as f64).and_then(|i| self.hist.get_mut(i)) {
                // Weighted by height like the measure step: under a closed canopy, leaves arching into
                // the inter-row are nearly as many as the returns of the crest, but lower.
                *h += (p[2] as f64).powi(2) + HEIGHT_WEIGHT_FLOOR_M2;
            }
        }
    }
}

/// Row spacing from the autocorrelation of the lateral canopy histogram (demeaned in place); see
/// [`peak_lag`].
pub(super) fn spacing(hist: &mut [f64], config: &DetectorConfig) -> Option<f64> {
    demean(hist);
    peak_lag(|lag| autocorrelation(hist, lag), config)
}

/// Row spacing from the autocorrelation of the canopy's upper envelope (see [`Lanes::fill_envelope`]):
/// like [`spacing`], over the pairs of bins that both hold canopy.
fn envelope_spacing(envelope: &[f64], filled: &[bool], config: &DetectorConfig) -> Option<f64> {
    peak_lag(|lag| masked_autocorrelation(envelope, filled, lag), config)
}

/// The strongest lag of an autocorrelation `ac` (by bin) in the searched spacing range, m: halved when
/// its half is nearly as strong (a lag of two spacings also correlates), refined by a parabola through
/// the peak; `None` when the peak is weaker than [`MIN_PERIODICITY`] of `ac(0)`.
fn peak_lag(ac: impl Fn(usize) -> f64, config: &DetectorConfig) -> Option<f64> {
    let energy = ac(0);
    if energy <= 0.0 {
        return None;
    }
    let lo = (config.spacing_min_m / HIST_BIN_M).ceil() as usize;
    let hi = ((config.spacing_max_m / HIST_BIN_M).floor() as usize).min(HIST_BINS / 2);
    // Local maxima only: at the low end of the range a broad crest (a closed canopy, a smooth envelope)
    // still correlates with itself, and that slope is not a period.
    let mut best = (f64::NEG_INFINITY, lo);
    let (mut prev, mut v) = (ac(lo.saturating_sub(1)), ac(lo));
    for lag in lo..=hi {
        let next = ac(lag + 1);
        if v > prev && v >= next && v > best.0 {
            best = (v, lag);
        }
        (prev, v) = (v, next);
    }
    if best.0 == f64::NEG_INFINITY {
        return None;
    }
    let half = best.1 / 2;
    if half >= lo {
        // Search around the half lag: the true spacing may sit a bin off it.
        let (v, lag) = (half.saturating_sub(2)..=half + 2)
            .map(|l| (ac(l), l))
            .fold((f64::NEG_INFINITY, half), |m, x| if x.0 > m.0 { x } else { m });
        if v >= 0.7 * best.0 {
            best = (v, lag);
        }
    }
    if best.0 / energy < MIN_PERIODICITY {
        return None;
    }
    // Parabolic refinement of the peak.
    let lag = best.1;
    let (l, c, r) = (ac(lag.saturating_sub(1)), best.0, ac(lag + 1));
    let den = l - 2.0 * c + r;
    let shift = if den < 0.0 { (0.5 * (l - r) / den).clamp(-0.5, 0.5) } else { 0.0 };
    let s = (lag as f64 + shift) * HIST_BIN_M;
    (s >= config.spacing_min_m && s <= config.spacing_max_m).then_some(s)
}

/// Tests the canopy period `s` against the ground-share profile of `ground_points` returns: true when
/// the ground repeats about every `2s` but not every `s` (the rows are that far apart and the canopy
/// has two crests per spacing); false when the ground is too sparse to say, agrees with `s`, or `2s` is
/// outside the searched range.
fn ground_repeats_every_other_crest(
    ground: &[f64],
    ground_points: f64,
    s: f64,
    config: &DetectorConfig,
) -> bool {
    if 2.0 * s > config.spacing_max_m || ground_points < MIN_GROUND_POINTS {
        return false;
    }
    // The canopy period of a two-crest canopy is only roughly half the spacing: look for the ground's
    // peaks within a fifth of each lag.
    let peak = |period_m: f64| -> (f64, f64) {
        let lo = (0.8 * period_m / HIST_BIN_M).floor() as usize;
        let hi = (1.2 * period_m / HIST_BIN_M).ceil() as usize;
        (lo..=hi)
            .map(|l| (autocorrelation(ground, l), l as f64 * HIST_BIN_M))
            .fold((f64::NEG_INFINITY, period_m), |m, x| if x.0 > m.0 { x } else { m })
    };
    let ((at_s, _), (at_2s, period_m)) = (peak(s), peak(2.0 * s));
    let periodic = at_2s >= MIN_PERIODICITY * autocorrelation(ground, 0);
    let period_ok = period_m >= config.spacing_min_m && period_m <= config.spacing_max_m;
    periodic && period_ok && at_s < GROUND_HALF_PERIOD_RATIO * at_2s
}

fn demean(hist: &mut [f64]) {
    let mean = hist.iter().sum::<f64>() / hist.len().max(1) as f64;
    hist.iter_mut().for_each(|h| *h -= mean);
}

/// Autocorrelation of a histogram at `lag` bins, per overlapping bin pair.
fn autocorrelation(hist: &[f64], lag: usize) -> f64 {
    let Some(shifted) = hist.get(lag..) else { return 0.0 };
    let n = shifted.len().max(1) as f64;
    hist.iter().zip(shifted).map(|(a, b)| a * b).sum::<f64>() / n
}

/// Autocorrelation of a profile at `lag` bins over the pairs of bins that are both `filled`, per pair;
/// 0 when fewer than [`MIN_ENVELOPE_PAIRS`] pairs overlap (too short a stretch to tell a period).
fn masked_autocorrelation(profile: &[f64], filled: &[bool], lag: usize) -> f64 {
    let (Some(shifted), Some(shifted_filled)) = (profile.get(lag..), filled.get(lag..)) else { return 0.0 };
    let (mut sum, mut n) = (0.0, 0usize);
    for ((a, b), (fa, fb)) in profile.iter().zip(shifted).zip(filled.iter().zip(shifted_filled)) {
        if *fa && *fb {
            sum += a * b;
            n += 1;
        }
    }
    if n < MIN_ENVELOPE_PAIRS { 0.0 } else { sum / n as f64 }
}

/// Lateral position (m) of the peak of a histogram's component with `period_m`, in `(-period_m/2,
/// period_m/2]`.
fn circular_mean(hist: &[f64], period_m: f64) -> f64 {
    let (mut c, mut sn) = (0.0, 0.0);
    for (i, h) in hist.iter().enumerate() {
        let phase = std::f64::consts::TAU * hist_centre(i) / period_m;
        c += h * phase.cos();
        sn += h * phase.sin();
    }
    sn.atan2(c) * period_m / std::f64::consts::TAU
}

/// The lane centre of a canopy with two crests per row spacing, m across the rows (`base_link` y at
/// x = 0 along the search's heading): `hist` is the canopy's lateral profile, `s` its period (half the
/// row spacing) and `envelope` its upper envelope. The lane centre is a crest or a gap between crests
/// (they lie a quarter spacing apart), and which one depends on the crop: in grown corn the plant tops
/// crest over the rows and the arching leaves of two rows meet in a second crest over the middle of
/// the inter-row, so the lane centre is a crest, and the gaps nearest the robot, a quarter spacing
/// off, put the wheels on the way to the rows (soak seed 1390: a lane followed 13-23 cm off its
/// centre line); where the leaves crest either side of each row instead, the lane centre is a gap.
/// The plant tops tell: the envelope rises once per spacing over the rows, so its component at the
/// spacing peaks on them, and half a spacing from there lies a crest or a gap. The lane centre is the
/// crest or the gap, whichever that is, nearest the robot: the envelope says which of the two, not
/// where (soak seed 1465, a LiDAR mount off by 2.4° in roll: the centre taken nearest half a spacing
/// from the envelope's peak lay 0.29 m off the robot, and the robot followed it onto a row, 17 plants).
fn two_crest_lane_centre(hist: &[f64], envelope: &[f64], s: f64) -> f64 {
    let crest = circular_mean(hist, s);
    let rows = circular_mean(envelope, 2.0 * s);
    let quarter = 0.5 * s;
    // A crest (even) or a gap (odd): only which of the two comes from the envelope, so that a weak or
    // tilted envelope puts the centre a quarter spacing off at worst, never on a row.
    let gap = ((rows + s - crest) / quarter).round().rem_euclid(2.0);
    (crest + gap * quarter + quarter).rem_euclid(s) - quarter
}
