//! Whole-field row extraction on a 30 m x 12 m field (16 rows) at terrestrial-scanner density,
//! about 2 M points: tall closed-canopy maize and seedlings.
//!
//! `cargo bench -p croprow-core --bench mapping -- --warm-up-time 1 --measurement-time 3`

use criterion::{Criterion, criterion_group, criterion_main};
use croprow_core::mapping::{Config, Extractor};

#[path = "../tests/common/mod.rs"]
mod common;

use common::{Crop, Field};

fn field(crop: Crop, plant_points: usize, ground_per_m2: f64) -> Vec<[f64; 3]> {
    Field {
        rows: 16,
        length_m: 30.0,
        angle_rad: 0.6,
        offset: [431_250.0, 5_210_480.0],
        ground_per_m2,
        plant_points,
        ..Field::new(7, crop)
    }
    .cloud()
}

fn bench(c: &mut Criterion) {
    let extractor = Extractor::new(Config::default()).unwrap();
    let mut group = c.benchmark_group("mapping");
    group.sample_size(10);
    for (name, cloud) in [
        ("maize_30x12m", field(Crop::Maize, 3, 3000.0)),
        ("seedlings_30x12m", field(Crop::Seedling, 8, 3500.0)),
    ] {
        let map = extractor.extract(&cloud).unwrap();
        eprintln!("{name}: {} points, {} rows, spacing {:.4} m", cloud.len(), map.rows.len(), map.spacing_m);
        group.bench_function(name, |b| b.iter(|| extractor.extract(std::hint::black_box(&cloud)).unwrap()));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
