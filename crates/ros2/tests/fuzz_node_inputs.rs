//! Fuzzing of what the live node takes from the wire: a stream of `/tf_static`, odometry, IMU and
//! `PointCloud2` messages, each mutated CDR (the bytes DDS hands over), decoded and fed to a
//! [`NodeCore`] with its wall clock. Whatever arrives, the node must not panic, every command must be
//! finite, and a command with a halt reason must be zero (the `Output` contract).
//!
//! `CROPROW_FUZZ_EXECS=100000 cargo test -p croprow-ros2 --test fuzz_node_inputs -- --nocapture`

#[path = "../../io/tests/fuzzer/mod.rs"]
mod fuzzer;
mod support;

use croprow_core::{Mount, Pose2, Twist2};
use croprow_io::msg::{self, Imu, Odometry, PointCloud2, TfMessage};
use croprow_ros2::{NodeConfig, NodeCore, Output};
use fuzzer::{Campaign, Verdict};
use support::Field;

/// Executions by default: each runs the detector and the MPC on a few scans (the long run's figures
/// are in docs/fuzzing.md).
const EXECS: usize = 2_000;

const TF_STATIC: u8 = 0;
const ODOMETRY: u8 = 1;
const IMU: u8 = 2;
const CLOUD: u8 = 3;

/// One framed message: `[kind][u32 length LE][CDR bytes]`.
fn frame(out: &mut Vec<u8>, kind: u8, cdr: Vec<u8>) {
    out.push(kind);
    out.extend_from_slice(&(cdr.len() as u32).to_le_bytes());
    out.extend_from_slice(&cdr);
}

/// A robot driving down a lane: `/tf_static`, then odometry at 50 Hz, IMU, and a scan every 0.1 s.
fn drive_seed() -> Vec<u8> {
    let field = Field::default();
    let mount = Mount::default();
    let mut out = Vec::new();
    frame(&mut out, TF_STATIC, msg::encode(&support::tf_static(&mount)).expect("encodes"));
    let cmd = Twist2::new(0.5, 0.0);
    let mut pose = Pose2::default();
    for k in 0..20 {
        let t = 100.0 + 0.02 * k as f64;
        pose = support::drive(pose, cmd, 0.02);
        frame(&mut out, ODOMETRY, msg::encode(&support::odometry(t, pose, cmd)).expect("encodes"));
        frame(&mut out, IMU, msg::encode(&support::imu(t, 0.0)).expect("encodes"));
        if k % 5 == 4 {
            // Every 8th point: a lighter scan keeps executions short and still shows the rows.
            let points: Vec<_> = field.scan(pose, &mount, k).into_iter().step_by(8).collect();
            frame(&mut out, CLOUD, msg::encode(&support::cloud(t, &points)).expect("encodes"));
        }
    }
    out
}

fn check(out: &Output) -> Result<(), String> {
    let (l, a) = (out.cmd_vel.linear, out.cmd_vel.angular);
    if ![l.x, l.y, l.z, a.x, a.y, a.z].iter().all(|v| v.is_finite()) {
        return Err(format!("a non-finite command {:?}", out.cmd_vel));
    }
    if out.halt.is_some() && [l.x, l.y, l.z, a.x, a.y, a.z].iter().any(|v| *v != 0.0) {
        return Err(format!("a halted node commands {:?} ({:?})", out.cmd_vel, out.halt));
    }
    Ok(())
}

#[test]
fn fuzz_node_message_stream() {
    let cfg = NodeConfig::default();
    Campaign::new("node_message_stream", vec![drive_seed()], EXECS).run(|mut bytes| {
        let mut node = NodeCore::new(cfg.clone()).map_err(|e| format!("default config: {e}"))?;
        let mut now_s = 100.0;
        let mut commands = 0usize;
        while let Some((&kind, rest)) = bytes.split_first() {
            let Some((len, rest)) = rest.split_first_chunk::<4>() else { break };
            let (cdr, rest) = rest.split_at_checked(u32::from_le_bytes(*len) as usize).unwrap_or((rest, &[]));
            bytes = rest;
            now_s += 0.01;
            match kind % 4 {
                TF_STATIC => {
                    if let Ok(m) = msg::decode_owned::<TfMessage>(cdr) {
                        node.on_tf_static(&m);
                    }
                }
                ODOMETRY => {
                    if let Ok(m) = msg::decode_owned::<Odometry>(cdr) {
                        let _ = node.on_odometry(now_s, &m).map_err(|e| e.to_string());
                    }
                }
                IMU => {
                    if let Ok(m) = msg::decode_owned::<Imu>(cdr) {
                        let _ = node.on_imu(&m).map_err(|e| e.to_string());
                    }
                }
                _ => {
                    if let Ok(m) = msg::decode::<PointCloud2<'_>>(cdr)
                        && let Ok(out) = node.on_cloud(now_s, &m)
                    {
                        check(&out)?;
                        commands += 1;
                    }
                }
            }
            check(&node.tick(now_s))?;
        }
        Ok(if commands > 0 { Verdict::Accepted } else { Verdict::Rejected })
    });
}
