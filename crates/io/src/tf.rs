//! A transform buffer for static transforms (`/tf_static`): looks up `target -> source` through any
//! chain of intermediate frames, e.g. `base_link -> velodyne` via `base_link -> sensor_mast -> velodyne`.
//!
//! Static transforms never change, so the buffer keeps the latest transform per child frame and no
//! history. Dynamic `/tf` (`odom -> base_link`) is read from the odometry topic instead.

use std::collections::HashMap;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use thiserror::Error;

use crate::msg::TransformStamped;

/// Longest chain followed before assuming the tree has a loop.
const MAX_DEPTH: usize = 64;

/// A transform that cannot be looked up.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum LookupError {
    /// No chain of static transforms connects the two frames.
    #[error("no static transform from `{target}` to `{frame}` (known parent -> child: {known})")]
    Unconnected {
        /// The frame the result is expressed in.
        target: String,
        /// The frame being located.
        frame: String,
        /// Every edge in the buffer, for the message.
        known: String,
    },
    /// The chain connects the frames, but composing it overflows (translations near `f64::MAX`):
    /// no finite transform exists.
    #[error("the static transforms from `{target}` to `{frame}` compose to a non-finite transform")]
    NonFinite {
        /// The frame the result is expressed in.
        target: String,
        /// The frame being located.
        frame: String,
    },
}

/// Latest static transform per child frame: `child -> (parent, T_parent_child)`.
#[derive(Debug, Clone, Default)]
pub struct TransformBuffer {
    edges: HashMap<String, (String, Isometry3<f64>)>,
}

impl TransformBuffer {
    /// An empty buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a transform; non-finite or zero rotations are ignored (returns false), as tf2 does.
    pub fn insert(&mut self, t: &TransformStamped) -> bool {
        let (tr, q) = (t.transform.translation, t.transform.rotation);
        let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
        if ![tr.x, tr.y, tr.z, norm].iter().all(|v| v.is_finite()) || norm < 1e-9 {
            return false;
        }
        let iso = Isometry3::from_parts(
            Translation3::new(tr.x, tr.y, tr.z),
            UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z)),
        );
        self.edges.insert(t.child_frame_id.clone(), (t.header.frame_id.clone(), iso));
        true
    }

    /// True when no transform is stored.
    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// Chain from `frame` up to its root: `(ancestor, T_ancestor_frame)`, starting with `(frame, I)`.
    fn ancestors<'a>(&'a self, frame: &'a str) -> Vec<(&'a str, Isometry3<f64>)> {
        let mut chain = Vec::new();
        let mut current = frame;
        let mut acc = Isometry3::identity();
        chain.push((frame, acc));
        while let Some((parent, t)) = self.edges.get(current) {
            acc = t * acc;
            current = parent.as_str();
            chain.push((current, acc));
            if chain.len() > MAX_DEPTH {
                break;
            }
        }
        chain
    }

    /// `T_target_source`: maps points given in `source` into `target`. Always finite: a chain whose
    /// composition overflows is [`LookupError::NonFinite`].
    pub fn lookup(&self, target: &str, source: &str) -> Result<Isometry3<f64>, LookupError> {
        let up_source = self.ancestors(source);
        let up_target = self.ancestors(target);
        for (frame, t_a_target) in &up_target {
            if let Some((_, t_a_source)) = up_source.iter().find(|(f, _)| f == frame) {
                let t = t_a_target.inverse() * t_a_source;
                // Each edge is finite, but a sum of translations near f64::MAX is not.
                if !t.to_homogeneous().iter().all(|v| v.is_finite()) {
                    return Err(LookupError::NonFinite {
                        target: target.to_owned(),
                        frame: source.to_owned(),
                    });
                }
                return Ok(t);
            }
        }
        let mut known: Vec<String> = self.edges.iter().map(|(c, (p, _))| format!("{p} -> {c}")).collect();
        known.sort();
        Err(LookupError::Unconnected {
            target: target.to_owned(),
            frame: source.to_owned(),
            known: if known.is_empty() { "none".to_owned() } else { known.join(", ") },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{Header, Quaternion as Q, Transform, Vector3};

    fn tf(parent: &str, child: &str, t: [f64; 3], q: Q) -> TransformStamped {
        TransformStamped {
            header: Header { frame_id: parent.into(), ..Header::default() },
            child_frame_id: child.into(),
            transform: Transform { translation: Vector3 { x: t[0], y: t[1], z: t[2] }, rotation: q },
        }
    }

    #[test]
    fn chains_through_intermediate_frames() {
        let mut b = TransformBuffer::new();
        b.insert(&tf("base_link", "mast", [0.5, 0.0, 1.0], Q::IDENTITY));
        b.insert(&tf("mast", "velodyne", [0.1, 0.0, 0.5], Q::from_rpy(0.0, 0.3, 0.0)));
        let t = b.lookup("base_link", "velodyne").unwrap();
        assert!((t.translation.vector - nalgebra::Vector3::new(0.6, 0.0, 1.5)).norm() < 1e-12);
        assert!((t.rotation.euler_angles().1 - 0.3).abs() < 1e-12);
        // And the inverse direction.
        let inv = b.lookup("velodyne", "base_link").unwrap();
        assert!((inv * t).translation.vector.norm() < 1e-12);
    }

    #[test]
    fn siblings_meet_at_a_common_parent() {
        let mut b = TransformBuffer::new();
        b.insert(&tf("base_footprint", "base_link", [0.0, 0.0, 0.2], Q::IDENTITY));
        b.insert(&tf("base_footprint", "velodyne", [0.6, 0.0, 1.5], Q::IDENTITY));
        let t = b.lookup("base_link", "velodyne").unwrap();
        assert!((t.translation.vector - nalgebra::Vector3::new(0.6, 0.0, 1.3)).norm() < 1e-12);
    }

    #[test]
    fn unconnected_frames_name_what_is_known() {
        let mut b = TransformBuffer::new();
        b.insert(&tf("base_link", "imu_link", [0.0; 3], Q::IDENTITY));
        let e = b.lookup("base_link", "velodyne").unwrap_err();
        assert!(e.to_string().contains("base_link -> imu_link"), "{e}");
        assert!(b.lookup("base_link", "base_link").is_ok());
    }

    #[test]
    fn bad_rotations_are_ignored() {
        let mut b = TransformBuffer::new();
        assert!(!b.insert(&tf("a", "b", [0.0; 3], Q { x: 0.0, y: 0.0, z: 0.0, w: 0.0 })));
        assert!(!b.insert(&tf("a", "b", [f64::NAN, 0.0, 0.0], Q::IDENTITY)));
        assert!(b.is_empty());
    }

    #[test]
    fn overflowing_chains_are_an_error_not_infinity() {
        let mut b = TransformBuffer::new();
        assert!(b.insert(&tf("base_link", "mast", [f64::MAX, 0.0, 0.0], Q::IDENTITY)));
        assert!(b.insert(&tf("mast", "velodyne", [f64::MAX, 0.0, 0.0], Q::IDENTITY)));
        assert!(matches!(b.lookup("base_link", "velodyne"), Err(LookupError::NonFinite { .. })));
        assert!(b.lookup("base_link", "mast").is_ok());
    }

    #[test]
    fn loops_do_not_hang() {
        let mut b = TransformBuffer::new();
        b.insert(&tf("a", "b", [0.0; 3], Q::IDENTITY));
        b.insert(&tf("b", "a", [0.0; 3], Q::IDENTITY));
        assert!(b.lookup("a", "c").is_err());
    }
}
