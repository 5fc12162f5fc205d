//! Cost of the default detector's `detect` on the criterion bench's scans (a full organised VLP-16
//! revolution over a closed grown canopy), for profiling where criterion's wall times are noisy: prints
//! the CPU time per call and a hash of every detection, so that a change to the detector can be checked
//! to leave its output bit for bit the same. Instruction counts:
//!
//! ```text
//! cargo build --release -p croprow-core --example detect_cost
//! valgrind --tool=callgrind --toggle-collect='*RowDetector*detect*' target/release/examples/detect_cost 20
//! ```
//!
//! Arguments: timed calls (default 200), then `register` to time the detector with canopy registration
//! on and the robot moving a keyframe (0.15 m) per call, so that every timed call registers. The hash covers a warm-up over 40 scans of three fixtures
//! (grown closed canopy, young rows with weeds and gaps, curved rows) as well as the timed calls.

use std::hash::{DefaultHasher, Hash, Hasher};
use std::time::Instant;

use croprow_core::{Detection, DetectorConfig, Mount, Point3, Pose2, RowDetector, Scan};

#[path = "../tests/support/mod.rs"]
mod support;

fn hash_detection(h: &mut DefaultHasher, d: &Detection) {
    format!("{d:?}").hash(h);
}

fn scans(field: &support::Field, seed: u64) -> Vec<(Pose2, Vec<Point3>)> {
    let mut lidar = support::Lidar::vlp16(seed);
    lidar.organized = true;
    (0..40)
        .map(|i| {
            let pose = Pose2::new(0.1 * i as f64, 0.02 + 0.002 * i as f64, 0.01);
            let pts = lidar.scan(field, &pose, &Mount::default());
            (pose, pts)
        })
        .collect()
}

fn main() {
    let calls: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(200);
    let register = std::env::args().nth(2).is_some_and(|a| a == "register");
    let config = DetectorConfig { register_enabled: register, ..DetectorConfig::default() };
    let mount = Mount::default();
    let mut hash = DefaultHasher::new();
    let weedy = support::Field {
        weed_density: 0.3,
        gaps: vec![(0, 1.5, 2.5), (-1, 3.0, 3.6)],
        plant_height_m: 0.3,
        ..support::Field::default()
    };
    let curved =
        support::Field { curve_amplitude_m: 1.0, curve_wavelength_m: 30.0, ..support::Field::default() };
    let mut timed = None;
    for (name, field) in [("curved", curved), ("weedy", weedy), ("grown", support::Field::grown_closed())] {
        let scans = scans(&field, 42);
        let mut det = RowDetector::new(config.clone()).expect("valid config");
        for (i, (pose, pts)) in scans.iter().enumerate() {
            let d = det.detect(
                Scan { stamp_s: 0.1 * i as f64, points: pts, twist: None, attitude: None },
                *pose,
                &mount,
            );
            hash_detection(&mut hash, &d);
        }
        eprintln!("{name}: warm-up hashed");
        timed = Some((det, scans));
    }
    let (mut det, scans) = timed.expect("fixtures");
    let (mut pose, pts) = scans.last().cloned().expect("scans");
    let mut t = 0.1 * scans.len() as f64;
    let start = Instant::now();
    for _ in 0..calls {
        t += 0.1;
        if register {
            pose.x += 0.15;
        }
        let d = det.detect(Scan { stamp_s: t, points: &pts, twist: None, attitude: None }, pose, &mount);
        hash_detection(&mut hash, &d);
    }
    let per_call_us = start.elapsed().as_secs_f64() * 1e6 / calls as f64;
    println!(
        "default detect{}: {per_call_us:.1} us per call (wall, {calls} calls incl. hashing), detection hash {:016x}",
        if register { " (registering every call)" } else { "" },
        hash.finish()
    );
}
