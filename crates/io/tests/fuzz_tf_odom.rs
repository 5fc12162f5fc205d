//! Fuzzing of the two decoders that turn outside messages into poses: `/tf_static` (`TFMessage` ->
//! [`TransformBuffer`] -> lookups through chains) and odometry (`Odometry` -> [`History`] ->
//! interpolated poses). Mutated CDR must decode or fail with a `CdrError`; whatever decodes must give
//! finite transforms and poses or a documented refusal (`LookupError`, `PoseGap`, `Backwards`), never
//! a non-finite pose handed on as if it were valid.
//!
//! `CROPROW_FUZZ_EXECS=100000 cargo test --release -p croprow-io --test fuzz_tf_odom -- --nocapture`

mod fuzzer;

use croprow_core::Pose2;
use croprow_io::msg::{
    self, Header, Odometry, Quaternion, TfMessage, Time, Transform, TransformStamped, Vector3,
};
use croprow_io::odom::History;
use croprow_io::tf::TransformBuffer;
use fuzzer::{Campaign, Verdict};

/// Executions per campaign by default (the long run's figures are in docs/fuzzing.md).
const EXECS: usize = 20_000;

fn edge(parent: &str, child: &str, t: [f64; 3], q: Quaternion) -> TransformStamped {
    TransformStamped {
        header: Header { stamp: Time { sec: 1, nanosec: 0 }, frame_id: parent.into() },
        child_frame_id: child.into(),
        transform: Transform { translation: Vector3 { x: t[0], y: t[1], z: t[2] }, rotation: q },
    }
}

#[test]
fn fuzz_tf_static_lookups() {
    let chain = TfMessage {
        transforms: vec![
            edge("base_link", "mast", [0.5, 0.0, 1.0], Quaternion::IDENTITY),
            edge("mast", "velodyne", [0.1, 0.0, 0.5], Quaternion::from_rpy(0.0, 0.4, 0.0)),
            edge("base_link", "imu_link", [0.0, 0.1, 0.2], Quaternion::from_yaw(1.0)),
        ],
    };
    let siblings = TfMessage {
        transforms: vec![
            edge("base_footprint", "base_link", [0.0, 0.0, 0.2], Quaternion::IDENTITY),
            edge(
                "base_footprint",
                "velodyne",
                [0.6, 0.0, 1.5],
                Quaternion { x: 0.0, y: 0.2, z: 0.0, w: 0.98 },
            ),
        ],
    };
    let looped = TfMessage {
        transforms: vec![
            edge("a", "b", [1.0, 0.0, 0.0], Quaternion::IDENTITY),
            edge("b", "a", [1.0, 0.0, 0.0], Quaternion::IDENTITY),
        ],
    };
    let seeds = [chain, siblings, looped]
        .iter()
        .flat_map(|m| [msg::encode(m).expect("encodes"), msg::encode_big_endian(m).expect("encodes")])
        .collect();
    Campaign::new("tf_static_lookups", seeds, EXECS).run(|bytes| {
        let Ok(message) = msg::decode_owned::<TfMessage>(bytes) else { return Ok(Verdict::Rejected) };
        let mut buffer = TransformBuffer::new();
        for t in &message.transforms {
            buffer.insert(t);
        }
        let mut frames: Vec<&str> = vec!["base_link", "velodyne"];
        for t in &message.transforms {
            frames.push(&t.header.frame_id);
            frames.push(&t.child_frame_id);
        }
        frames.truncate(8);
        for target in &frames {
            for source in &frames {
                let Ok(iso) = buffer.lookup(target, source) else { continue };
                let m = iso.to_homogeneous();
                if !m.iter().all(|v| v.is_finite()) {
                    return Err(format!("lookup {target} <- {source} gave a non-finite transform {iso:?}"));
                }
                if target == source && (m - nalgebra::Matrix4::identity()).abs().max() > 1e-9 {
                    return Err(format!("lookup {target} <- {target} is not the identity: {iso:?}"));
                }
            }
        }
        Ok(Verdict::Accepted)
    });
}

fn odometry(t_s: f64, x: f64, yaw: f64) -> Odometry {
    let mut o = Odometry { child_frame_id: "base_link".into(), ..Odometry::default() };
    o.header = Header { stamp: Time::from_seconds(t_s).expect("stamp"), frame_id: "odom".into() };
    o.pose.pose.position.x = x;
    o.pose.pose.position.y = 0.1 * x;
    o.pose.pose.orientation = Quaternion::from_yaw(yaw);
    o
}

/// Messages framed as `[u32 length LE][CDR bytes]`, so mutations reach the sequence as well as each
/// message.
fn frame(messages: &[Odometry]) -> Vec<u8> {
    let mut out = Vec::new();
    for m in messages {
        let b = msg::encode(m).expect("encodes");
        out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        out.extend_from_slice(&b);
    }
    out
}

fn unframe(mut bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    std::iter::from_fn(move || {
        let (len, rest) = bytes.split_first_chunk::<4>()?;
        let (m, rest) = rest.split_at_checked(u32::from_le_bytes(*len) as usize).unwrap_or((rest, &[]));
        bytes = rest;
        Some(m)
    })
}

#[test]
fn fuzz_odometry_history() {
    let steady: Vec<Odometry> =
        (0..6).map(|k| odometry(100.0 + 0.02 * k as f64, 0.01 * k as f64, 3.1)).collect();
    let gap = [odometry(5.0, 0.0, -3.1), odometry(5.02, 0.01, 3.1), odometry(6.0, 0.5, 0.0)];
    let seeds = vec![frame(&steady), frame(&gap)];
    Campaign::new("odometry_history", seeds, EXECS).run(|bytes| {
        // What the replay does with each message: decode, skip non-finite poses, refuse time going back.
        let mut history = History::new(0.1, 0.5);
        let mut stamps = Vec::new();
        let mut decoded = 0;
        for m in unframe(bytes) {
            let Ok(o) = msg::decode_owned::<Odometry>(m) else { continue };
            decoded += 1;
            let p = o.pose.pose;
            let pose = Pose2::new(p.position.x, p.position.y, p.orientation.yaw());
            let stamp_s = o.header.stamp.as_seconds();
            if pose.is_finite() && history.push(stamp_s, pose).is_ok() {
                stamps.push(stamp_s);
            }
        }
        let probes = stamps.iter().flat_map(|&t| [t, t - 0.05, t + 0.01, t + 0.05, t - 1.0, t + 1.0]);
        for t in probes.chain(stamps.windows(2).map(|w| 0.5 * (w[0] + w[1]))) {
            if let Ok(pose) = history.pose_at(t)
                && !pose.is_finite()
            {
                return Err(format!("pose at {t} s is not finite: {pose:?} (samples at {stamps:?})"));
            }
        }
        Ok(if decoded > 0 { Verdict::Accepted } else { Verdict::Rejected })
    });
}

/// Structured: any finite samples (huge coordinates and stamps included), probed around every stamp.
#[test]
fn fuzz_odometry_history_structured() {
    use proptest::prelude::*;
    let cases = fuzzer::execs_or(EXECS);
    let mut runner = fuzzer::proptest_runner("odometry_history_structured", EXECS);
    let finite = || prop_oneof![4 => -1e3f64..1e3, 1 => proptest::num::f64::NORMAL, 1 => Just(f64::MAX), 1 => Just(f64::MIN)];
    let samples = proptest::collection::vec((0.0f64..0.3, finite(), finite(), -10.0f64..10.0), 1..8);
    let result = runner.run(&(samples, -1e9f64..1e9), |(samples, t0)| {
        let mut history = History::new(0.1, 0.5);
        let mut t = t0;
        let mut stamps = Vec::new();
        for (dt, x, y, yaw) in samples {
            t += dt;
            if history.push(t, Pose2::new(x, y, yaw)).is_ok() {
                stamps.push(t);
            }
        }
        for &s in &stamps {
            for probe in [s, s - 0.05, s + 0.01, s + 0.05, s + 0.2] {
                if let Ok(pose) = history.pose_at(probe) {
                    prop_assert!(
                        pose.is_finite(),
                        "pose at {} s is {:?} (samples at {:?})",
                        probe,
                        pose,
                        stamps
                    );
                }
            }
        }
        Ok(())
    });
    println!("fuzz odometry_history_structured: {cases} cases, seed {}", fuzzer::base_seed());
    if let Err(e) = result {
        panic!("fuzz odometry_history_structured: {e}");
    }
}
