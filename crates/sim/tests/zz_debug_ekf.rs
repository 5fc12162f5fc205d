use croprow_core::Twist2;
use croprow_core::odometry::Ekf;
use croprow_sim::{Scenario, World};

#[test]
fn debug_ekf_turn() {
    let mut sc = Scenario::builtin("full-field").unwrap();
    if std::env::var("NODIST").is_ok() {
        sc.robot.yaw_disturbance_rad_s = 0.0;
    }
    if std::env::var("NOLAT").is_ok() {
        sc.robot.lateral_slip_gain = 0.0;
    }
    let mut w = World::new(&sc).unwrap();
    let mut ekf = Ekf::new(croprow_sim::experiment::detection::ekf_config()).unwrap();
    ekf.reset(0.0, w.robot().pose()).unwrap();
    let mut gyro_int = w.robot().pose().yaw;
    for i in 0..1600 {
        let t = i as f64 * 0.01;
        let cmd = if t < 3.0 {
            Twist2::ZERO
        } else if t < 8.0 {
            Twist2::new(0.3, 0.0)
        } else {
            Twist2::new(0.2, 0.9)
        };
        let s = w.step(cmd).unwrap();
        if let Some(wh) = s.wheel {
            ekf.update_wheel(wh.stamp_s, wh.twist.v, wh.twist.omega).unwrap();
        }
        if let Some(imu) = s.imu {
            ekf.update_imu(imu.stamp_s, imu.gyro_z_rad_s).unwrap();
            gyro_int += (imu.gyro_z_rad_s - 0.005) * 0.01;
        }
        if i % 100 == 0 {
            let truth = s.truth.pose;
            eprintln!("dx={:.3} dy={:.3}", ekf.pose().x - truth.x, ekf.pose().y - truth.y);
            eprintln!(
                "t={:.1} truth_yaw={:.3} ekf_yaw={:.3} d={:.4} gyroint_d={:.4} bias={:.4} v={:.3} true_v={:.3} w={:.3} true_w={:.3}",
                t,
                truth.yaw,
                ekf.pose().yaw,
                ekf.pose().yaw - truth.yaw,
                gyro_int - truth.yaw,
                ekf.gyro_bias_radps(),
                ekf.twist().v,
                s.true_twist.v,
                ekf.twist().omega,
                s.true_twist.omega
            );
        }
    }
}
