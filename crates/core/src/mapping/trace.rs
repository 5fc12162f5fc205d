//! Following one row along the field in short segments, so curved rows come out right.
//!
//! From a seed on the row, each step predicts the next centre one `step_m` ahead along the current
//! heading, gathers the slice points in a window around the prediction (`window_m` along, a fraction of
//! the spacing across), and moves the centre to their robust across-row centroid (median, then two
//! trimmed means, which ignores the odd weed between the rows). The heading follows the measured
//! centres. A window counts as a gap when it holds too few points, far fewer than the trace's mean support (a weed in a gap), or a centre that jumps sideways (rows bend by millimetres per
//! step); over a gap the trace coasts straight on for up to `max_gap_m`, and a trace that finds
//! nothing further ends at its last supported centre.

/// Points of the height slice, bucketed on a uniform grid for rectangle queries (local frame, m).
#[derive(Debug)]
pub(crate) struct Index {
    cell_m: f64,
    nx: usize,
    ny: usize,
    start: Vec<usize>,
    xy: Vec<[f64; 2]>,
}

impl Index {
    /// Buckets `xy` (all with `0 <= x <= extent[0]`, `0 <= y <= extent[1]`).
    pub(crate) fn new(xy: &[[f64; 2]], extent_m: [f64; 2], cell_m: f64) -> Self {
        let nx = super::ground::cells_along(extent_m[0], cell_m);
        let ny = super::ground::cells_along(extent_m[1], cell_m);
        let cell_of = |p: &[f64; 2]| {
            let ix = ((p[0] / cell_m) as usize).min(nx - 1);
            let iy = ((p[1] / cell_m) as usize).min(ny - 1);
            iy * nx + ix
        };
        let mut start = vec![0usize; nx * ny + 1];
        for p in xy {
            start[cell_of(p) + 1] += 1;
        }
        for i in 0..nx * ny {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut sorted = vec![[0.0; 2]; xy.len()];
        for p in xy {
            let c = cell_of(p);
            sorted[fill[c]] = *p;
            fill[c] += 1;
        }
        Self { cell_m, nx, ny, start, xy: sorted }
    }

    /// Calls `visit(along, across)` for every point in the rectangle centred on `centre` with unit
    /// axis `dir`, `half_along` and `half_across` wide (coordinates relative to the centre).
    pub(crate) fn for_each_in(
        &self,
        centre: [f64; 2],
        dir: [f64; 2],
        half_along: f64,
        half_across: f64,
        mut visit: impl FnMut(f64, f64),
    ) {
        let reach_x = (dir[0] * half_along).abs() + (dir[1] * half_across).abs();
        let reach_y = (dir[1] * half_along).abs() + (dir[0] * half_across).abs();
        let range = |c: f64, reach: f64, n: usize| {
            let lo = ((c - reach) / self.cell_m).floor().max(0.0) as usize;
            let hi = ((c + reach) / self.cell_m).floor();
            (lo, if hi < 0.0 { None } else { Some((hi as usize).min(n - 1)) })
        };
        let (x0, x1) = range(centre[0], reach_x, self.nx);
        let (y0, y1) = range(centre[1], reach_y, self.ny);
        let (Some(x1), Some(y1)) = (x1, y1) else { return };
        if x0 > x1 || y0 > y1 {
            return;
        }
        for iy in y0..=y1 {
            let (a, b) = (self.start[iy * self.nx + x0], self.start[iy * self.nx + x1 + 1]);
            for p in &self.xy[a..b] {
                let (dx, dy) = (p[0] - centre[0], p[1] - centre[1]);
                let along = dx * dir[0] + dy * dir[1];
                let across = -dx * dir[1] + dy * dir[0];
                if along.abs() <= half_along && across.abs() <= half_across {
                    visit(along, across);
                }
            }
        }
    }
}

/// Tracing parameters, in metres, derived from the config and the estimated spacing.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Params {
    pub step_m: f64,
    pub window_m: f64,
    pub half_width_m: f64,
    pub max_gap_m: f64,
    pub min_points: usize,
    /// The trace stops when its heading leaves this cone around the field's row direction (cos).
    pub min_heading_cos: f64,
    pub extent_m: [f64; 2],
}

/// One traced row: centres in the local frame, m, and how many slice points supported them.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Trace {
    pub centres: Vec<[f64; 2]>,
    pub support: usize,
}

/// A window with less than this share of the trace's typical support is treated as a gap.
const WEED_SUPPORT_RATIO: f64 = 0.3;

/// A centre more than this share of the half-width off the prediction is treated as a gap: rows bend
/// by millimetres per step, a weed beside the row pulls by decimetres.
const MAX_JUMP_FRACTION: f64 = 0.5;

/// Traces rows through an [`Index`], reusing one scratch buffer.
#[derive(Debug)]
pub(crate) struct Tracer<'a> {
    index: &'a Index,
    params: Params,
    offsets: Vec<f64>,
}

impl<'a> Tracer<'a> {
    pub(crate) fn new(index: &'a Index, params: Params) -> Self {
        Self { index, params, offsets: Vec::new() }
    }

    /// The robust across-row centre of the window at `centre` heading `dir`: `(offset_m, points)`.
    pub(crate) fn measure(&mut self, centre: [f64; 2], dir: [f64; 2]) -> Option<(f64, usize)> {
        let p = self.params;
        self.offsets.clear();
        let offsets = &mut self.offsets;
        self.index
            .for_each_in(centre, dir, p.window_m / 2.0, p.half_width_m, |_, across| offsets.push(across));
        let count = self.offsets.len();
        if count < p.min_points {
            return None;
        }
        let mid = count / 2;
        let (_, median, _) = self.offsets.select_nth_unstable_by(mid, f64::total_cmp);
        let mut c = *median;
        for shrink in [0.6, 0.4] {
            let half = p.half_width_m * shrink;
            let (sum, n) = self
                .offsets
                .iter()
                .filter(|o| (*o - c).abs() <= half)
                .fold((0.0, 0usize), |(s, n), o| (s + o, n + 1));
            if n == 0 {
                break;
            }
            c = sum / n as f64;
        }
        Some((c, count))
    }

    /// Traces the row through `seed` both ways along `dir` (unit), or `None` when the seed has no support.
    pub(crate) fn trace(&mut self, seed: [f64; 2], dir: [f64; 2]) -> Option<Trace> {
        let normal = [-dir[1], dir[0]];
        let mut centre = seed;
        let mut support = 0;
        for _ in 0..2 {
            let (off, n) = self.measure(centre, dir)?;
            centre = [centre[0] + normal[0] * off, centre[1] + normal[1] * off];
            support = n;
        }
        let (ahead, s_ahead) = self.follow(centre, dir, support);
        let (behind, s_behind) = self.follow(centre, [-dir[0], -dir[1]], support);
        let mut centres: Vec<[f64; 2]> = behind.into_iter().rev().collect();
        centres.push(centre);
        centres.extend(ahead);
        Some(Trace { centres, support: support + s_ahead + s_behind })
    }

    /// Follows the row from `start` along `dir0`; returns the supported centres (not `start`) and
    /// their summed support.
    fn follow(&mut self, start: [f64; 2], dir0: [f64; 2], seed_support: usize) -> (Vec<[f64; 2]>, usize) {
        let p = self.params;
        let (mut at, mut dir) = (start, dir0);
        let mut kept = Vec::new();
        let mut pending: Vec<[f64; 2]> = Vec::new();
        let mut support = 0;
        let margin = p.window_m;
        // Mean point count of the supported windows, the seed's included: a window far below it inside
        // a gap holds a weed, not the row. (Cumulative, not running: a running mean sinks as weak
        // windows are accepted and lets the trace slide from the row onto a string of weeds.)
        let (mut support_sum, mut supported) = (seed_support as f64, 1.0f64);
        loop {
            let next = [at[0] + dir[0] * p.step_m, at[1] + dir[1] * p.step_m];
            if next[0] < -margin
                || next[1] < -margin
                || next[0] > p.extent_m[0] + margin
                || next[1] > p.extent_m[1] + margin
            {
                break;
            }
            let reading = self.measure(next, dir).filter(|&(off, n)| {
                let enough = n as f64 >= WEED_SUPPORT_RATIO * support_sum / supported;
                enough && off.abs() <= MAX_JUMP_FRACTION * p.half_width_m
            });
            match reading {
                Some((off, n)) => {
                    support_sum += n as f64;
                    supported += 1.0;
                    let moved = [next[0] - dir[1] * off, next[1] + dir[0] * off];
                    let last = kept.last().copied().unwrap_or(start);
                    let (dx, dy) = (moved[0] - last[0], moved[1] - last[1]);
                    let len = (dx * dx + dy * dy).sqrt();
                    if len > 1e-9 {
                        // Half the new chord: heading noise from one centroid is damped, curvature
                        // is still followed within a few steps.
                        let (hx, hy) = (0.5 * dir[0] + 0.5 * dx / len, 0.5 * dir[1] + 0.5 * dy / len);
                        let norm = (hx * hx + hy * hy).sqrt();
                        if norm > 1e-9 {
                            dir = [hx / norm, hy / norm];
                        }
                    }
                    if dir[0] * dir0[0] + dir[1] * dir0[1] < p.min_heading_cos {
                        break;
                    }
                    kept.append(&mut pending);
                    kept.push(moved);
                    support += n;
                    at = moved;
                }
                None => {
                    pending.push(next);
                    if pending.len() as f64 * p.step_m > p.max_gap_m {
                        break;
                    }
                    at = next;
                }
            }
        }
        (kept, support)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(extent_m: [f64; 2]) -> Params {
        Params {
            step_m: 0.5,
            window_m: 1.0,
            half_width_m: 0.3,
            max_gap_m: 2.0,
            min_points: 3,
            min_heading_cos: 0.5,
            extent_m,
        }
    }

    #[test]
    fn rectangle_query_sees_only_inside_points() {
        let pts: Vec<[f64; 2]> =
            (0..100).flat_map(|i| (0..100).map(move |j| [i as f64 * 0.1, j as f64 * 0.1])).collect();
        let index = Index::new(&pts, [10.0, 10.0], 0.5);
        let d = std::f64::consts::FRAC_1_SQRT_2;
        let mut n = 0;
        index.for_each_in([5.0, 5.0], [d, d], 1.0, 0.5, |a, c| {
            assert!(a.abs() <= 1.0 && c.abs() <= 0.5);
            n += 1;
        });
        // A 2 m x 1 m rectangle on a 0.1 m lattice holds about 200 points (±10% for the rotated edges).
        assert!((180..=220).contains(&n), "{n}");
    }

    #[test]
    fn trace_bridges_a_gap_and_stops_at_the_end() {
        // A straight row along x at y = 2 from x = 1 to 9 with a gap from 4 to 5.5 m.
        let pts: Vec<[f64; 2]> = (0..=80)
            .map(|i| 1.0 + i as f64 * 0.1)
            .filter(|x| !(4.0..5.5).contains(x))
            .map(|x| [x, 2.0])
            .collect();
        let index = Index::new(&pts, [10.0, 4.0], 0.5);
        let mut tracer = Tracer::new(&index, params([10.0, 4.0]));
        let t = tracer.trace([5.8, 2.1], [1.0, 0.0]).unwrap();
        let first = t.centres.first().unwrap();
        let last = t.centres.last().unwrap();
        // Ends within one step (0.5 m) of the row's ends; every centre on the row (1 mm).
        assert!((first[0] - 1.0).abs() <= 0.5 && (last[0] - 9.0).abs() <= 0.5, "{first:?} {last:?}");
        assert!(t.centres.iter().all(|c| (c[1] - 2.0).abs() < 1e-3));
    }
}
