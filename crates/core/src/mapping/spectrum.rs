//! Row direction, spacing and how periodic a patch of the field is, from the spectrum of its occupancy
//! profile across the rows.
//!
//! The points of one tile are rasterised into a binary occupancy image (binary, so dense canopies and
//! sparse seedlings weigh alike and the scanner's range-dependent density does not matter). For each
//! candidate direction θ the occupied cells are projected on the normal of θ and the profile's power
//! spectrum is taken; rows are the direction and frequency where the occupied cells are most coherent
//! with a comb (fundamental plus weighted harmonics). The coherence at the row frequency, in [0, 1],
//! is the tile's *periodicity*: the crop-agnostic evidence used to pick the height slice and the seeds.

use std::f64::consts::PI;

/// The dominant row pattern of one tile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pattern {
    /// Direction of the rows, rad in [0, π), counter-clockwise from +x.
    pub direction_rad: f64,
    /// Distance between rows across the direction, m.
    pub spacing_m: f64,
    /// Coherence of the occupied cells with the row comb (magnitude of the mean phasor), in [0, 1].
    pub periodicity: f64,
}

/// Reusable buffers for the spectral analysis of tiles (allocated once per extraction).
#[derive(Debug)]
pub(crate) struct Analyzer {
    raster_m: f64,
    min_spacing_m: f64,
    max_spacing_m: f64,
    occupied: Vec<bool>,
    cells: Vec<[f64; 2]>,
    re: Vec<f64>,
    im: Vec<f64>,
    power: Vec<f64>,
}

/// Harmonic weights: the fundamental must dominate so that half the row spacing (whose harmonics are
/// the same peaks) never wins a tie.
const HARMONIC_WEIGHTS: [f64; 3] = [1.0, 0.5, 0.33];

/// A sub-multiple of the chosen frequency this coherent (relative) is the true row frequency.
const SUBHARMONIC_RATIO: f64 = 0.5;

/// Fewest occupied raster cells worth analysing.
const MIN_CELLS: usize = 100;

impl Analyzer {
    pub(crate) fn new(raster_m: f64, min_spacing_m: f64, max_spacing_m: f64) -> Self {
        Self {
            raster_m,
            min_spacing_m,
            max_spacing_m,
            occupied: Vec::new(),
            cells: Vec::new(),
            re: Vec::new(),
            im: Vec::new(),
            power: Vec::new(),
        }
    }

    /// The row pattern of the points `xy` (relative to the tile centre, inside `±half_m`), or `None`
    /// when the tile holds too little to say.
    pub(crate) fn analyse(&mut self, xy: impl Iterator<Item = [f64; 2]>, half_m: f64) -> Option<Pattern> {
        let side = ((2.0 * half_m / self.raster_m).ceil() as usize).max(1);
        self.occupied.clear();
        self.occupied.resize(side * side, false);
        self.cells.clear();
        for [x, y] in xy {
            let ix = ((x + half_m) / self.raster_m).floor();
            let iy = ((y + half_m) / self.raster_m).floor();
            if ix < 0.0 || iy < 0.0 || ix >= side as f64 || iy >= side as f64 {
                continue;
            }
            let c = iy as usize * side + ix as usize;
            if !self.occupied[c] {
                self.occupied[c] = true;
                let centre = |i: f64| (i + 0.5) * self.raster_m - half_m;
                self.cells.push([centre(ix), centre(iy)]);
            }
        }
        if self.cells.len() < MIN_CELLS {
            return None;
        }
        let coarse_step = 3f64.to_radians();
        let mut best: Option<Pattern> = None;
        for i in 0..60 {
            best = better(best, self.evaluate(i as f64 * coarse_step, half_m));
        }
        let centre = best?.direction_rad;
        let fine_step = 0.25f64.to_radians();
        for i in -12..=12 {
            let theta = (centre + i as f64 * fine_step).rem_euclid(PI);
            best = better(best, self.evaluate(theta, half_m));
        }
        best
    }

    /// The pattern at one direction: the best row spacing and its periodicity.
    fn evaluate(&mut self, theta: f64, half_m: f64) -> Option<Pattern> {
        let bin_m = self.raster_m / 2.0;
        let n = ((2.0 * half_m * std::f64::consts::SQRT_2 / bin_m).ceil() as usize + 2).next_power_of_two();
        let span_m = n as f64 * bin_m;
        self.re.clear();
        self.re.resize(n, 0.0);
        self.im.clear();
        self.im.resize(n, 0.0);
        let (s, c) = theta.sin_cos();
        for &[x, y] in &self.cells {
            let across = -s * x + c * y;
            let i = ((across + span_m / 2.0) / bin_m) as usize;
            if let Some(v) = self.re.get_mut(i) {
                *v += 1.0;
            }
        }
        fft(&mut self.re, &mut self.im);
        // |X_k| / M is the coherence of the M occupied cells with a comb of period span/k: 1 when
        // every cell sits on a tooth, about 1/sqrt(M) for no pattern. The normaliser does not depend
        // on the direction, so a blurred (misaligned) profile never scores higher than a sharp one.
        let cells = self.cells.len() as f64;
        self.power.clear();
        self.power.extend(self.re.iter().zip(&self.im).take(n / 2).map(|(r, i)| r.hypot(*i) / cells));
        let k_lo = ((span_m / self.max_spacing_m).ceil() as usize).max(1);
        let k_hi = ((span_m / self.min_spacing_m).floor() as usize).min(n / 2 - 1);
        let share = |k: usize| self.power.get(k).copied().unwrap_or(0.0);
        let (mut best_k, mut best_score) = (0usize, 0.0);
        for k in k_lo..=k_hi {
            let score: f64 = HARMONIC_WEIGHTS.iter().enumerate().map(|(h, w)| w * share(k * (h + 1))).sum();
            if score > best_score {
                (best_k, best_score) = (k, score);
            }
        }
        if best_k == 0 {
            return None;
        }
        // A sharp comb (thin stalks) is as coherent at twice or three times its frequency as at its
        // own, so the harmonic sum can tie; rows evenly spaced have no power at a sub-multiple of their
        // frequency, so a strong one there means the rows are that much farther apart.
        'octave: loop {
            for divisor in [2, 3] {
                let centre = (best_k as f64 / divisor as f64).round() as usize;
                let sub = (centre.saturating_sub(1)..=centre + 1)
                    .filter(|k| *k >= k_lo)
                    .max_by(|a, b| share(*a).total_cmp(&share(*b)));
                if let Some(k) = sub
                    && k < best_k
                    && share(k) >= SUBHARMONIC_RATIO * share(best_k)
                {
                    best_k = k;
                    continue 'octave;
                }
            }
            break;
        }
        // Parabolic interpolation of the fundamental's peak refines the spacing between FFT bins.
        let (a, b, cc) = (share(best_k - 1), share(best_k), share(best_k + 1));
        let denom = a - 2.0 * b + cc;
        let shift = if denom.abs() > 1e-12 { (0.5 * (a - cc) / denom).clamp(-0.5, 0.5) } else { 0.0 };
        // The best of a few thousand (direction, frequency) pairs over M random cells reaches about
        // 3/sqrt(M) by chance: report the coherence above that floor.
        let periodicity = (share(best_k) - 3.0 / cells.sqrt()).max(0.0);
        Some(Pattern { direction_rad: theta, spacing_m: span_m / (best_k as f64 + shift), periodicity })
    }
}

fn better(a: Option<Pattern>, b: Option<Pattern>) -> Option<Pattern> {
    match (a, b) {
        (Some(a), Some(b)) => Some(if b.periodicity > a.periodicity { b } else { a }),
        (a, b) => a.or(b),
    }
}

/// In-place iterative radix-2 FFT; `re.len()` must be a power of two (the caller pads).
fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let (ws, wc) = (-2.0 * PI / len as f64).sin_cos();
        for start in (0..n).step_by(len) {
            let (mut cr, mut ci) = (1.0, 0.0);
            for k in 0..len / 2 {
                let (a, b) = (start + k, start + k + len / 2);
                let tr = re[b] * cr - im[b] * ci;
                let ti = re[b] * ci + im[b] * cr;
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
                (cr, ci) = (cr * wc - ci * ws, cr * ws + ci * wc);
            }
        }
        len <<= 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_of_a_cosine_has_one_peak() {
        let n = 64;
        let mut re: Vec<f64> = (0..n).map(|i| (2.0 * PI * 5.0 * i as f64 / n as f64).cos()).collect();
        let mut im = vec![0.0; n];
        fft(&mut re, &mut im);
        // A unit cosine at bin 5 puts n/2 into bins 5 and n-5 and nothing elsewhere (1e-9).
        for k in 0..n {
            let mag = (re[k] * re[k] + im[k] * im[k]).sqrt();
            let want = if k == 5 || k == n - 5 { n as f64 / 2.0 } else { 0.0 };
            assert!((mag - want).abs() < 1e-9, "bin {k}: {mag}");
        }
    }

    #[test]
    fn finds_direction_and_spacing_of_narrow_rows() {
        // Rows 0.8 m apart at 30°, 6 cm wide, sampled every 2 cm along and across.
        let theta = 30f64.to_radians();
        let (s, c) = theta.sin_cos();
        let mut pts = Vec::new();
        for row in -5..=5 {
            for i in -200..=200 {
                for w in -1..=1 {
                    let (along, across) = (i as f64 * 0.02, row as f64 * 0.8 + w as f64 * 0.02);
                    pts.push([c * along - s * across, s * along + c * across]);
                }
            }
        }
        let mut a = Analyzer::new(0.04, 0.25, 2.0);
        let p = a.analyse(pts.iter().copied().filter(|p| p[0].abs() < 3.0 && p[1].abs() < 3.0), 3.0).unwrap();
        // Direction within 0.5°, spacing within 3 cm: this is the coarse, per-tile estimate.
        assert!((p.direction_rad - theta).abs() < 0.5f64.to_radians(), "{p:?}");
        assert!((p.spacing_m - 0.8).abs() < 0.03, "{p:?}");
        assert!(p.periodicity > 0.3, "{p:?}");
    }
}
