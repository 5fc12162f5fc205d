//! Detector accuracy on synthetic VLP-16 scans: both modes on the same fields.
mod support;

use croprow_core::DetectorConfig;
use support::{Field, drive, run};

#[test]
fn probe() {
    let field = Field::default();
    let poses = drive(&field, 0.0, 6.0, 0.1, 0.05, 2f64.to_radians());
    for (name, cfg) in [("default", DetectorConfig::default()), ("paper", DetectorConfig::paper())] {
        let e = run(&field, cfg, &poses, 20, 1);
        println!("{name}: {}", e.summary());
        for d in e.detections.iter().step_by(10) {
            println!(
                "  {:?} {:?} {:?} sp {:?}",
                d.status,
                d.left.map(|r| (r.offset_m, r.heading_rad.to_degrees())),
                d.right.map(|r| r.offset_m),
                d.row_spacing_m
            );
        }
    }
}
