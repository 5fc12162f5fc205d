//! The Navigator end to end with the real detector: ray-cast VLP-16 scans of the detector tests'
//! analytic field (`support`), perfect odometry, an ideal unicycle, 10 Hz scans and control.
//! The lane centre is y = 0, rows run along +x.

mod support;

use croprow_core::control::lane_switch::{LaneSwitchConfig, Mode};
use croprow_core::navigator::{NavInput, Navigator, NavigatorConfig};
use croprow_core::{Mount, Pose2, Scan, Twist2};
use support::{Field, Lidar};

const PERIOD_S: f64 = 0.1;

struct Trace {
    /// (distance travelled m, |cross-track| m) per step.
    errors: Vec<(f64, f64)>,
    final_mode: Mode,
    max_excursion_m: f64,
    final_pose: Pose2,
}

fn run(field: &Field, cfg: NavigatorConfig, start: Pose2, seconds: f64) -> Trace {
    let mount = Mount::default();
    let mut lidar = Lidar::vlp16(3);
    lidar.azimuth_step_deg = 0.4; // half the rays: same geometry, half the test time
    let mut nav = Navigator::new(cfg).unwrap();
    let mut pose = start;
    let mut dist = 0.0;
    let mut errors = vec![];
    let mut final_mode = Mode::Acquiring;
    for i in 0..(seconds / PERIOD_S) as usize {
        let t = i as f64 * PERIOD_S;
        let points = lidar.scan(field, &pose, &mount);
        let out = nav.step(NavInput {
            stamp_s: t,
            odom: pose,
            odom_twist: Twist2::ZERO,
            scan: Some(Scan { stamp_s: t, points: &points }),
            mount: &mount,
            mpc_budget: None,
        });
        assert!(out.cmd.is_finite());
        let mid = pose.yaw + 0.5 * out.cmd.omega * PERIOD_S;
        let next = Pose2::new(
            pose.x + out.cmd.v * PERIOD_S * mid.cos(),
            pose.y + out.cmd.v * PERIOD_S * mid.sin(),
            pose.yaw + out.cmd.omega * PERIOD_S,
        );
        dist += (next.x - pose.x).hypot(next.y - pose.y);
        pose = next;
        errors.push((dist, (pose.y - field.curve(pose.x)).abs()));
        final_mode = out.mode;
        if matches!(out.mode, Mode::Done | Mode::Stopped { .. }) {
            break;
        }
    }
    Trace { errors, final_mode, max_excursion_m: nav.lane_switcher().max_excursion_m(), final_pose: pose }
}

#[test]
fn recovers_to_the_centre_line_with_the_real_detector() {
    let field = Field::young_corn();
    let start = Pose2::new(0.0, 0.3, (-8f64).to_radians());
    let tr = run(&field, NavigatorConfig::default(), start, 16.0);
    assert!(matches!(tr.final_mode, Mode::Following), "{:?}", tr.final_mode);
    let last_bad = tr.errors.iter().rposition(|e| e.1 >= 0.02).unwrap_or(0);
    let settle = tr.errors.get(last_bad + 1).map_or(f64::INFINITY, |e| e.0);
    let tail: Vec<f64> = tr.errors.iter().filter(|e| e.0 > 4.0).map(|e| e.1).collect();
    let mean = tail.iter().sum::<f64>() / tail.len().max(1) as f64;
    eprintln!("real detector, young corn: under 2 cm for good after {settle:.2} m, mean |cross-track| after 4 m {:.2} cm", 100.0 * mean);
    assert!(settle < 3.0, "settled after {settle:.2} m");
    assert!(mean < 0.01, "mean cross-track {mean:.4} m");
}

#[test]
fn stops_past_the_row_end_inside_the_headland() {
    let field = Field { row_end_x_m: Some(8.0), ..Field::young_corn() };
    let cfg = NavigatorConfig { lane_switch: LaneSwitchConfig { lanes: 1, ..LaneSwitchConfig::default() }, ..NavigatorConfig::default() };
    let tr = run(&field, cfg.clone(), Pose2::new(0.0, 0.0, 0.0), 40.0);
    assert_eq!(tr.final_mode, Mode::Done);
    // The rear wheels are past the last plant, and base_link within the 1.5 m headland.
    let past = tr.final_pose.x - 8.0;
    eprintln!("real detector, row end: stopped {past:.3} m past the row end (excursion {:.3} m)", tr.max_excursion_m);
    assert!(past > cfg.lane_switch.wheel_x_m, "stopped {past:.3} m past the end");
    assert!(past <= 1.5, "stopped {past:.3} m past the end");
}
