//! Row following under the MPC on 20 m of each Table I field, closed loop with the EKF, against the
//! paper's Table I cross-track means (Sec. V-B) and our aims (< 1 cm straight, < 3 cm curved).

use croprow_core::control::lane_switch::Mode;
use croprow_sim::Scenario;
use croprow_sim::closed_loop::{self, Run, RunConfig};

/// Runs `name` shortened to `length_m`, one lane.
fn follow(name: &str, length_m: f64) -> Run {
    let mut s = Scenario::builtin(name).unwrap();
    s.field.length_m = length_m;
    let cfg = RunConfig { lanes: 1, ..RunConfig::default() };
    closed_loop::run(&s, closed_loop::sim_navigator(), cfg, |_| {}).unwrap()
}

/// Asserts a clean single-lane run with a cross-track mean under `limit_m`.
fn check(name: &str, limit_m: f64) {
    let run = follow(name, 20.0);
    let m = &run.metrics;
    eprintln!("{name}: {m:?}");
    assert_eq!(m.final_mode, Mode::Done, "{name}: {m:?}");
    assert_eq!(m.lanes_completed, 1);
    assert_eq!(m.crop_contacts, 0, "{name}");
    assert_eq!(m.command_violations, 0, "{name}");
    assert!(m.following_samples > 200, "{name}: {m:?}");
    assert!(m.cross_track_mean_m < limit_m, "{name}: {:.2} cm", m.cross_track_mean_m * 100.0);
}

#[test]
fn young_corn_beats_the_paper() {
    check("young-corn", 0.0097);
}

#[test]
fn debug_trace() {
    let mut sc = Scenario::builtin("young-corn").unwrap();
    sc.field.length_m = 20.0;
    if std::env::var("PERFECT").is_ok() {
        sc.sensors.perfect_odometry = true;
    }
    if std::env::var("SCALE0").is_ok() {
        sc.sensors.encoder_scale_error = 0.0;
        sc.robot.longitudinal_slip = 0.0;
        sc.robot.slip_variation = 0.0;
    }
    if std::env::var("NODIST").is_ok() {
        sc.robot.yaw_disturbance_rad_s = 0.0;
    }
    if std::env::var("NOBIAS").is_ok() {
        sc.sensors.gyro_bias_rad_s = 0.0;
    }
    if std::env::var("NOSLIP").is_ok() {
        sc.robot.lateral_slip_gain = 0.0;
        sc.robot.slip_variation = 0.0;
    }
    let cfg = RunConfig { lanes: 1, ..RunConfig::default() };
    let mut nc = closed_loop::sim_navigator();
    if let Ok(v) = std::env::var("WYAW") {
        nc.ekf.wheel_yaw_rate_std_radps = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("BWALK") {
        nc.ekf.gyro_bias_walk = v.parse().unwrap();
    }
    let run = closed_loop::run(&sc, nc, cfg, |_| {}).unwrap();
    eprintln!("{:?}", run.metrics);
    for s in run.samples.iter().filter(|s| s.detection.is_some()).step_by(5) {
        eprintln!(
            "t={:.1} truth=({:.3},{:.3},{:.3}) odom=({:.3},{:.3},{:.3}) cmd=({:.2},{:.3}) {:?} lane={} ct={:.3} he={:.3} det={:?}",
            s.t_s,
            s.truth.x,
            s.truth.y,
            s.truth.yaw,
            s.odom.x,
            s.odom.y,
            s.odom.yaw,
            s.cmd.v,
            s.cmd.omega,
            s.mode.as_str(),
            s.lane,
            s.cross_track_m,
            s.heading_err_rad,
            s.detection
        );
    }
}

#[test]
fn debug_detect() {
    let mut sc = Scenario::builtin("young-corn").unwrap();
    sc.field.length_m = 20.0;
    if std::env::var("PERFECT").is_ok() {
        sc.sensors.perfect_odometry = true;
    }
    let mut nc = closed_loop::sim_navigator();
    if std::env::var("PAPER").is_ok() {
        nc.detector = croprow_core::DetectorConfig::paper();
    }
    let cfg = RunConfig { lanes: 1, ..RunConfig::default() };
    let mut lp = croprow_sim::ClosedLoop::new(&sc, &nc, cfg).unwrap();
    let mut k = 0;
    while !lp.is_finished() {
        lp.step().unwrap();
        let tick = lp.last_tick().unwrap();
        let truth = tick.step.truth.pose;
        let odom = tick.odom;
        let Some(out) = tick.nav else { continue };
        let bias = lp.ekf().map(|e| e.gyro_bias_radps());
        let Some(det) = out.detection else { continue };
        k += 1;
        if k % 5 != 0 {
            continue;
        }
        let e = croprow_sim::metrics::score_detection(lp.world().field(), &truth, &det);
        let fr = out.tracking.map(|f| (f.lateral_m, f.heading_rad));
        eprintln!(
            "b={:?} t={:.1} x={:.2} dyaw={:.3} dl={:?} dr={:?} frenet={:?} cmd=({:.2},{:.3})",
            bias.map(|b| (b * 10000.0).round()),
            out.stamp_s,
            truth.x,
            odom.yaw - truth.yaw,
            e.left.map(|r| (r.distance_m * 100.0).round()),
            e.right.map(|r| (r.distance_m * 100.0).round()),
            fr.map(|(a, b)| ((a * 1000.0).round() / 1000.0, (b * 1000.0).round() / 1000.0)),
            out.cmd.v,
            out.cmd.omega
        );
    }
    eprintln!("{:?}", lp.finish().metrics);
}
