//! Crop rows from a whole-field point-cloud map (drone or terrestrial scanner): every row as a
//! polyline, plus the row spacing. This is how the paper's ground truth was made, and how a user plans
//! coverage. It sits beside perception: perception sees one scan from the robot, mapping sees the field.
//!
//! The steps, each in its own module:
//!
//! 1. **Ground** (`ground`): a low percentile of z per `ground_cell_m` cell, holes filled, smoothed;
//!    every point gets its height above the local ground, so terrain relief does not matter.
//! 2. **Height slice**: vegetation is everything above `clearance_m`. Its height range (up to the
//!    98th percentile, the canopy top) is cut into `slice_bands` equal bands; each band and the whole
//!    range are scored by how periodic their occupancy is across the rows (next step), and the most
//!    periodic slice wins. A closed canopy (tall maize) is flat across the rows and scores low, while
//!    the stalks just above the ground are strongly periodic, so the stalks are chosen; for seedlings
//!    or an open canopy the whole vegetation or its upper part wins. `height_slice_m` fixes the slice.
//! 3. **Row pattern** (`spectrum`): per `tile_m` tile, the direction and spacing whose across-row
//!    occupancy profile puts the largest share of its variance in one frequency and its harmonics.
//!    Crop-agnostic: the spacing is estimated, never assumed.
//! 4. **Tracing** (`trace`): seeds on the row comb of each periodic tile (teeth with far less support
//!    than the others, beyond the field's last row, are skipped), each row followed both ways in
//!    `step_m` steps by a robust local centroid, coasting over gaps of up to `max_gap_m`.
//! 5. **Assembly**: rows are ordered across the field, fragments of one row joined, traces off the
//!    row comb (weed patches) dropped, and the spacing refined from the distances between
//!    neighbouring rows.
//!
//! Coordinates are `f64` in the cloud's own frame and units (metres, z up; UTM-like offsets are fine:
//! the work is done relative to a local origin).
//!
//! ```
//! use croprow_core::mapping::{Config, Extractor};
//! // Three rows along x, 0.75 m apart, 0.2 m tall, on flat ground, 1 km from the origin.
//! let mut cloud = Vec::new();
//! for i in 0..400 {
//!     for j in 0..60 {
//!         let (x, y) = (i as f64 * 0.025, j as f64 * 0.05 - 0.75);
//!         cloud.push([x + 1000.0, y, 0.0]);
//!     }
//!     for row in 0..3 {
//!         cloud.push([i as f64 * 0.025 + 1000.0, row as f64 * 0.75, 0.2]);
//!     }
//! }
//! let map = Extractor::new(Config::default()).unwrap().extract(&cloud).unwrap();
//! assert_eq!(map.rows.len(), 3);
//! assert!((map.spacing_m - 0.75).abs() < 0.01);
//! ```

mod ground;
mod spectrum;
mod trace;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::error::{ConfigError, check_range};
use ground::Ground;
use spectrum::{Analyzer, Pattern};
use trace::{Index, Params, Trace, Tracer};

/// Settings of the row extraction from a field map. Lengths in the cloud's units (metres).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Side of the ground-estimate cells, m. Default 1.0: larger than a row spacing, so each cell
    /// sees soil between the rows, and small enough to follow 0.2 m of relief.
    pub ground_cell_m: f64,
    /// Percentile of z per cell taken as the ground, in [0, 0.5]. Default 0.05.
    pub ground_percentile: f64,
    /// Height above the local ground below which a point is soil, m. Default 0.03 (a few times the
    /// range noise of a survey scanner; seedlings of 5 cm still show).
    pub clearance_m: f64,
    /// Number of equal height bands of the vegetation tried as the slice (plus the whole), 1..=10.
    /// Default 4.
    pub slice_bands: usize,
    /// A fixed height slice `[min, max]` above the ground, m, instead of the automatic choice.
    /// Default none (automatic).
    pub height_slice_m: Option<[f64; 2]>,
    /// Smallest row spacing searched, m. Default 0.25.
    pub min_spacing_m: f64,
    /// Largest row spacing searched, m. Default 2.0 (wider than any row crop planter).
    pub max_spacing_m: f64,
    /// Side of the square tiles analysed for direction and spacing, m. Default 6.0: several rows per
    /// tile, and short enough that a curved row is nearly straight inside one.
    pub tile_m: f64,
    /// Cell of the occupancy raster used for the spectrum, m. Default 0.04.
    pub raster_m: f64,
    /// Distance between successive centres of a traced row, m. Default 0.5.
    pub step_m: f64,
    /// Length along the row of the window whose points give one centre, m. Default 1.0.
    pub window_m: f64,
    /// Half-width of that window across the row, as a fraction of the spacing, in [0.1, 0.5].
    /// Default 0.4 (stays clear of the neighbouring row's centre).
    pub half_width_fraction: f64,
    /// Longest gap in a row bridged by a straight line, m. Default 3.0.
    pub max_gap_m: f64,
    /// Fewest slice points in a window for it to give a centre. Default 4.
    pub min_segment_points: usize,
    /// Shortest row reported, m. Default 2.0 (shorter traces are weed patches or field edges).
    pub min_row_length_m: f64,
    /// Least periodicity (coherence of the occupancy with the row comb, [0, 1]; about 1/sqrt(cells) for
    /// no pattern) for a tile to count as rows. Default 0.15.
    pub min_periodicity: f64,
    /// Largest horizontal extent of a cloud, m. Default 2000 (a large farm field; refuses mixed-up
    /// coordinate systems before allocating grids for them).
    pub max_extent_m: f64,
    /// Fewest points in a cloud. Default 100.
    pub min_points: usize,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            ground_cell_m: 1.0,
            ground_percentile: 0.05,
            clearance_m: 0.03,
            slice_bands: 4,
            height_slice_m: None,
            min_spacing_m: 0.25,
            max_spacing_m: 2.0,
            tile_m: 6.0,
            raster_m: 0.04,
            step_m: 0.5,
            window_m: 1.0,
            half_width_fraction: 0.4,
            max_gap_m: 3.0,
            min_segment_points: 4,
            min_row_length_m: 2.0,
            min_periodicity: 0.15,
            max_extent_m: 2000.0,
            min_points: 100,
        }
    }
}

impl Config {
    /// Checks every field, naming the first bad one (`mapping.<field>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("mapping.ground_cell_m", self.ground_cell_m, 0.1, 50.0)?;
        check_range("mapping.ground_percentile", self.ground_percentile, 0.0, 0.5)?;
        check_range("mapping.clearance_m", self.clearance_m, 0.0, 2.0)?;
        check_range("mapping.slice_bands", self.slice_bands as f64, 1.0, 10.0)?;
        if let Some([lo, hi]) = self.height_slice_m {
            check_range("mapping.height_slice_m[0]", lo, 0.0, 20.0)?;
            check_range("mapping.height_slice_m[1]", hi, lo + 1e-3, 20.0)?;
        }
        check_range("mapping.min_spacing_m", self.min_spacing_m, 0.05, 10.0)?;
        check_range("mapping.max_spacing_m", self.max_spacing_m, self.min_spacing_m * 1.5, 20.0)?;
        check_range("mapping.tile_m", self.tile_m, 2.0 * self.max_spacing_m, 200.0)?;
        // At most 4096 raster cells a tile side keeps the occupancy image and its FFT small.
        check_range(
            "mapping.raster_m",
            self.raster_m,
            (self.tile_m / 4096.0).max(0.005),
            self.min_spacing_m / 4.0,
        )?;
        check_range("mapping.step_m", self.step_m, 0.05, 10.0)?;
        check_range("mapping.window_m", self.window_m, 0.05, 20.0)?;
        check_range("mapping.half_width_fraction", self.half_width_fraction, 0.1, 0.5)?;
        check_range("mapping.max_gap_m", self.max_gap_m, 0.0, 1000.0)?;
        check_range("mapping.min_segment_points", self.min_segment_points as f64, 1.0, 1e6)?;
        check_range("mapping.min_row_length_m", self.min_row_length_m, 0.0, 1e4)?;
        check_range("mapping.min_periodicity", self.min_periodicity, 0.0, 1.0)?;
        check_range("mapping.max_extent_m", self.max_extent_m, 1.0, 1e5)?;
        check_range("mapping.min_points", self.min_points as f64, 10.0, 1e9)?;
        Ok(())
    }
}

/// Why a cloud gave no rows.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum MapError {
    /// Too few points to estimate a ground and a row pattern.
    #[error("the cloud has {found} points; at least {needed} are needed (mapping.min_points)")]
    TooFewPoints {
        /// Points in the cloud.
        found: usize,
        /// `mapping.min_points`.
        needed: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("point {index} has a non-finite coordinate")]
    NonFinite {
        /// Index of the first bad point.
        index: usize,
    },
    /// The cloud is wider than `mapping.max_extent_m`.
    #[error("the cloud spans {extent_m:.0} m, more than mapping.max_extent_m = {max_m} m")]
    TooLarge {
        /// Largest horizontal extent, in the cloud's units.
        extent_m: f64,
        /// `mapping.max_extent_m`.
        max_m: f64,
    },
    /// Nothing stands above the ground.
    #[error("only {found} points stand more than mapping.clearance_m above the ground; no vegetation")]
    NoVegetation {
        /// Points above the clearance.
        found: usize,
    },
    /// The vegetation shows no row pattern (a weedy patch, a lawn, a wrong spacing range).
    #[error(
        "no row pattern: the most periodic height slice scores {periodicity:.3}, below mapping.min_periodicity = {min}"
    )]
    NoRowPattern {
        /// Best median tile periodicity over the slices tried.
        periodicity: f64,
        /// `mapping.min_periodicity`.
        min: f64,
    },
}

/// The band of heights above the local ground whose points mark the rows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HeightSlice {
    /// Lower bound above the ground, m.
    pub min_m: f64,
    /// Upper bound above the ground, m.
    pub max_m: f64,
    /// Median tile periodicity of the slice, in [0, 1].
    pub periodicity: f64,
}

/// One crop row of the field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// Position across the field, 0.. in order from one side to the other.
    pub index: usize,
    /// Row centre as a polyline `[x, y]` in the cloud's frame, ordered along the field direction.
    pub polyline: Vec<[f64; 2]>,
    /// Slice points that supported the centres.
    pub support: usize,
    /// Length of the polyline, m.
    pub length_m: f64,
}

/// Every row of a field and its layout.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RowMap {
    /// The rows, ordered across the field (`rows[i].index == i`).
    pub rows: Vec<Row>,
    /// Estimated distance between neighbouring row centres, measured across the rows, m.
    pub spacing_m: f64,
    /// Mean row direction, rad in [0, π), counter-clockwise from the cloud's +x.
    pub direction_rad: f64,
    /// The height slice the rows were found in.
    pub slice: HeightSlice,
    /// Vegetation height (98th percentile above the ground), m.
    pub canopy_height_m: f64,
}

/// Extracts the crop rows of a field cloud. Built once from a validated [`Config`].
#[derive(Debug, Clone)]
pub struct Extractor {
    config: Config,
}

/// One analysed tile: its centre (local frame) and row pattern.
#[derive(Debug, Clone, Copy)]
struct Tile {
    centre: [f64; 2],
    pattern: Pattern,
}

impl Extractor {
    /// An extractor, or the first invalid field of `config`.
    pub fn new(config: Config) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self { config })
    }

    /// The configuration in use.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Extracts every row of `points` (`[x, y, z]`, z up, any horizontal frame and offset).
    ///
    /// Allocates a few arrays the size of the cloud (local coordinates, heights, the slice).
    pub fn extract(&self, points: &[[f64; 3]]) -> Result<RowMap, MapError> {
        let cfg = &self.config;
        if points.len() < cfg.min_points {
            return Err(MapError::TooFewPoints { found: points.len(), needed: cfg.min_points });
        }
        let (origin, extent) = bounds(points)?;
        if extent[0].max(extent[1]) > cfg.max_extent_m {
            return Err(MapError::TooLarge { extent_m: extent[0].max(extent[1]), max_m: cfg.max_extent_m });
        }
        let local: Vec<[f64; 3]> =
            points.iter().map(|p| [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]]).collect();
        // The ground grid is capped at ~2048 cells a side (32 MB an array), whatever the config.
        let ground_cell_m = cfg.ground_cell_m.max(extent[0].max(extent[1]) / 2048.0);
        let ground = Ground::estimate(&local, extent, ground_cell_m, cfg.ground_percentile);
        let heights: Vec<f64> = local.iter().map(|p| p[2] - ground.height_at(p[0], p[1])).collect();

        let mut vegetation: Vec<f64> = heights.iter().copied().filter(|h| *h > cfg.clearance_m).collect();
        if vegetation.len() < cfg.min_points {
            return Err(MapError::NoVegetation { found: vegetation.len() });
        }
        let k = ((vegetation.len() - 1) as f64 * 0.98) as usize;
        let canopy_height_m = *vegetation.select_nth_unstable_by(k, f64::total_cmp).1;
        let top_m = vegetation.iter().copied().fold(f64::MIN, f64::max) + 1e-6;

        let mut analyzer = Analyzer::new(cfg.raster_m, cfg.min_spacing_m, cfg.max_spacing_m);
        // Slices are compared on the most populated tiles only (the field's interior); the winner is
        // then analysed on every tile.
        let mut best: Option<(HeightSlice, Vec<[f64; 2]>)> = None;
        for (min_m, max_m) in self.candidate_slices(canopy_height_m, top_m) {
            let xy = slice_points(&local, &heights, min_m, max_m);
            let tiles = self.analyse_tiles(&mut analyzer, &xy, extent, SLICE_SCORING_TILES);
            let mut scores: Vec<f64> = tiles.iter().map(|t| t.pattern.periodicity).collect();
            let periodicity = median(&mut scores).unwrap_or(0.0);
            if best.as_ref().is_none_or(|(s, _)| periodicity > s.periodicity) {
                best = Some((HeightSlice { min_m, max_m: max_m.min(top_m), periodicity }, xy));
            }
        }
        let (slice, xy) =
            best.unwrap_or((HeightSlice { min_m: 0.0, max_m: 0.0, periodicity: 0.0 }, Vec::new()));
        let tiles = self.analyse_tiles(&mut analyzer, &xy, extent, usize::MAX);
        let mut good: Vec<Tile> =
            tiles.into_iter().filter(|t| t.pattern.periodicity >= cfg.min_periodicity).collect();
        if slice.periodicity < cfg.min_periodicity || good.is_empty() {
            return Err(MapError::NoRowPattern { periodicity: slice.periodicity, min: cfg.min_periodicity });
        }
        good.sort_by(|a, b| b.pattern.periodicity.total_cmp(&a.pattern.periodicity));
        let mut spacings: Vec<f64> = good.iter().map(|t| t.pattern.spacing_m).collect();
        let coarse_spacing_m = median(&mut spacings).unwrap_or(cfg.min_spacing_m);
        let direction_rad = mean_axis(good.iter().map(|t| (t.pattern.direction_rad, t.pattern.periodicity)));

        // At most ~2048 buckets a side keeps the index small on a large field.
        let bucket_m = cfg.window_m.max(0.5).max(extent[0].max(extent[1]) / 2048.0);
        let index = Index::new(&xy, extent, bucket_m);
        let params = Params {
            step_m: cfg.step_m,
            window_m: cfg.window_m,
            half_width_m: cfg.half_width_fraction * coarse_spacing_m,
            max_gap_m: cfg.max_gap_m,
            min_points: cfg.min_segment_points,
            min_heading_cos: 60f64.to_radians().cos(),
            extent_m: extent,
        };
        let traces = self.trace_rows(&index, params, &good, coarse_spacing_m, extent);
        let axis = [direction_rad.cos(), direction_rad.sin()];
        let rows = assemble(traces, axis, coarse_spacing_m, cfg.step_m, cfg.min_row_length_m);
        let spacing_m = refine_spacing(&rows, coarse_spacing_m);
        let rows = rows
            .into_iter()
            .enumerate()
            .map(|(index, t)| {
                let polyline: Vec<[f64; 2]> =
                    t.centres.iter().map(|c| [c[0] + origin[0], c[1] + origin[1]]).collect();
                Row { index, length_m: polyline_length(&t.centres), polyline, support: t.support }
            })
            .collect();
        Ok(RowMap { rows, spacing_m, direction_rad, slice, canopy_height_m })
    }

    /// The height slices tried: the fixed one, or the whole vegetation and `slice_bands` bands of it.
    fn candidate_slices(&self, canopy_m: f64, top_m: f64) -> Vec<(f64, f64)> {
        let cfg = &self.config;
        if let Some([lo, hi]) = cfg.height_slice_m {
            return vec![(lo, hi)];
        }
        let lo = cfg.clearance_m;
        let band = ((canopy_m - lo) / cfg.slice_bands as f64).max(0.0);
        let mut slices = vec![(lo, top_m)];
        if cfg.slice_bands > 1 && band > 0.0 {
            for j in 0..cfg.slice_bands {
                let hi = if j + 1 == cfg.slice_bands { top_m } else { lo + band * (j + 1) as f64 };
                slices.push((lo + band * j as f64, hi));
            }
        }
        slices
    }

    /// The row pattern of the (at most `limit`, most populated) tiles of `xy` that hold enough to analyse.
    fn analyse_tiles(
        &self,
        analyzer: &mut Analyzer,
        xy: &[[f64; 2]],
        extent: [f64; 2],
        limit: usize,
    ) -> Vec<Tile> {
        let tile = self.config.tile_m.max(extent[0].max(extent[1]) / 4096.0);
        let nx = (extent[0] / tile).ceil().max(1.0) as usize;
        let ny = (extent[1] / tile).ceil().max(1.0) as usize;
        let mut buckets: Vec<Vec<[f64; 2]>> = vec![Vec::new(); nx * ny];
        // Tiles are centred on the cloud's extent so a small field sits in the middle of one tile.
        let x0 = extent[0] / 2.0 - nx as f64 * tile / 2.0;
        let y0 = extent[1] / 2.0 - ny as f64 * tile / 2.0;
        for p in xy {
            let ix = (((p[0] - x0) / tile) as usize).min(nx - 1);
            let iy = (((p[1] - y0) / tile) as usize).min(ny - 1);
            buckets[iy * nx + ix].push(*p);
        }
        let mut order: Vec<usize> = (0..buckets.len()).collect();
        order.sort_by_key(|&i| std::cmp::Reverse(buckets[i].len()));
        order.truncate(limit);
        let mut tiles = Vec::new();
        for i in order {
            let pts = &buckets[i];
            let centre = [x0 + ((i % nx) as f64 + 0.5) * tile, y0 + ((i / nx) as f64 + 0.5) * tile];
            let rel = pts.iter().map(|p| [p[0] - centre[0], p[1] - centre[1]]);
            if let Some(pattern) = analyzer.analyse(rel, tile / 2.0) {
                tiles.push(Tile { centre, pattern });
            }
        }
        tiles
    }

    /// Seeds rows on the comb of each periodic tile (most periodic first) and traces the new ones.
    fn trace_rows(
        &self,
        index: &Index,
        params: Params,
        tiles: &[Tile],
        spacing_m: f64,
        extent: [f64; 2],
    ) -> Vec<Trace> {
        let mut tracer = Tracer::new(index, params);
        let mut traces: Vec<Trace> = Vec::new();
        let half = self.config.tile_m / 2.0;
        for tile in tiles {
            let (s, c) = tile.pattern.direction_rad.sin_cos();
            let (dir, normal) = ([c, s], [-s, c]);
            // Phase of the row comb in this tile: the argument of the profile's Fourier coefficient
            // at the row frequency.
            let (mut re, mut im) = (0.0, 0.0);
            index.for_each_in(tile.centre, dir, half, half, |_, across| {
                let phase = std::f64::consts::TAU * across / spacing_m;
                re += phase.cos();
                im += phase.sin();
            });
            let offset = im.atan2(re) / std::f64::consts::TAU * spacing_m;
            let reach = (half * std::f64::consts::SQRT_2 / spacing_m).ceil() as i64;
            // Rows can lie on the very edge of the cloud: seeds up to half a spacing out are tried.
            let margin = spacing_m / 2.0;
            let mut seeds: Vec<([f64; 2], usize)> = (-reach..=reach)
                .map(|m| {
                    let a = offset + m as f64 * spacing_m;
                    [tile.centre[0] + normal[0] * a, tile.centre[1] + normal[1] * a]
                })
                .filter(|s| {
                    (-margin..=extent[0] + margin).contains(&s[0])
                        && (-margin..=extent[1] + margin).contains(&s[1])
                })
                .filter_map(|s| tracer.measure(s, dir).map(|(_, n)| (s, n)))
                .collect();
            // A tooth of the comb beyond the field's last row sees only weeds: far less support than
            // the teeth on rows.
            let mut supports: Vec<f64> = seeds.iter().map(|(_, n)| *n as f64).collect();
            let typical = median(&mut supports).unwrap_or(0.0);
            seeds.retain(|(_, n)| *n as f64 >= MIN_RELATIVE_SUPPORT * typical);
            for (seed, _) in seeds {
                if traces.iter().any(|t| distance_to_polyline(seed, &t.centres) < 0.5 * spacing_m) {
                    continue;
                }
                if let Some(t) = tracer.trace(seed, dir)
                    && polyline_length(&t.centres) >= self.config.min_row_length_m
                {
                    traces.push(t);
                }
            }
        }
        traces
    }
}

/// The bounding box corner (the local origin) and the horizontal extent of a cloud.
fn bounds(points: &[[f64; 3]]) -> Result<([f64; 3], [f64; 2]), MapError> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (index, p) in points.iter().enumerate() {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(MapError::NonFinite { index });
        }
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    Ok((lo, [hi[0] - lo[0], hi[1] - lo[1]]))
}

/// The horizontal positions of the points whose height above the ground is in `[min_m, max_m)`.
fn slice_points(local: &[[f64; 3]], heights: &[f64], min_m: f64, max_m: f64) -> Vec<[f64; 2]> {
    local
        .iter()
        .zip(heights)
        .filter(|(_, h)| (min_m..max_m).contains(*h))
        .map(|(p, _)| [p[0], p[1]])
        .collect()
}

fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    Some(*values.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// Weighted mean of axial directions (θ and θ + π are the same row), rad in [0, π).
fn mean_axis(dirs: impl Iterator<Item = (f64, f64)>) -> f64 {
    let (s, c) = dirs
        .fold((0.0, 0.0), |(s, c), (theta, w)| (s + w * (2.0 * theta).sin(), c + w * (2.0 * theta).cos()));
    (s.atan2(c) / 2.0).rem_euclid(std::f64::consts::PI)
}

fn polyline_length(pts: &[[f64; 2]]) -> f64 {
    pts.windows(2).map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1])).sum()
}

/// Distance from `p` to the closest point of a polyline, and whether that point lies strictly
/// between the polyline's ends (so the distance is a true perpendicular one).
fn closest_on_polyline(p: [f64; 2], line: &[[f64; 2]]) -> (f64, bool) {
    let mut best = (f64::INFINITY, false);
    for (i, w) in line.windows(2).enumerate() {
        let (ax, ay, bx, by) = (w[0][0], w[0][1], w[1][0], w[1][1]);
        let (dx, dy) = (bx - ax, by - ay);
        let len2 = dx * dx + dy * dy;
        let t = if len2 > 0.0 { ((p[0] - ax) * dx + (p[1] - ay) * dy) / len2 } else { 0.0 };
        let tc = t.clamp(0.0, 1.0);
        let d = (p[0] - ax - tc * dx).hypot(p[1] - ay - tc * dy);
        let interior = !((i == 0 && t < 0.0) || (i + 2 == line.len() && t > 1.0));
        if d < best.0 {
            best = (d, interior);
        }
    }
    if let [only] = line {
        return ((p[0] - only[0]).hypot(p[1] - only[1]), false);
    }
    best
}

fn distance_to_polyline(p: [f64; 2], line: &[[f64; 2]]) -> f64 {
    closest_on_polyline(p, line).0
}

/// Tiles on which the candidate height slices are compared.
const SLICE_SCORING_TILES: usize = 6;

/// Support per metre, relative to the median row's, below which a trace is weeds, not a row.
const MIN_RELATIVE_SUPPORT: f64 = 0.3;

/// Orders traces across the field, joins fragments of the same row, drops traces off the row comb,
/// and smooths each polyline lightly.
///
/// Across-field position is measured against the longest trace, so curved fields order correctly:
/// every trace's key is the median of its offsets from that reference, taken across `axis`.
fn assemble(
    mut traces: Vec<Trace>,
    axis: [f64; 2],
    spacing_m: f64,
    step_m: f64,
    min_length_m: f64,
) -> Vec<Trace> {
    let along = |p: &[f64; 2]| p[0] * axis[0] + p[1] * axis[1];
    let across = |p: &[f64; 2]| -p[0] * axis[1] + p[1] * axis[0];
    for t in &mut traces {
        if let (Some(a), Some(b)) = (t.centres.first(), t.centres.last())
            && along(b) < along(a)
        {
            t.centres.reverse();
        }
    }
    let Some(reference) = traces.iter().max_by_key(|t| t.centres.len()).cloned() else {
        return Vec::new();
    };
    let ref_curve: Vec<(f64, f64)> = reference.centres.iter().map(|p| (along(p), across(p))).collect();
    let reference_across = |t: f64| -> f64 {
        let i = ref_curve.partition_point(|(a, _)| *a < t);
        match (i.checked_sub(1).and_then(|j| ref_curve.get(j)), ref_curve.get(i)) {
            (Some(&(a0, u0)), Some(&(a1, u1))) if a1 > a0 => u0 + (u1 - u0) * (t - a0) / (a1 - a0),
            (Some(&(_, u)), _) | (None, Some(&(_, u))) => u,
            (None, None) => 0.0,
        }
    };
    let mut keyed: Vec<(f64, Trace)> = traces
        .into_iter()
        .map(|t| {
            let mut offsets: Vec<f64> =
                t.centres.iter().map(|p| across(p) - reference_across(along(p))).collect();
            (median(&mut offsets).unwrap_or(0.0), t)
        })
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));

    // Traces whose keys are within a third of a spacing are pieces of one row. Within a row the best
    // supported pieces are kept first; a piece overlapping a kept one along the row is a duplicate (or
    // a trace that slid off the row at its end) and goes; the rest are joined in order along the row.
    let mut groups: Vec<(f64, Vec<Trace>)> = Vec::new();
    for (key, t) in keyed {
        match groups.last_mut() {
            Some((group_key, pieces)) if (key - *group_key).abs() < spacing_m / 3.0 => pieces.push(t),
            _ => groups.push((key, vec![t])),
        }
    }
    let span = |t: &Trace| {
        let first = t.centres.first().map_or(0.0, along);
        let last = t.centres.last().map_or(0.0, along);
        (first, last)
    };
    let mut rows: Vec<(f64, Trace)> = Vec::new();
    for (key, mut pieces) in groups {
        pieces.sort_by_key(|t| std::cmp::Reverse(t.support));
        let mut kept: Vec<Trace> = Vec::new();
        for piece in pieces {
            let (a0, a1) = span(&piece);
            let overlaps = kept.iter().any(|k| {
                let (b0, b1) = span(k);
                a0 < b1 - step_m / 2.0 && b0 < a1 - step_m / 2.0
            });
            if !overlaps {
                kept.push(piece);
            }
        }
        kept.sort_by(|a, b| span(a).0.total_cmp(&span(b).0));
        let mut joined = Trace { centres: Vec::new(), support: 0 };
        for piece in kept {
            joined.centres.extend_from_slice(&piece.centres);
            joined.support += piece.support;
        }
        rows.push((key, joined));
    }
    // Rows sit on a comb of the spacing; a trace between two teeth is a weed patch, and so is a trace
    // on a tooth beyond the field whose support per metre is a fraction of a real row's.
    let reference_key = rows.iter().max_by_key(|(_, t)| t.support).map_or(0.0, |(k, _)| *k);
    let density = |t: &Trace| t.support as f64 / polyline_length(&t.centres).max(step_m);
    let mut densities: Vec<f64> = rows.iter().map(|(_, t)| density(t)).collect();
    let typical = median(&mut densities).unwrap_or(0.0);
    rows.into_iter()
        .filter(|(key, t)| {
            let teeth = (key - reference_key) / spacing_m;
            (teeth - teeth.round()).abs() < 0.25
                && polyline_length(&t.centres) >= min_length_m
                && density(t) >= MIN_RELATIVE_SUPPORT * typical
        })
        .map(|(_, mut t)| {
            smooth(&mut t.centres);
            t
        })
        .collect()
}

/// One pass of a [1/4, 1/2, 1/4] filter over the interior vertices: halves the centroid noise while
/// the bias on a curve of radius R is only step²/(4R).
fn smooth(pts: &mut [[f64; 2]]) {
    if pts.len() < 3 {
        return;
    }
    let orig = pts.to_vec();
    for (i, w) in orig.windows(3).enumerate() {
        pts[i + 1] = [
            0.25 * w[0][0] + 0.5 * w[1][0] + 0.25 * w[2][0],
            0.25 * w[0][1] + 0.5 * w[1][1] + 0.25 * w[2][1],
        ];
    }
}

/// The spacing from the perpendicular distances between neighbouring rows (a missing row in between
/// counts as two spacings); falls back to the coarse spectral estimate.
fn refine_spacing(rows: &[Trace], coarse_m: f64) -> f64 {
    let (mut total_m, mut count) = (0.0, 0.0);
    for pair in rows.windows(2) {
        let mut d: Vec<f64> = pair[0]
            .centres
            .iter()
            .map(|p| closest_on_polyline(*p, &pair[1].centres))
            .filter(|(_, interior)| *interior)
            .map(|(d, _)| d)
            .collect();
        let Some(d) = median(&mut d) else { continue };
        let teeth = (d / coarse_m).round();
        if teeth >= 1.0 && (d / teeth - coarse_m).abs() < 0.2 * coarse_m {
            total_m += d;
            count += teeth;
        }
    }
    if count > 0.0 { total_m / count } else { coarse_m }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_config_is_valid_and_bad_fields_are_named() {
        assert!(Config::default().validate().is_ok());
        let bad = Config { tile_m: 1.0, ..Config::default() };
        assert!(bad.validate().unwrap_err().to_string().contains("mapping.tile_m"));
        let bad = Config { height_slice_m: Some([0.5, 0.2]), ..Config::default() };
        assert!(bad.validate().unwrap_err().to_string().contains("mapping.height_slice_m[1]"));
        let bad = Config { min_periodicity: f64::NAN, ..Config::default() };
        assert!(Extractor::new(bad).is_err());
    }

    #[test]
    fn config_reads_from_toml_with_defaults() {
        let c: Config = toml::from_str("step_m = 0.25\nheight_slice_m = [0.05, 0.3]").unwrap();
        assert_eq!(c.step_m, 0.25);
        assert_eq!(c.height_slice_m, Some([0.05, 0.3]));
        assert_eq!(c.window_m, Config::default().window_m);
        assert!(toml::from_str::<Config>("stepm = 1").is_err());
    }

    #[test]
    fn axial_mean_wraps_at_pi() {
        let m = mean_axis([(0.01, 1.0), (std::f64::consts::PI - 0.01, 1.0)].into_iter());
        assert!(m.min(std::f64::consts::PI - m) < 1e-9, "{m}");
    }

    #[test]
    fn bad_clouds_are_refused() {
        let ex = Extractor::new(Config::default()).unwrap();
        assert!(matches!(ex.extract(&[]), Err(MapError::TooFewPoints { found: 0, .. })));
        let mut flat: Vec<[f64; 3]> = (0..200).map(|i| [i as f64 * 0.1, (i % 7) as f64, 0.0]).collect();
        assert!(matches!(ex.extract(&flat), Err(MapError::NoVegetation { .. })));
        flat[17][2] = f64::NAN;
        assert_eq!(ex.extract(&flat), Err(MapError::NonFinite { index: 17 }));
        flat[17] = [1e6, 0.0, 0.0];
        assert!(matches!(ex.extract(&flat), Err(MapError::TooLarge { .. })));
    }

    #[test]
    fn perpendicular_distance_flags_points_beyond_the_ends() {
        let line = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
        assert_eq!(closest_on_polyline([1.5, 0.3], &line), (0.3, true));
        let (d, interior) = closest_on_polyline([3.0, 0.0], &line);
        assert!((d - 1.0).abs() < 1e-12 && !interior);
    }
}
