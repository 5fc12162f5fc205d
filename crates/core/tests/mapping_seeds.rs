//! Robustness of the row extraction: every synthetic scenario over twelve seeds and directions must
//! meet the same bar as the single-field tests (row count, spacing within 1 cm, every row within 3 cm
//! RMS of its true centre).

mod common;

use common::{Crop, Field};
use croprow_core::mapping::{Config, Extractor};

#[test]
fn every_scenario_over_twelve_seeds() {
    let extractor = Extractor::new(Config::default()).unwrap();
    let mut failures = Vec::new();
    let (mut worst_rms, mut worst_spacing) = (0.0f64, 0.0f64);
    for seed in 100..112u64 {
        // Directions spread over the half turn (0.47 rad apart, wrapping).
        let angle_rad = seed as f64 * 0.47;
        let fields = [
            (
                "angle+utm",
                Field { angle_rad, offset: [523_417.3, 4_512_093.8], ..Field::new(seed, Crop::Seedling) },
            ),
            ("curved", Field { curve_m: 6.0, length_m: 30.0, angle_rad, ..Field::new(seed, Crop::Seedling) }),
            (
                "weeds+gaps",
                Field {
                    weeds_per_m2: 0.5,
                    gaps: true,
                    spacing_m: 0.5,
                    angle_rad,
                    ..Field::new(seed, Crop::Seedling)
                },
            ),
            ("maize+gaps", Field { angle_rad, gaps: true, ..Field::new(seed, Crop::Maize) }),
            (
                "relief",
                Field { relief_m: 0.2, angle_rad, weeds_per_m2: 0.2, ..Field::new(seed, Crop::Seedling) },
            ),
            (
                "bushes",
                Field {
                    spacing_m: 1.5,
                    rows: 6,
                    angle_rad,
                    weeds_per_m2: 0.3,
                    ..Field::new(seed, Crop::Bush)
                },
            ),
        ];
        for (name, field) in fields {
            match extractor.extract(&field.cloud()) {
                Ok(map) => {
                    let worst = field.score(&map).iter().map(|(_, rms)| *rms).fold(0.0, f64::max);
                    worst_rms = worst_rms.max(worst);
                    worst_spacing = worst_spacing.max((map.spacing_m - field.spacing_m).abs());
                    if map.rows.len() != field.rows
                        || (map.spacing_m - field.spacing_m).abs() >= 0.01
                        || worst >= 0.03
                    {
                        failures.push(format!(
                            "{name} seed {seed}: {} rows, spacing {:.4} m, worst RMS {worst:.3} m",
                            map.rows.len(),
                            map.spacing_m
                        ));
                    }
                }
                Err(e) => failures.push(format!("{name} seed {seed}: {e}")),
            }
        }
    }
    eprintln!("72 fields: worst row RMS {worst_rms:.4} m, worst spacing error {worst_spacing:.4} m");
    assert!(failures.is_empty(), "{failures:#?}");
}
