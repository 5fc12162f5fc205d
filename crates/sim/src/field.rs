//! Procedural crop fields: seeded corn or soybean rows built from primitives, with per-plant
//! variability, missing plants, gaps, weeds, terrain relief and curved rows, plus their ground truth.
//!
//! The field frame is the simulator's world frame (REP-103, z up): rows run along +x from `x = 0` to
//! `x = length_m`; row `k` (0-based, counted to the left) has its centre curve at
//! `y = k · row_spacing_m + A · sin(2π x / λ)` (the paper's curved field with `A = 6`, `λ = 100`; `A = 0` is
//! straight). The robot usually drives in "lane" `k`, the inter-row between rows `k` and `k + 1`.
//!
//! ```
//! use croprow_sim::{Field, FieldConfig};
//! let field = Field::generate(&FieldConfig { length_m: 10.0, ..FieldConfig::default() }, 1).unwrap();
//! assert_eq!(field.row_y(2, 0.0), 1.5);
//! assert!(!field.stems().is_empty());
//! ```

use std::f64::consts::{PI, TAU};

use croprow_core::error::check_range;
use croprow_core::{ConfigError, Pose2};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use crate::faults::{FaultConfig, WeedPatch};
use crate::scene::{Class, Prim, Scene};
use crate::terrain::Relief;

/// Cell edge of the ray-casting grid, m: half a corn leaf segment. With per-cell height ranges of each
/// primitive (see `scene`), 0.1 m took fewer instructions per revolution than 0.07 m and 0.14 m (callgrind).
const CELL_M: f64 = 0.1;
/// Weeds keep this far from a row centre, m ("between the rows").
const WEED_ROW_CLEARANCE_M: f64 = 0.12;
/// Most plants a field may hold (the paper's 200 m x 16-row soybean field has 40 000).
const MAX_PLANTS: f64 = 200_000.0;
/// Most weed clumps a field may hold.
const MAX_WEEDS: f64 = 200_000.0;
/// Seed offset of the weed patch's own random stream (so the rest of the field does not change).
const SEED_WEED_PATCH: u64 = 0x5EED_7A11;
/// Weed clump height range, m (issue 3).
const WEED_HEIGHT_M: (f64, f64) = (0.01, 0.08);
/// Weed clump width range, m (issue 3).
const WEED_WIDTH_M: (f64, f64) = (0.10, 0.45);

/// The crop species.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Crop {
    /// Maize: a stalk with long arching leaves in one vertical plane.
    Corn,
    /// Soybean: a bush of trifoliate leaves on a dome.
    Soybean,
}

/// The growth stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    /// 0.2-0.4 m tall, open canopy: the ground between the rows is visible.
    Young,
    /// 0.4-0.7 m tall, canopy closed over the inter-row.
    Grown,
}

impl Stage {
    /// Plant height range of the stage, m (issue 3).
    pub fn height_range_m(&self) -> (f64, f64) {
        match self {
            Stage::Young => (0.2, 0.4),
            Stage::Grown => (0.4, 0.7),
        }
    }
}

/// Parameters of a field. Every length in metres, field frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FieldConfig {
    /// Crop species. Default `corn`.
    pub crop: Crop,
    /// Growth stage. Default `young`.
    pub stage: Stage,
    /// Number of rows. Default 16 (paper Sec. V-A).
    pub rows: u32,
    /// Distance between row centres, m. Default 0.75 (paper Sec. V).
    pub row_spacing_m: f64,
    /// Row length along x, m. Default 200 (paper Sec. V-A).
    pub length_m: f64,
    /// Nominal distance between plants in a row, m. Default 0.17.
    pub plant_spacing_m: f64,
    /// Standard deviation of each plant's position about its nominal spot, m. Default 0.01.
    pub position_sigma_m: f64,
    /// Relative height variation: heights are uniform in nominal·(1 ± this), clamped to the stage's range.
    /// Default 0.2.
    pub height_variation: f64,
    /// Probability that a plant is missing. Default 0.05.
    pub missing_probability: f64,
    /// Expected number of gaps (discontinuities) per 100 m of row. Default 1.
    pub gaps_per_100m: f64,
    /// Shortest gap, m. Default 1.
    pub gap_min_m: f64,
    /// Longest gap, m. Default 3.
    pub gap_max_m: f64,
    /// Weed clumps per square metre of field (between the rows, 1-8 cm tall, 10-45 cm wide). Default 0.3.
    pub weeds_per_m2: f64,
    /// Peak terrain relief, m; 0 is flat ground. Default 0, at most 0.2.
    pub relief_m: f64,
    /// Main wavelength of the relief, m. Default 20.
    pub relief_wavelength_m: f64,
    /// Amplitude A of the row curve `A·sin(2πx/λ)`, m; 0 is straight rows. Default 0 (paper curved field: 6).
    pub curve_amplitude_m: f64,
    /// Wavelength λ of the row curve, m. Default 100 (paper curved field).
    pub curve_wavelength_m: f64,
    /// Bare ground around the field (headlands), m. Default 6.
    pub headland_m: f64,
}

impl Default for FieldConfig {
    fn default() -> Self {
        Self {
            crop: Crop::Corn,
            stage: Stage::Young,
            rows: 16,
            row_spacing_m: 0.75,
            length_m: 200.0,
            plant_spacing_m: 0.17,
            position_sigma_m: 0.01,
            height_variation: 0.2,
            missing_probability: 0.05,
            gaps_per_100m: 1.0,
            gap_min_m: 1.0,
            gap_max_m: 3.0,
            weeds_per_m2: 0.3,
            relief_m: 0.0,
            relief_wavelength_m: 20.0,
            curve_amplitude_m: 0.0,
            curve_wavelength_m: 100.0,
            headland_m: 6.0,
        }
    }
}

impl FieldConfig {
    /// Checks every field, naming the first bad one (`field.row_spacing_m`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("field.rows", self.rows as f64, 1.0, 200.0)?;
        check_range("field.row_spacing_m", self.row_spacing_m, 0.2, 3.0)?;
        check_range("field.length_m", self.length_m, 1.0, 2000.0)?;
        check_range("field.plant_spacing_m", self.plant_spacing_m, 0.03, 2.0)?;
        check_range("field.position_sigma_m", self.position_sigma_m, 0.0, 0.1)?;
        check_range("field.height_variation", self.height_variation, 0.0, 0.5)?;
        check_range("field.missing_probability", self.missing_probability, 0.0, 0.95)?;
        check_range("field.gaps_per_100m", self.gaps_per_100m, 0.0, 50.0)?;
        check_range("field.gap_min_m", self.gap_min_m, 0.0, 50.0)?;
        check_range("field.gap_max_m", self.gap_max_m, self.gap_min_m, 50.0)?;
        check_range("field.weeds_per_m2", self.weeds_per_m2, 0.0, 20.0)?;
        check_range("field.relief_m", self.relief_m, 0.0, 0.2)?;
        check_range("field.relief_wavelength_m", self.relief_wavelength_m, 2.0, 1000.0)?;
        check_range("field.curve_amplitude_m", self.curve_amplitude_m, 0.0, 50.0)?;
        check_range("field.curve_wavelength_m", self.curve_wavelength_m, 5.0, 10_000.0)?;
        check_range("field.headland_m", self.headland_m, 0.0, 100.0)?;
        // The scene lives in memory (~50 bytes per primitive, ~40 primitives per plant): refuse fields
        // that would need gigabytes rather than fail allocating.
        let plants = self.rows as f64 * self.length_m / self.plant_spacing_m;
        if plants > MAX_PLANTS {
            return Err(ConfigError::invalid(
                "field.plant_spacing_m",
                format!(
                    "{plants:.0} plants exceed the simulator's limit of {MAX_PLANTS}: shorten or thin the field"
                ),
            ));
        }
        let area_m2 = self.rows as f64 * self.row_spacing_m * self.length_m;
        if self.weeds_per_m2 * area_m2 > MAX_WEEDS {
            return Err(ConfigError::invalid(
                "field.weeds_per_m2",
                format!(
                    "{:.0} weed clumps exceed the simulator's limit of {MAX_WEEDS}",
                    self.weeds_per_m2 * area_m2
                ),
            ));
        }
        // Rows steeper than 45° would no longer run "along x": refuse rather than simulate nonsense.
        if self.curve_amplitude_m * TAU / self.curve_wavelength_m > 1.0 {
            return Err(ConfigError::invalid(
                "field.curve_amplitude_m",
                "rows steeper than 45° (2π·A/λ > 1): lengthen curve_wavelength_m or lower the amplitude",
            ));
        }
        Ok(())
    }
}

/// Ground truth of one plant: where its stem meets the ground (field frame, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stem {
    /// Stem position x, m.
    pub x_m: f64,
    /// Stem position y, m.
    pub y_m: f64,
    /// Row index (0 = the rightmost row, y smallest).
    pub row: u32,
    /// Plant height above its base, m.
    pub height_m: f64,
}

/// A generated field: geometry for the ray caster and ground truth for the metrics.
#[derive(Debug, Clone)]
pub struct Field {
    config: FieldConfig,
    relief: Relief,
    scene: Scene,
    /// All stems, grouped by row and sorted by x within a row.
    stems: Vec<Stem>,
    /// `stems[row_start[k]..row_start[k + 1]]` are the stems of row `k`.
    row_start: Vec<usize>,
    weed_count: usize,
}

impl Field {
    /// Builds a field from its configuration and a seed; the same seed gives the same field, bit for bit.
    pub fn generate(config: &FieldConfig, seed: u64) -> Result<Self, ConfigError> {
        Self::generate_with_faults(config, &FaultConfig::default(), seed)
    }

    /// [`Field::generate`] with the field's faults: a row gap (`faults.row_gap`) and a tall weed patch
    /// (`faults.weed_patch`). Outside them the field is bit for bit the fault-free one: plants in the
    /// gap are drawn and then left out, and the weed patch has its own random stream.
    pub fn generate_with_faults(
        config: &FieldConfig,
        faults: &FaultConfig,
        seed: u64,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        faults.validate()?;
        let p = &faults.weed_patch;
        let patch_clumps = p.clumps_per_m2 * p.length_m * config.row_spacing_m * f64::from(config.rows);
        if p.enabled && patch_clumps > MAX_WEEDS {
            return Err(ConfigError::invalid(
                "faults.weed_patch.clumps_per_m2",
                format!("{patch_clumps:.0} weed clumps exceed the simulator's limit of {MAX_WEEDS}"),
            ));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let relief = if config.relief_m > 0.0 {
            Relief::new(
                config.relief_m,
                config.relief_wavelength_m,
                [rng.random_range(0.0..TAU), rng.random_range(0.0..TAU), rng.random_range(0.0..TAU)],
            )
        } else {
            Relief::flat()
        };
        let mut prims = Vec::new();
        let mut stems = Vec::new();
        let mut row_start = vec![0];
        let shape = Shape::new(config.crop, config.stage);
        for row in 0..config.rows {
            let gaps = sample_gaps(config, &mut rng);
            let mut x = 0.0;
            let mut row_stems = Vec::new();
            while x <= config.length_m {
                let heading = curve_slope(config, x).atan();
                let (nx, ny) = (x, row_y_of(config, row, x));
                // Equal spacing along the curve, not along x.
                x += config.plant_spacing_m * heading.cos();
                if gaps.iter().any(|&(a, b)| nx >= a && nx <= b)
                    || rng.random_bool(config.missing_probability)
                {
                    continue;
                }
                let px = nx + config.position_sigma_m * normal(&mut rng);
                let py = ny + config.position_sigma_m * normal(&mut rng);
                let (lo, hi) = config.stage.height_range_m();
                let nominal = 0.5 * (lo + hi);
                let v = config.height_variation;
                let h = (nominal * rng.random_range((1.0 - v)..=(1.0 + v))).clamp(lo, hi);
                let base = [px, py, relief.height(px, py)];
                let mark = prims.len();
                match config.crop {
                    Crop::Corn => corn(&shape, base, h, &mut rng, &mut prims),
                    Crop::Soybean => soybean(&shape, base, h, &mut rng, &mut prims),
                }
                if faults.row_gap.covers(row, nx) {
                    prims.truncate(mark);
                    continue;
                }
                row_stems.push(Stem { x_m: px, y_m: py, row, height_m: h });
            }
            row_stems.sort_by(|a, b| a.x_m.total_cmp(&b.x_m));
            stems.extend(row_stems);
            row_start.push(stems.len());
        }
        let mut weed_count = weeds(config, &relief, &mut rng, &mut prims);
        if faults.weed_patch.enabled {
            let mut patch_rng = ChaCha8Rng::seed_from_u64(seed ^ SEED_WEED_PATCH);
            weed_count += weed_patch(config, &faults.weed_patch, &relief, &mut patch_rng, &mut prims);
        }
        let (y_min, y_max) = (
            -config.curve_amplitude_m,
            (config.rows - 1) as f64 * config.row_spacing_m + config.curve_amplitude_m,
        );
        let m = config.headland_m + 1.0;
        let scene = Scene::build(prims, relief, -m, config.length_m + m, y_min - m, y_max + m, CELL_M);
        Ok(Self { config: config.clone(), relief, scene, stems, row_start, weed_count })
    }

    /// The configuration the field was built from.
    pub fn config(&self) -> &FieldConfig {
        &self.config
    }

    /// Every plant stem, grouped by row, sorted by x within a row.
    pub fn stems(&self) -> &[Stem] {
        &self.stems
    }

    /// The stems of one row, sorted by x (empty for a row that does not exist).
    pub fn row_stems(&self, row: u32) -> &[Stem] {
        let k = row as usize;
        match (self.row_start.get(k), self.row_start.get(k + 1)) {
            (Some(&a), Some(&b)) => self.stems.get(a..b).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Number of weed clumps.
    pub fn weed_count(&self) -> usize {
        self.weed_count
    }

    /// Number of ray-casting primitives (leaves, stalks, weeds).
    pub fn primitive_count(&self) -> usize {
        self.scene.primitive_count()
    }

    /// True centre of row `row` at `x` (field frame): its y, m. Rows are defined for every x (the
    /// curve is analytic); plants exist only for `0 ≤ x ≤ length_m`.
    pub fn row_y(&self, row: u32, x: f64) -> f64 {
        row_y_of(&self.config, row, x)
    }

    /// Centre line of lane `lane` (between rows `lane` and `lane + 1`) at `x`: its y, m.
    pub fn lane_y(&self, lane: u32, x: f64) -> f64 {
        self.row_y(lane, x) + 0.5 * self.config.row_spacing_m
    }

    /// Direction of every row at `x`, rad from +x (field frame).
    pub fn row_heading(&self, x: f64) -> f64 {
        curve_slope(&self.config, x).atan()
    }

    /// Ground height at `(x, y)`, m.
    pub fn ground_z(&self, x: f64, y: f64) -> f64 {
        self.relief.height(x, y)
    }

    /// Ground gradient `(∂z/∂x, ∂z/∂y)` at `(x, y)`.
    pub fn ground_gradient(&self, x: f64, y: f64) -> (f64, f64) {
        self.relief.gradient(x, y)
    }

    /// Where the true centre curve of `row` crosses the `base_link` y axis of a robot at `pose`:
    /// `(offset_m, heading_rad)` in `base_link` (offset positive to the left, heading relative to the
    /// robot's x axis). `None` when the curve does not cross the axis within 50 m (a robot across the rows).
    pub fn row_in_base(&self, row: u32, pose: &Pose2) -> Option<(f64, f64)> {
        // Solve g(s) = P_y(s) - row_y(P_x(s)) = 0 along P(s) = pose + s·(-sin ψ, cos ψ) by Newton.
        let (sn, cs) = pose.yaw.sin_cos();
        let mut s = 0.0;
        for _ in 0..20 {
            let (px, py) = (pose.x - s * sn, pose.y + s * cs);
            let g = py - self.row_y(row, px);
            let dg = cs + curve_slope(&self.config, px) * sn;
            if dg.abs() < 1e-6 {
                return None;
            }
            let step = g / dg;
            s -= step;
            if step.abs() < 1e-10 {
                break;
            }
        }
        let px = pose.x - s * sn;
        let ok = s.is_finite() && s.abs() < 50.0 && (pose.y + s * cs - self.row_y(row, px)).abs() < 1e-6;
        ok.then(|| (s, croprow_core::geometry::wrap_angle(self.row_heading(px) - pose.yaw)))
    }

    /// The ray-casting scene.
    pub(crate) fn scene(&self) -> &Scene {
        &self.scene
    }
}

fn curve_slope(c: &FieldConfig, x: f64) -> f64 {
    let k = TAU / c.curve_wavelength_m;
    c.curve_amplitude_m * k * (k * x).cos()
}

fn row_y_of(c: &FieldConfig, row: u32, x: f64) -> f64 {
    row as f64 * c.row_spacing_m + c.curve_amplitude_m * (TAU * x / c.curve_wavelength_m).sin()
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// Gaps of one row as `[start, end]` intervals along x: about `gaps_per_100m` per 100 m.
fn sample_gaps(c: &FieldConfig, rng: &mut ChaCha8Rng) -> Vec<(f64, f64)> {
    let p_per_m = (c.gaps_per_100m / 100.0).min(1.0);
    let mut gaps = Vec::new();
    let mut x = 0.0;
    while x < c.length_m {
        if rng.random_bool(p_per_m) {
            let start = x + rng.random_range(0.0..1.0);
            let len = if c.gap_max_m > c.gap_min_m {
                rng.random_range(c.gap_min_m..=c.gap_max_m)
            } else {
                c.gap_min_m
            };
            gaps.push((start, start + len));
        }
        x += 1.0;
    }
    gaps
}

/// Scatters the tall weed clumps of a weed patch over every inter-row; returns how many.
fn weed_patch(
    c: &FieldConfig,
    p: &WeedPatch,
    relief: &Relief,
    rng: &mut ChaCha8Rng,
    out: &mut Vec<Prim>,
) -> usize {
    let lanes = c.rows.saturating_sub(1);
    if lanes == 0 {
        return 0;
    }
    let r = 0.5 * p.width_m;
    // Clumps stay clear of the row centres, as the field's own weeds do, and never wider than the lane.
    let half_lane = (0.5 * c.row_spacing_m - WEED_ROW_CLEARANCE_M - r).max(0.0);
    let n = (p.clumps_per_m2 * p.length_m * c.row_spacing_m * f64::from(lanes)).round() as usize;
    for _ in 0..n {
        let x = p.from_x_m + rng.random_range(0.0..=1.0) * p.length_m;
        let lane = rng.random_range(0..lanes);
        let y = row_y_of(c, lane, x) + 0.5 * c.row_spacing_m + rng.random_range(-1.0..=1.0) * half_lane;
        let h = p.height_m * rng.random_range(0.5..=1.0);
        out.push(Prim::spheroid([x, y, relief.height(x, y)], r, h, Class::Weed));
    }
    n
}

/// Stage- and crop-dependent plant proportions.
struct Shape {
    /// Leaves (corn) or trifoliates (soybean) per plant.
    organs: (u32, u32),
    /// Corn leaf length or soybean canopy radius, m.
    reach_m: (f64, f64),
    /// Corn leaf width or soybean leaflet half-length, m.
    leaf_m: f64,
    /// Stalk radius, m.
    stalk_r_m: f64,
}

impl Shape {
    fn new(crop: Crop, stage: Stage) -> Self {
        // Grown canopies must reach past the half inter-row (0.375 m) so that they close over it.
        match (crop, stage) {
            (Crop::Corn, Stage::Young) => {
                Self { organs: (5, 7), reach_m: (0.18, 0.30), leaf_m: 0.05, stalk_r_m: 0.008 }
            }
            (Crop::Corn, Stage::Grown) => {
                Self { organs: (11, 14), reach_m: (0.45, 0.70), leaf_m: 0.10, stalk_r_m: 0.013 }
            }
            (Crop::Soybean, Stage::Young) => {
                Self { organs: (4, 6), reach_m: (0.10, 0.16), leaf_m: 0.035, stalk_r_m: 0.004 }
            }
            (Crop::Soybean, Stage::Grown) => {
                Self { organs: (11, 15), reach_m: (0.36, 0.46), leaf_m: 0.06, stalk_r_m: 0.006 }
            }
        }
    }
}

/// A corn plant: a stalk and arching strap leaves, alternating in one vertical plane (distichous).
fn corn(s: &Shape, base: [f64; 3], h: f64, rng: &mut ChaCha8Rng, out: &mut Vec<Prim>) {
    out.push(Prim::cylinder(base[0], base[1], s.stalk_r_m, base[2], base[2] + 0.8 * h, Class::Crop));
    // The whorl: the youngest leaves, still rolled and erect, make the top of the plant at the stalk, so
    // that (as in a real field) the canopy crest runs along the row and the arching leaves hang below it
    // in the inter-row. Two crossed upright blades, from 0.7 h to the top.
    let turn = rng.random_range(0.0..PI);
    let half_h = 0.15 * h;
    let centre = [base[0], base[1], base[2] + h - half_h];
    for az in [turn, turn + 0.5 * PI] {
        let (sa, ca) = az.sin_cos();
        let w = [ca * 0.5 * s.leaf_m, sa * 0.5 * s.leaf_m, 0.0];
        out.push(Prim::patch(centre, [0.0, 0.0, half_h], w, false, Class::Crop));
    }
    let n = rng.random_range(s.organs.0..=s.organs.1);
    // Field corn tends to turn its leaves across the row, towards the light of the inter-row.
    let plane = 0.5 * PI + rng.random_range(-0.8..0.8);
    for i in 0..n {
        let f = (i as f64 + 0.5) / n as f64;
        // Middle leaves are the longest; upper ones are short and steep.
        let len = rng.random_range(s.reach_m.0..=s.reach_m.1) * (0.65 + 0.45 * (PI * f).sin()).min(1.0);
        let az = plane + if i % 2 == 0 { 0.0 } else { PI } + rng.random_range(-0.35..0.35);
        let a0 = rng.random_range(0.75..1.1) + 0.3 * f;
        let bend = rng.random_range(0.55..0.8);
        let seg = len / 3.0;
        let angles = [a0, a0 - bend, a0 - 2.0 * bend];
        let rise: f64 = angles.iter().take(2).map(|a| seg * a.sin().max(0.0)).sum();
        // Leaves stay below the whorl: their arches top out at 0.85 h.
        let z_attach = (base[2] + h * (0.12 + 0.75 * f)).min(base[2] + 0.85 * h - rise).max(base[2] + 0.02);
        let (sa, ca) = az.sin_cos();
        let side = [-sa, ca, 0.0];
        let mut p = [base[0], base[1], z_attach];
        for (j, a) in angles.iter().enumerate() {
            let (sz, cz) = a.sin_cos();
            let d = [ca * cz * seg, sa * cz * seg, sz * seg];
            let c = [p[0] + 0.5 * d[0], p[1] + 0.5 * d[1], p[2] + 0.5 * d[2]];
            let half_w = 0.5 * s.leaf_m * (1.0 - 0.25 * j as f64);
            let u = [0.5 * d[0], 0.5 * d[1], 0.5 * d[2]];
            let w = [side[0] * half_w, side[1] * half_w, 0.0];
            out.push(Prim::patch(c, u, w, false, Class::Crop));
            p = [p[0] + d[0], p[1] + d[1], (p[2] + d[2]).max(base[2] + 0.01)];
        }
    }
}

/// A soybean plant: a short stem and trifoliate leaves spread over a dome.
fn soybean(s: &Shape, base: [f64; 3], h: f64, rng: &mut ChaCha8Rng, out: &mut Vec<Prim>) {
    out.push(Prim::cylinder(base[0], base[1], s.stalk_r_m, base[2], base[2] + 0.7 * h, Class::Crop));
    let n = rng.random_range(s.organs.0..=s.organs.1);
    let radius = rng.random_range(s.reach_m.0..=s.reach_m.1);
    let half_len = s.leaf_m;
    for _ in 0..n {
        let az = rng.random_range(0.0..TAU);
        let r = radius * rng.random_range(0.0f64..1.0).sqrt();
        let q = r / radius;
        // Dome: the top leaves reach the plant height, the outer ones hang lower.
        let z = base[2] + (h * (1.0 - 0.45 * q * q) - 0.3 * half_len).max(0.03);
        let (sa, ca) = az.sin_cos();
        let tip = [base[0] + r * ca, base[1] + r * sa, z];
        for dir in [az, az + 1.2, az - 1.2] {
            let (sd, cd) = dir.sin_cos();
            // Leaflets tilt down along their length by up to ~30°.
            let tilt = rng.random_range(-0.5..0.15);
            let (st, ct) = f64::sin_cos(tilt);
            let u = [cd * ct * half_len, sd * ct * half_len, st * half_len];
            let hw = 0.6 * half_len;
            let w = [-sd * hw, cd * hw, 0.0];
            let c = [tip[0] + u[0], tip[1] + u[1], tip[2] + u[2]];
            out.push(Prim::patch(c, u, w, true, Class::Crop));
        }
    }
}

/// Scatters weed clumps between the rows; returns how many.
fn weeds(c: &FieldConfig, relief: &Relief, rng: &mut ChaCha8Rng, out: &mut Vec<Prim>) -> usize {
    let width = c.rows.saturating_sub(1) as f64 * c.row_spacing_m + c.row_spacing_m;
    let n = (c.weeds_per_m2 * width * c.length_m).round() as usize;
    let mut placed = 0;
    for _ in 0..n {
        let x = rng.random_range(0.0..=c.length_m);
        let v = rng.random_range(-0.5..(c.rows as f64 - 0.5));
        // Distance to the nearest row centre in row units.
        let off = (v - v.round()).abs() * c.row_spacing_m;
        if off < WEED_ROW_CLEARANCE_M {
            continue;
        }
        let y = v * c.row_spacing_m + c.curve_amplitude_m * (TAU * x / c.curve_wavelength_m).sin();
        let h = rng.random_range(WEED_HEIGHT_M.0..=WEED_HEIGHT_M.1);
        let w = rng.random_range(WEED_WIDTH_M.0..=WEED_WIDTH_M.1);
        let z = relief.height(x, y);
        out.push(Prim::spheroid([x, y, z], 0.5 * w, h, Class::Weed));
        // A couple of smaller satellites give the clump an irregular outline.
        for _ in 0..rng.random_range(0..3u32) {
            let (dx, dy) = (rng.random_range(-0.4..0.4) * w, rng.random_range(-0.4..0.4) * w);
            out.push(Prim::spheroid([x + dx, y + dy, z], 0.25 * w, 0.6 * h, Class::Weed));
        }
        placed += 1;
    }
    placed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn short(crop: Crop, stage: Stage) -> FieldConfig {
        FieldConfig { crop, stage, length_m: 20.0, ..FieldConfig::default() }
    }

    #[test]
    fn same_seed_same_field_different_seed_different_field() {
        let c = short(Crop::Corn, Stage::Young);
        let (a, b, d) = (
            Field::generate(&c, 3).unwrap(),
            Field::generate(&c, 3).unwrap(),
            Field::generate(&c, 4).unwrap(),
        );
        assert_eq!(a.stems(), b.stems());
        assert_ne!(a.stems(), d.stems());
    }

    #[test]
    fn stems_follow_their_rows_and_heights_stay_in_the_stage_range() {
        for (crop, stage) in [(Crop::Corn, Stage::Young), (Crop::Soybean, Stage::Grown)] {
            let c = FieldConfig { curve_amplitude_m: 6.0, ..short(crop, stage) };
            let f = Field::generate(&c, 1).unwrap();
            let (lo, hi) = stage.height_range_m();
            for s in f.stems() {
                // 5σ of the 1 cm position noise.
                assert!((s.y_m - f.row_y(s.row, s.x_m)).abs() < 0.05);
                assert!(s.height_m >= lo && s.height_m <= hi);
            }
            // Missing plants and gaps thin the rows but most plants are there.
            let expected = c.rows as f64 * c.length_m / c.plant_spacing_m;
            assert!(f.stems().len() as f64 > 0.8 * expected, "{} of {expected}", f.stems().len());
        }
    }

    #[test]
    fn absurd_parameters_name_the_field() {
        for (c, name) in [
            (FieldConfig { row_spacing_m: -0.75, ..FieldConfig::default() }, "field.row_spacing_m"),
            (FieldConfig { rows: 0, ..FieldConfig::default() }, "field.rows"),
            (FieldConfig { relief_m: 1.0, ..FieldConfig::default() }, "field.relief_m"),
            (FieldConfig { gap_min_m: 3.0, gap_max_m: 1.0, ..FieldConfig::default() }, "field.gap_max_m"),
            (FieldConfig { length_m: f64::NAN, ..FieldConfig::default() }, "field.length_m"),
            (FieldConfig { curve_amplitude_m: 30.0, ..FieldConfig::default() }, "field.curve_amplitude_m"),
            (FieldConfig { rows: 200, length_m: 2000.0, ..FieldConfig::default() }, "field.plant_spacing_m"),
        ] {
            let e = Field::generate(&c, 0).unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
    }

    #[test]
    fn a_row_gap_removes_only_the_plants_inside_it() {
        use crate::faults::RowGap;
        let c = short(Crop::Corn, Stage::Young);
        let clean = Field::generate(&c, 5).unwrap();
        let faults = FaultConfig {
            row_gap: RowGap { enabled: true, from_x_m: 8.0, length_m: 4.0, rows: vec![7, 8] },
            ..FaultConfig::default()
        };
        let gap = Field::generate_with_faults(&c, &faults, 5).unwrap();
        for row in 0..c.rows {
            // Nominal spots inside the gap, with 5σ of the 1 cm position noise either side.
            let inside = |s: &&Stem| s.x_m > 8.05 && s.x_m < 11.95;
            let kept: Vec<_> = clean.row_stems(row).iter().filter(|s| !inside(s)).collect();
            let got: Vec<_> = gap.row_stems(row).iter().filter(|s| !inside(s)).collect();
            if row == 7 || row == 8 {
                assert_eq!(gap.row_stems(row).iter().filter(inside).count(), 0, "row {row}");
                assert!(clean.row_stems(row).iter().filter(inside).count() > 15, "row {row}");
            } else {
                assert_eq!(gap.row_stems(row), clean.row_stems(row), "row {row}");
            }
            assert!(got.len() <= kept.len() && got.len() + 1 >= kept.len(), "row {row}");
        }
    }

    #[test]
    fn a_weed_patch_adds_tall_weeds_between_the_rows_only() {
        use crate::faults::WeedPatch;
        let c = short(Crop::Corn, Stage::Young);
        let clean = Field::generate(&c, 5).unwrap();
        let huge = FaultConfig {
            weed_patch: WeedPatch {
                enabled: true,
                length_m: 2000.0,
                clumps_per_m2: 50.0,
                ..WeedPatch::default()
            },
            ..FaultConfig::default()
        };
        let e = Field::generate_with_faults(&c, &huge, 5).unwrap_err().to_string();
        assert!(e.contains("faults.weed_patch.clumps_per_m2"), "{e}");
        let faults = FaultConfig {
            weed_patch: WeedPatch { enabled: true, ..WeedPatch::default() },
            ..FaultConfig::default()
        };
        let patch = Field::generate_with_faults(&c, &faults, 5).unwrap();
        // 3 clumps/m² over 3 m of 15 inter-rows 0.75 m wide.
        assert_eq!(patch.weed_count() - clean.weed_count(), 101);
        assert_eq!(patch.stems(), clean.stems());
        // A vertical ray down the middle of a lane inside the patch meets a weed up to 0.5 m tall
        // somewhere; outside the patch the lane is at most the field's own 8 cm weeds.
        let top = |x: f64, y: f64| {
            patch.scene().cast([x as f32, y as f32, 2.0], [0.0, 0.0, -1.0], 3.0).map(|(t, _)| 2.0 - t as f64)
        };
        let tallest_inside =
            (0..300).filter_map(|i| top(8.0 + 0.01 * i as f64, patch.lane_y(7, 0.0))).fold(0.0, f64::max);
        let tallest_outside =
            (0..300).filter_map(|i| top(14.0 + 0.01 * i as f64, patch.lane_y(7, 0.0))).fold(0.0, f64::max);
        assert!(tallest_inside > 0.2 && tallest_inside <= 0.5 + 1e-3, "{tallest_inside}");
        assert!(tallest_outside < 0.09, "{tallest_outside}");
    }

    #[test]
    fn row_in_base_finds_straight_and_curved_rows() {
        let f = Field::generate(&short(Crop::Corn, Stage::Young), 0).unwrap();
        // Robot between rows 7 and 8, heading +x: row 8 is 0.375 m to its left.
        let pose = Pose2::new(5.0, 7.5 * 0.75, 0.0);
        let (off, hd) = f.row_in_base(8, &pose).unwrap();
        assert!((off - 0.375).abs() < 1e-9 && hd.abs() < 1e-12);
        let c = FieldConfig { curve_amplitude_m: 6.0, ..short(Crop::Corn, Stage::Young) };
        let f = Field::generate(&c, 0).unwrap();
        let x = 12.0;
        let pose = Pose2::new(x, f.lane_y(7, x), f.row_heading(x));
        let (off, hd) = f.row_in_base(8, &pose).unwrap();
        // Rows are offset in y, so across a sloped row the perpendicular offset is 0.375·cos(heading),
        // up to the curvature over that short span (2 mm).
        assert!((off - 0.375 * f.row_heading(x).cos()).abs() < 0.002, "{off}");
        assert!(hd.abs() < 0.01, "{hd}");
    }
}
