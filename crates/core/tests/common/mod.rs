//! Seeded synthetic whole fields for the mapping tests and bench: rows along a reference curve (or
//! straight) at any angle and offset, seedlings or tall closed-canopy maize, weeds, gaps, relief.

#![allow(dead_code)]

use croprow_core::mapping::RowMap;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Crop {
    /// 5-10 cm tall, a few sparse points each.
    Seedling,
    /// 2-2.4 m tall, stalks plus leaves spreading ±0.45 m from 0.6 m up: the canopy closes.
    Maize,
    /// 0.4-0.6 m tall bushes (soybean-like), an open canopy ±0.2 m wide at every height.
    Bush,
}

#[derive(Debug, Clone)]
pub struct Field {
    pub seed: u64,
    pub rows: usize,
    pub spacing_m: f64,
    pub length_m: f64,
    /// Row direction in the cloud frame, rad.
    pub angle_rad: f64,
    /// Added to every x, y (UTM-like), m.
    pub offset: [f64; 2],
    /// Amplitude of the reference curve `v = a sin(2π u / 100)`, m; rows are its parallel offsets
    /// (constant spacing across the rows, as a planter makes them).
    pub curve_m: f64,
    pub crop: Crop,
    pub weeds_per_m2: f64,
    /// Gaps of 1.5 m per row (at a seeded position).
    pub gaps: bool,
    /// Peak-to-peak terrain relief, m.
    pub relief_m: f64,
    /// Ground points per square metre (150 by default; a terrestrial scan has thousands).
    pub ground_per_m2: f64,
    /// Points per plant, relative to the default (15 per seedling, 80 per maize plant).
    pub plant_points: usize,
}

impl Field {
    pub fn new(seed: u64, crop: Crop) -> Self {
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
            ground_per_m2: 150.0,
            plant_points: 1,
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
    pub fn row_point(&self, r: usize, u: f64, lateral_m: f64) -> [f64; 2] {
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

    pub fn cloud(&self) -> Vec<[f64; 3]> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let noise = Normal::new(0.0, 0.005).unwrap();
        let jitter = Normal::new(0.0, 0.01).unwrap();
        let mut pts = Vec::new();
        let width = (self.rows as f64 * self.spacing_m).max(6.0) + 1.0;
        let area = (self.length_m + 2.0) * width;
        // Ground over the field plus 1 m at each end.
        for _ in 0..(area * self.ground_per_m2) as usize {
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
                for _ in 0..15 * self.plant_points {
                    let h = rng.random_range(0.0..height);
                    let spread = 0.03 * h / height;
                    let (du, dv) = (rng.random_range(-spread..=spread), rng.random_range(-spread..=spread));
                    put(du, dv, h);
                }
            }
            Crop::Bush => {
                let height = rng.random_range(0.4..0.6);
                for _ in 0..40 * self.plant_points {
                    let h = rng.random_range(0.05..height);
                    let (du, dv) = (rng.random_range(-0.1..0.1), rng.random_range(-0.2..0.2));
                    put(du, dv, h);
                }
            }
            Crop::Maize => {
                let height = rng.random_range(2.0..2.4);
                for _ in 0..20 * self.plant_points {
                    let (du, dv) = (rng.random_range(-0.01..0.01), rng.random_range(-0.01..0.01));
                    put(du, dv, rng.random_range(0.0..height));
                }
                for _ in 0..60 * self.plant_points {
                    let h = rng.random_range(0.6..height);
                    let (du, dv) = (rng.random_range(-0.3..0.3), rng.random_range(-0.45..0.45));
                    put(du, dv, h);
                }
            }
        }
    }

    /// Lateral RMS error (m) of every extracted row against its nearest true row, and the true rows
    /// each extracted row matched (in order).
    pub fn score(&self, map: &RowMap) -> Vec<(usize, f64)> {
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
