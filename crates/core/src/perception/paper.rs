//! The paper's pipeline after preprocessing (Sec. III-A-2 and III-A-3): K-means per depth bin, lateral
//! merging of centroids closer than 0.3 m, a centroid map carried by odometry, then RANSAC on the
//! centroids of the first row left and the first row right, from 0.5 m behind the robot to the farthest.

use crate::geometry::Pose2;

use super::RowEstimate;
use super::config::DetectorConfig;
use super::map::CentroidMap;
use super::rng::Rng;

/// Fewest points for a K-means cluster to count as a row centroid (a lone return is noise).
const MIN_CLUSTER_POINTS: u32 = 3;
/// Fewest map centroids for a lateral group to count as a row.
const MIN_ROW_CENTROIDS: usize = 3;
/// Most depth bins handled (the config's range over its bin width is capped to this).
const MAX_BINS: usize = 64;

/// A lateral range `(y_min, y_max)` of map centroids, m in `base_link`.
type Span = (f64, f64);

/// One K-means cluster: running sums and its centre.
#[derive(Debug, Clone, Copy, Default)]
struct Cluster {
    cx: f64,
    cy: f64,
    sx: f64,
    sy: f64,
    n: u32,
}

/// The rows the paper's method found on one scan.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PaperRows {
    pub(crate) left: Option<RowEstimate>,
    pub(crate) right: Option<RowEstimate>,
}

/// Buffers and RNG of the paper pipeline, allocated once.
#[derive(Debug, Clone)]
pub(crate) struct Paper {
    rng: Rng,
    sorted: Vec<[f32; 2]>,
    bin_start: Vec<usize>,
    dist2: Vec<f64>,
    clusters: Vec<Cluster>,
    /// Map centroids in `base_link` within the fit window: `[x, y]`.
    window: Vec<[f64; 2]>,
    /// Indices into `window`, sorted by y.
    order: Vec<usize>,
    row: Vec<[f64; 2]>,
    inliers: Vec<bool>,
}

impl Paper {
    pub(crate) fn new(config: &DetectorConfig) -> Self {
        let cap = config.map_capacity;
        Self {
            rng: Rng::new(0x5EED_C0FF),
            sorted: Vec::new(),
            bin_start: vec![0; MAX_BINS + 1],
            dist2: Vec::new(),
            clusters: Vec::with_capacity(config.kmeans_k),
            window: Vec::with_capacity(cap),
            order: Vec::with_capacity(cap),
            row: Vec::with_capacity(cap),
            inliers: Vec::with_capacity(cap),
        }
    }

    /// Clusters this scan's canopy (`base_link`, sensor at `sensor_x_m`), adds the centroids to the
    /// map at `odom`, and fits the first left and right rows. `centroids` receives the map in
    /// `base_link`.
    pub(crate) fn step(
        &mut self,
        canopy: &[[f32; 3]],
        sensor_x_m: f64,
        odom: &Pose2,
        config: &DetectorConfig,
        map: &mut CentroidMap,
        centroids: &mut Vec<[f64; 2]>,
    ) -> PaperRows {
        self.cluster_bins(canopy, sensor_x_m, odom, config, map);
        self.collect_window(odom, config, map, centroids);
        let (left, right) = self.first_rows(config);
        PaperRows {
            left: left.and_then(|g| self.fit_row(g, config)),
            right: right.and_then(|g| self.fit_row(g, config)),
        }
    }

    /// The row selection and RANSAC stage alone, for the per-stage benchmark; returns the rows found.
    pub(crate) fn fit_stage(
        &mut self,
        odom: &Pose2,
        config: &DetectorConfig,
        map: &CentroidMap,
        centroids: &mut Vec<[f64; 2]>,
    ) -> usize {
        self.collect_window(odom, config, map, centroids);
        let (left, right) = self.first_rows(config);
        let l = left.and_then(|g| self.fit_row(g, config)).is_some();
        let r = right.and_then(|g| self.fit_row(g, config)).is_some();
        usize::from(l) + usize::from(r)
    }

    /// Counting-sorts the canopy by depth bin, then runs K-means and the lateral merge in each bin
    /// (also the K-means stage of the per-stage benchmark).
    pub(crate) fn cluster_bins(
        &mut self,
        canopy: &[[f32; 3]],
        sensor_x_m: f64,
        odom: &Pose2,
        config: &DetectorConfig,
        map: &mut CentroidMap,
    ) {
        let bin_m = config.depth_bin_m as f32;
        let n_bins = ((config.max_depth_m / config.depth_bin_m).ceil() as usize).clamp(1, MAX_BINS);
        let sx = sensor_x_m as f32;
        let bin_of = |p: &[f32; 3]| {
            let d = (p[0] - sx) / bin_m;
            if d >= 0.0 && d < n_bins as f32 { Some(d as usize) } else { None }
        };
        self.bin_start.iter_mut().for_each(|s| *s = 0);
        for p in canopy {
            if let Some(b) = bin_of(p)
                && let Some(c) = self.bin_start.get_mut(b + 1)
            {
                *c += 1;
            }
        }
        for i in 1..self.bin_start.len() {
            self.bin_start[i] += self.bin_start[i - 1];
        }
        let total = self.bin_start.get(n_bins).copied().unwrap_or(0);
        self.sorted.clear();
        self.sorted.resize(total, [0.0; 2]);
        // Fill bins from their start; `dist2` doubles as the per-bin cursor so no extra buffer is needed.
        self.dist2.clear();
        self.dist2.extend(self.bin_start.iter().map(|&s| s as f64));
        for p in canopy {
            if let Some(b) = bin_of(p)
                && let Some(cur) = self.dist2.get_mut(b)
            {
                if let Some(slot) = self.sorted.get_mut(*cur as usize) {
                    *slot = [p[0], p[1]];
                }
                *cur += 1.0;
            }
        }
        for b in 0..n_bins {
            let (lo, hi) = (self.bin_start[b], self.bin_start[b + 1]);
            if hi > lo {
                self.kmeans(lo, hi, config);
                self.merge_and_store(odom, config, map);
            }
        }
    }

    /// K-means (k-means++ seeding, Lloyd iterations) on `sorted[lo..hi]`; leaves clusters in `clusters`.
    fn kmeans(&mut self, lo: usize, hi: usize, config: &DetectorConfig) {
        let pts = &self.sorted[lo..hi];
        let k = config.kmeans_k.min(pts.len());
        self.clusters.clear();
        self.dist2.clear();
        self.dist2.resize(pts.len(), f64::INFINITY);
        let first = pts[self.rng.below(pts.len())];
        self.clusters.push(Cluster { cx: first[0] as f64, cy: first[1] as f64, ..Cluster::default() });
        while self.clusters.len() < k {
            let Some(last) = self.clusters.last().copied() else { break };
            let mut sum = 0.0;
            for (d, p) in self.dist2.iter_mut().zip(pts) {
                let (dx, dy) = (p[0] as f64 - last.cx, p[1] as f64 - last.cy);
                *d = d.min(dx * dx + dy * dy);
                sum += *d;
            }
            if sum <= 0.0 {
                break;
            }
            let mut target = self.rng.unit() * sum;
            let mut pick = pts.len() - 1;
            for (i, d) in self.dist2.iter().enumerate() {
                target -= d;
                if target <= 0.0 {
                    pick = i;
                    break;
                }
            }
            let p = pts[pick];
            self.clusters.push(Cluster { cx: p[0] as f64, cy: p[1] as f64, ..Cluster::default() });
        }
        for _ in 0..config.kmeans_iterations {
            self.clusters.iter_mut().for_each(|c| (c.sx, c.sy, c.n) = (0.0, 0.0, 0));
            for p in pts {
                let (px, py) = (p[0] as f64, p[1] as f64);
                let mut best = (f64::INFINITY, 0usize);
                for (i, c) in self.clusters.iter().enumerate() {
                    let d = (px - c.cx) * (px - c.cx) + (py - c.cy) * (py - c.cy);
                    if d < best.0 {
                        best = (d, i);
                    }
                }
                if let Some(c) = self.clusters.get_mut(best.1) {
                    c.sx += px;
                    c.sy += py;
                    c.n += 1;
                }
            }
            let mut moved = false;
            for c in self.clusters.iter_mut().filter(|c| c.n > 0) {
                let (nx, ny) = (c.sx / c.n as f64, c.sy / c.n as f64);
                moved |= (nx - c.cx).abs() + (ny - c.cy).abs() > 1e-6;
                (c.cx, c.cy) = (nx, ny);
            }
            if !moved {
                break;
            }
        }
    }

    /// Merges clusters closer than `merge_distance_m` laterally and stores the survivors in the map.
    fn merge_and_store(&mut self, odom: &Pose2, config: &DetectorConfig, map: &mut CentroidMap) {
        self.clusters.retain(|c| c.n > 0);
        self.clusters.sort_unstable_by(|a, b| a.cy.total_cmp(&b.cy));
        let mut acc: Option<Cluster> = None;
        let flush = |c: Cluster, map: &mut CentroidMap| {
            if c.n >= MIN_CLUSTER_POINTS {
                map.push(odom, c.sx / c.n as f64, c.sy / c.n as f64, c.n as f64, 0.0);
            }
        };
        for c in &self.clusters {
            acc = match acc {
                Some(mut a) if (c.cy - a.sy / a.n as f64).abs() < config.merge_distance_m => {
                    a.sx += c.sx;
                    a.sy += c.sy;
                    a.n += c.n;
                    Some(a)
                }
                Some(a) => {
                    flush(a, map);
                    Some(*c)
                }
                None => Some(*c),
            };
        }
        if let Some(a) = acc {
            flush(a, map);
        }
    }

    /// Map centroids from `behind_m` behind `base_link` onwards, in `base_link`.
    fn collect_window(
        &mut self,
        odom: &Pose2,
        config: &DetectorConfig,
        map: &CentroidMap,
        out: &mut Vec<[f64; 2]>,
    ) {
        out.clear();
        self.window.clear();
        for p in map.points() {
            let (x, y) = odom.inverse_transform_point(p[0], p[1]);
            out.push([x, y]);
            if x >= -config.behind_m {
                self.window.push([x, y]);
            }
        }
    }

    /// Groups window centroids by lateral position (gaps wider than the merge distance, and the robot's
    /// own centre line, split groups) and returns the y-ranges of the first group left and the first
    /// group right with at least `MIN_ROW_CENTROIDS` members (fewer is clutter, not a row).
    fn first_rows(&mut self, config: &DetectorConfig) -> (Option<Span>, Option<Span>) {
        self.order.clear();
        self.order.extend(0..self.window.len());
        let w = &self.window;
        self.order.sort_unstable_by(|&a, &b| w[a][1].total_cmp(&w[b][1]));
        let y = |k: usize| w[self.order[k]][1];
        let (mut left, mut right) = (None, None);
        let mut start = 0;
        while start < self.order.len() {
            let mut end = start + 1;
            while end < self.order.len()
                && y(end) - y(end - 1) < config.merge_distance_m
                && (y(end) >= 0.0) == (y(start) >= 0.0)
            {
                end += 1;
            }
            if end - start >= MIN_ROW_CENTROIDS {
                if y(start) < 0.0 {
                    right = Some((y(start), y(end - 1)));
                } else if left.is_none() {
                    left = Some((y(start), y(end - 1)));
                }
            }
            start = end;
        }
        (left, right)
    }

    /// RANSAC (seeded) then a least-squares refit on the inliers, for the centroids with y in `range`.
    fn fit_row(&mut self, range: Span, config: &DetectorConfig) -> Option<RowEstimate> {
        self.row.clear();
        self.row.extend(self.window.iter().filter(|p| p[1] >= range.0 && p[1] <= range.1));
        let n = self.row.len();
        let (xmin, xmax) = self
            .row
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[0]), hi.max(p[0])));
        if n < 2 || xmax - xmin < config.min_span_m {
            return None;
        }
        let mut best = (0usize, 0.0, 0.0);
        for _ in 0..config.ransac_iterations {
            let (p, q) = (self.row[self.rng.below(n)], self.row[self.rng.below(n)]);
            let dx = q[0] - p[0];
            if dx.abs() < 1e-3 {
                continue;
            }
            let m = (q[1] - p[1]) / dx;
            let c = p[1] - m * p[0];
            let tol = config.ransac_inlier_m * (1.0 + m * m).sqrt();
            let count = self.row.iter().filter(|r| (r[1] - m * r[0] - c).abs() <= tol).count();
            if count > best.0 {
                best = (count, m, c);
            }
        }
        if best.0 < 2 {
            return None;
        }
        let (_, m, c) = best;
        let tol = config.ransac_inlier_m * (1.0 + m * m).sqrt();
        self.inliers.clear();
        self.inliers.extend(self.row.iter().map(|r| (r[1] - m * r[0] - c).abs() <= tol));
        let (m, c) = least_squares(self.row.iter().zip(&self.inliers).filter(|(_, k)| **k).map(|(p, _)| *p))?;
        let (x1, x2) = self
            .row
            .iter()
            .zip(&self.inliers)
            .filter(|(_, k)| **k)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (p, _)| (lo.min(p[0]), hi.max(p[0])));
        Some(RowEstimate {
            line: [x1, m * x1 + c, x2, m * x2 + c],
            offset_m: c,
            heading_rad: m.atan(),
            curvature_per_m: 0.0,
            confidence: best.0 as f64 / n as f64,
        })
    }
}

/// Ordinary least squares `y = m x + c`; `None` when the x values do not spread.
fn least_squares(points: impl Iterator<Item = [f64; 2]>) -> Option<(f64, f64)> {
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        n += 1.0;
        sx += p[0];
        sy += p[1];
        sxx += p[0] * p[0];
        sxy += p[0] * p[1];
    }
    let det = n * sxx - sx * sx;
    if n < 2.0 || det.abs() < 1e-9 {
        return None;
    }
    let m = (n * sxy - sx * sy) / det;
    let c = (sy - m * sx) / n;
    (m.is_finite() && c.is_finite()).then_some((m, c))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_recovers_a_line() {
        let (m, c) = least_squares((0..10).map(|i| [i as f64, 0.1 * i as f64 + 0.4])).unwrap();
        assert!((m - 0.1).abs() < 1e-12 && (c - 0.4).abs() < 1e-12);
        assert!(least_squares([[1.0, 0.0], [1.0, 2.0]].into_iter()).is_none());
    }

    #[test]
    fn two_straight_rows_of_points_give_two_rows() {
        // Canopy points on rows at y = ±0.375 from x = 1 to 4 m: one scan gives centroids every depth bin;
        // the rows are fitted once their centroids span 2 m (tolerance 1 cm, 0.5°).
        let cfg = DetectorConfig::paper();
        let mut canopy = Vec::new();
        for i in 0..300 {
            let x = 1.0 + 0.01 * i as f32;
            for dy in [-0.05f32, 0.0, 0.05] {
                canopy.push([x, 0.375 + dy, 0.1]);
                canopy.push([x, -0.375 + dy, 0.1]);
            }
        }
        let mut paper = Paper::new(&cfg);
        let mut map = CentroidMap::new(cfg.map_capacity);
        let mut out = Vec::new();
        let rows = paper.step(&canopy, 0.6, &Pose2::default(), &cfg, &mut map, &mut out);
        let (l, r) = (rows.left.unwrap(), rows.right.unwrap());
        assert!((l.offset_m - 0.375).abs() < 0.01 && (r.offset_m + 0.375).abs() < 0.01, "{l:?} {r:?}");
        assert!(l.heading_rad.abs() < 0.5f64.to_radians() && r.heading_rad.abs() < 0.5f64.to_radians());
    }
}
