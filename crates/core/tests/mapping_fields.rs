//! Whole-field row extraction on seeded synthetic fields: straight rows at an arbitrary angle with a
//! UTM-like offset, curved rows, seedlings, tall closed-canopy maize, weeds and gaps, terrain relief.
//!
//! Every test asserts the row count, the spacing within 1 cm and every polyline within 3 cm (RMS) of
//! its true row centre. The lateral error is measured against the true centre line extended 1 m past
//! the row ends, so it scores where the centre is, not how far the trace runs past the last plant.

use croprow_core::mapping::{Config, Extractor, RowMap};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

#[derive(Debug, Clone, Copy, PartialEq)]
enum Crop {
    /// 5-10 cm tall, a few sparse points each.
    Seedling,
    /// 2-2.4 m tall, stalks plus leaves spreading ±0.45 m from 0.6 m up: the canopy closes.
    Maize,
}

#[derive(Debug, Clone)]
struct Field {
    seed: u64,
    rows: usize,
    spacing_m: f64,
    length_m: f64,
    /// Row direction in the cloud frame, rad.
    angle_rad: f64,
    /// Added to every x, y (UTM-like), m.
    offset: [f64; 2],
    /// Amplitude of the reference curve `v = a sin(2π u / 100)`, m; rows are its parallel offsets
    /// (constant spacing across the rows, as a planter makes them).
    curve_m: f64,
    crop: Crop,
    weeds_per_m2: f64,
    /// Gaps of 1.5 m per row (at a seeded position).
    gaps: bool,
    /// Peak-to-peak terrain relief, m.
    relief_m: f64,
}

impl Field {
    fn new(seed: u64, crop: Crop) -> Self {
        Self {
            seed,
            rows: 8,
            spacing_m: 0.76,
            length_m: 20.0,
            angle_rad: 0.0,
            offset: [0.0, 0.0],
            curve_m: 0.0,
            crop,
            weeds_per_m2: 0.0,
            gaps: false,
            relief_m: 0.0,
        }
    }

    /// Reference curve and its unit normal in the row frame (u along, v across).
    fn curve(&self, u: f64) -> ([f64; 2], [f64; 2]) {
        let k = std::f64::consts::TAU / 100.0;
        let slope = self.curve_m * k * (k * u).cos();
        let norm = (1.0 + slope * slope).sqrt();
        ([u, self.curve_m * (k * u).sin()], [-slope / norm, 1.0 / norm])
    }

    /// Row `r`'s centre at parameter `u`, plus `lateral_m` along the normal, in the cloud frame.
    fn row_point(&self, r: usize, u: f64, lateral_m: f64) -> [f64; 2] {
        let (c, n) = self.curve(u);
        let v = (r as f64 - (self.rows as f64 - 1.0) / 2.0) * self.spacing_m + lateral_m;
        self.to_cloud([c[0] + n[0] * v, c[1] + n[1] * v])
    }

    fn to_cloud(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.angle_rad.sin_cos();
        [c * p[0] - s * p[1] + self.offset[0], s * p[0] + c * p[1] + self.offset[1]]
    }

    fn ground_z(&self, x: f64, y: f64) -> f64 {
        let (x, y) = (x - self.offset[0], y - self.offset[1]);
        self.relief_m * (0.35 * (x / 4.0).sin() + 0.15 * (y / 3.0).cos())
    }

    fn cloud(&self) -> Vec<[f64; 3]> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let noise = Normal::new(0.0, 0.005).unwrap();
        let jitter = Normal::new(0.0, 0.01).unwrap();
        let mut pts = Vec::new();
        let width = (self.rows as f64 * self.spacing_m).max(6.0) + 1.0;
        let area = (self.length_m + 2.0) * width;
        // Ground over the field plus 1 m at each end.
        for _ in 0..(area * 150.0) as usize {
            let u = rng.random_range(-1.0..self.length_m + 1.0);
            let v = rng.random_range(-width / 2.0..width / 2.0);
            let (c, n) = self.curve(u);
            let [x, y] = self.to_cloud([c[0] + n[0] * v, c[1] + n[1] * v]);
            pts.push([x, y, self.ground_z(x, y) + noise.sample(&mut rng)]);
        }
        for r in 0..self.rows {
            let gap_at = rng.random_range(3.0..self.length_m - 5.0);
            let mut u = 0.0;
            while u < self.length_m {
                u += rng.random_range(0.12..0.22);
                if self.gaps && (gap_at..gap_at + 1.5).contains(&u) {
                    continue;
                }
                let lateral = jitter.sample(&mut rng);
                self.plant(&mut rng, r, u, lateral, &mut pts);
            }
        }
        for _ in 0..(area * self.weeds_per_m2) as usize {
            let u = rng.random_range(0.0..self.length_m);
            let v = rng.random_range(-width / 2.0..width / 2.0);
            let (c, n) = self.curve(u);
            for _ in 0..12 {
                let [x, y] = self.to_cloud([c[0] + n[0] * v, c[1] + n[1] * v]);
                let (dx, dy) = (rng.random_range(-0.04..0.04), rng.random_range(-0.04..0.04));
                pts.push([x + dx, y + dy, self.ground_z(x, y) + rng.random_range(0.0..0.08)]);
            }
        }
        pts
    }

    fn plant(&self, rng: &mut ChaCha8Rng, r: usize, u: f64, lateral: f64, pts: &mut Vec<[f64; 3]>) {
        let mut put = |du: f64, dv: f64, h: f64| {
            let [x, y] = self.row_point(r, u + du, lateral + dv);
            pts.push([x, y, self.ground_z(x, y) + h]);
        };
        match self.crop {
            Crop::Seedling => {
                let height = rng.random_range(0.05..0.10);
                for _ in 0..15 {
                    let h = rng.random_range(0.0..height);
                    let spread = 0.03 * h / height;
                    let (du, dv) = (rng.random_range(-spread..=spread), rng.random_range(-spread..=spread));
                    put(du, dv, h);
                }
            }
            Crop::Maize => {
                let height = rng.random_range(2.0..2.4);
                for _ in 0..20 {
                    let (du, dv) = (rng.random_range(-0.01..0.01), rng.random_range(-0.01..0.01));
                    put(du, dv, rng.random_range(0.0..height));
                }
                for _ in 0..60 {
                    let h = rng.random_range(0.6..height);
                    let (du, dv) = (rng.random_range(-0.3..0.3), rng.random_range(-0.45..0.45));
                    put(du, dv, h);
                }
            }
        }
    }

    /// Lateral RMS error (m) of every extracted row against its nearest true row, and the true rows
    /// each extracted row matched (in order).
    fn score(&self, map: &RowMap) -> Vec<(usize, f64)> {
        let truth: Vec<Vec<[f64; 2]>> = (0..self.rows)
            .map(|r| {
                (0..=((self.length_m + 2.0) / 0.02) as usize)
                    .map(|i| self.row_point(r, i as f64 * 0.02 - 1.0, 0.0))
                    .collect()
            })
            .collect();
        map.rows
            .iter()
            .map(|row| {
                let mut best = (usize::MAX, f64::INFINITY);
                for (r, line) in truth.iter().enumerate() {
                    let sq: f64 = row.polyline.iter().map(|p| nearest_sq(*p, line)).sum();
                    let rms = (sq / row.polyline.len() as f64).sqrt();
                    if rms < best.1 {
                        best = (r, rms);
                    }
                }
                best
            })
            .collect()
    }
}

/// Squared distance from `p` to the nearest sample of a densely sampled (2 cm) line; the sampling adds
/// at most 0.1 mm.
fn nearest_sq(p: [f64; 2], line: &[[f64; 2]]) -> f64 {
    line.iter().map(|q| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).fold(f64::INFINITY, f64::min)
}

/// Extracts the rows and checks count, spacing (1 cm), per-row RMS (3 cm) and order across the field.
fn check(field: &Field) -> RowMap {
    let map = Extractor::new(Config::default()).unwrap().extract(&field.cloud()).unwrap();
    assert_eq!(map.rows.len(), field.rows, "row count; slice {:?}", map.slice);
    assert!(
        (map.spacing_m - field.spacing_m).abs() < 0.01,
        "spacing {} vs {}",
        map.spacing_m,
        field.spacing_m
    );
    let scores = field.score(&map);
    for (i, (r, rms)) in scores.iter().enumerate() {
        assert!(*rms < 0.03, "row {i} (true {r}) RMS {rms:.4} m");
    }
    let worst = scores.iter().map(|(_, rms)| *rms).fold(0.0, f64::max);
    eprintln!(
        "rows {} spacing error {:+.4} m worst row RMS {worst:.4} m",
        map.rows.len(),
        map.spacing_m - field.spacing_m
    );
    let matched: Vec<usize> = scores.iter().map(|(r, _)| *r).collect();
    let ascending: Vec<usize> = (0..field.rows).collect();
    let descending: Vec<usize> = (0..field.rows).rev().collect();
    assert!(matched == ascending || matched == descending, "rows out of order: {matched:?}");
    for (i, row) in map.rows.iter().enumerate() {
        assert_eq!(row.index, i);
        assert!(row.length_m > 0.8 * field.length_m, "row {i} is {} m long", row.length_m);
    }
    map
}

#[test]
fn straight_rows_at_an_angle_with_utm_offset() {
    let field = Field {
        angle_rad: 37f64.to_radians(),
        offset: [523_417.3, 4_512_093.8],
        ..Field::new(1, Crop::Seedling)
    };
    let map = check(&field);
    let err = (map.direction_rad - field.angle_rad).abs();
    assert!(err.min(std::f64::consts::PI - err) < 1f64.to_radians(), "direction {}", map.direction_rad);
    // Coordinates stay in the cloud's frame.
    assert!(map.rows.iter().all(|r| r.polyline.iter().all(|p| p[0] > 523_000.0 && p[1] > 4_512_000.0)));
}

#[test]
fn curved_rows() {
    check(&Field { curve_m: 6.0, length_m: 30.0, angle_rad: -0.4, ..Field::new(2, Crop::Seedling) });
}

#[test]
fn seedlings_with_weeds_and_gaps() {
    check(&Field { weeds_per_m2: 0.5, gaps: true, spacing_m: 0.5, ..Field::new(3, Crop::Seedling) });
}

#[test]
fn tall_closed_canopy_maize_is_found_by_its_stalks() {
    let map = check(&Field { angle_rad: 1.2, ..Field::new(4, Crop::Maize) });
    // The stalks, not the canopy: the chosen slice starts near the ground.
    assert!(map.slice.min_m < 0.5 && map.slice.max_m < 1.5, "{:?}", map.slice);
}

#[test]
fn terrain_relief() {
    check(&Field { relief_m: 0.2, angle_rad: 2.5, weeds_per_m2: 0.2, ..Field::new(5, Crop::Seedling) });
}

#[test]
fn weeds_alone_are_no_rows() {
    let field = Field { rows: 0, weeds_per_m2: 3.0, ..Field::new(6, Crop::Seedling) };
    let cloud = field.cloud();
    let err = Extractor::new(Config::default()).unwrap().extract(&cloud).unwrap_err();
    assert!(err.to_string().contains("no row pattern"), "{err}");
}
