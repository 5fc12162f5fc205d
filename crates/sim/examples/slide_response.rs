//! The detector alone against odometry that drifts the way an unsensed slide or gyro bias makes it
//! drift: the robot drives exactly down its lane centre (so the true rows in `base_link` never move),
//! while the odometry pose given to the detector slides sideways by `slide` m per metre, or turns by
//! `turn` rad per metre, from x = 4 m on. Prints the detector's lane-centre error every metre (the
//! true answer is 0) and the largest one. With `register`, `crab` and `overcount` it shows why
//! registration under-reads a wheel slide that the robot crabs against (docs/faults.md, session 43).
//!
//! ```text
//! cargo run --release -p croprow-sim --example slide_response -- grown-corn 0.05 0 0 20 register
//! ```
//!
//! Arguments: scenario (default grown-corn), slide m/m (default 0.05), turn rad/m (default 0), a step
//! of the odometry sideways at the onset, m (default 0), print every N scans (default 20), then the
//! words `register` (canopy registration on, `detector.register_enabled`), `noshear` (the fit's
//! shear term off, `detector.shear_enabled`), `truth` (the robot truly slides across the rows and the
//! odometry runs straight down the lane centre, instead of the odometry drifting off a robot on the
//! centre line), `crab=RAD` (the robot heads this far to the left of the rows while it drives along
//! them, as it does against a slide; default 0) and `overcount=R` (from the start the odometry puts
//! the robot (1 + R) times as far along its heading as it truly went, as wheels that slip do;
//! default 0).
//!
//! ```text
//! cargo run --release -p croprow-sim --example slide_response -- grown-soybean 0 0 0 1000 register crab=-0.06 overcount=0.45
//! ```

use croprow_core::{DetectorConfig, Pose2, RowDetector, Scan};
use croprow_sim::{BodyPose, Field, Lidar, ScanBuffer, Scenario};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map(String::as_str).unwrap_or("grown-corn");
    let slide: f64 = args.get(1).map(|a| a.parse()).transpose()?.unwrap_or(0.05);
    let turn: f64 = args.get(2).map(|a| a.parse()).transpose()?.unwrap_or(0.0);
    let jump: f64 = args.get(3).map(|a| a.parse()).transpose()?.unwrap_or(0.0);
    let every: usize = args.get(4).map(|a| a.parse()).transpose()?.unwrap_or(20);
    let mut s = Scenario::builtin(name)?;
    s.field.length_m = 24.0;
    let field = Field::generate(&s.field, s.seed)?;
    let mut lidar = Lidar::new(&s.lidar, 1)?;
    let word = |w: &str| args.iter().skip(5).any(|a| a == w);
    let value = |key: &str| -> Result<f64, Box<dyn std::error::Error>> {
        let Some(text) = args.iter().skip(5).find_map(|a| a.strip_prefix(key)?.strip_prefix('=')) else {
            return Ok(0.0);
        };
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!("`{key}={text}`: expected a finite number").into()),
        }
    };
    let (truly_slides, crab, overcount) = (word("truth"), value("crab")?, value("overcount")?);
    let cfg = DetectorConfig {
        register_enabled: word("register"),
        shear_enabled: !word("noshear"),
        ..Default::default()
    };
    let mut det = RowDetector::new(cfg)?;
    let mut scan = ScanBuffer::default();
    let lane = s.lane();
    let (step_m, onset_m) = (0.05, 4.0);
    let mut worst: f64 = 0.0;
    let (mut sum_abs, mut scored) = (0.0, 0usize);
    let mut x = 1.0;
    let mut k = 0;
    while x < 20.0 {
        let d = f64::max(x - onset_m, 0.0);
        let slid = if truly_slides { slide * d } else { 0.0 };
        let truth = Pose2::new(x, field.lane_y(lane, x) - slid, field.row_heading(x) + crab);
        lidar.scan(&field, &BodyPose::planar(truth), &mut scan);
        let yaw_err = turn * d;
        // Odometry's pose: the true one moved sideways (slide) and turned (the turn's heading error
        // integrated into position too).
        let lateral = slide * d + 0.5 * turn * d * d + if d > 0.0 { jump } else { 0.0 };
        let (sn, cs) = truth.yaw.sin_cos();
        // With `truth`, the lateral term brings the odometry back onto the lane centre.
        let ahead = overcount * (x - 1.0);
        let odom = Pose2::new(
            truth.x - sn * lateral + cs * ahead,
            truth.y + cs * lateral + sn * ahead,
            truth.yaw + yaw_err,
        );
        let det_out = det.detect(
            Scan { stamp_s: 0.1 * k as f64, points: &scan.points, twist: None, attitude: None },
            odom,
            &s.lidar.mount,
        );
        // The lane centre lies `slid` to the left of a robot that truly slid.
        let centre = match (det_out.left, det_out.right) {
            (Some(l), Some(r)) => Some(0.5 * (l.offset_m + r.offset_m) - slid),
            _ => None,
        };
        if let Some(c) = centre
            && x > onset_m
        {
            worst = worst.max(c.abs());
            sum_abs += c.abs();
            scored += 1;
        }
        if k % every == 0 {
            println!(
                "x {x:5.2} m  odom off {:6.3} m  centre error {}  status {:?}",
                lateral,
                centre.map_or("   --   ".into(), |c| format!("{c:+.3} m")),
                det_out.status
            );
        }
        x += step_m;
        k += 1;
    }
    println!(
        "{name}: slide {slide} m/m, turn {turn} rad/m: worst centre error after onset {worst:.3} m, mean {:.4} m over {scored} scans",
        sum_abs / scored.max(1) as f64
    );
    Ok(())
}
