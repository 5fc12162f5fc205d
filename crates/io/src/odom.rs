//! Odometry history: `odom -> base_link` poses by stamp, interpolated to a scan's stamp.
//!
//! Between two samples the pose is linear in x, y and follows the shortest arc in yaw. A scan stamp
//! outside the samples is extrapolated at constant velocity by at most `max_extrapolation_s`; beyond
//! that, or across a gap longer than `max_gap_s` (odometry dropped out), there is no pose and the
//! reason is returned as a [`PoseGap`].

use std::collections::VecDeque;
use std::fmt;

use croprow_core::geometry::wrap_angle;
use croprow_core::{Pose2, Twist2};

/// Why no odometry pose exists at a stamp.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum PoseGap {
    /// No odometry sample was received yet.
    NoOdometry,
    /// The stamp is before the first sample by more than the extrapolation window.
    BeforeFirst {
        /// First sample stamp, s.
        first_s: f64,
    },
    /// The stamp is after the last sample by more than the extrapolation window.
    AfterLast {
        /// Last sample stamp, s.
        last_s: f64,
    },
    /// The surrounding samples are further apart than the allowed gap.
    Gap {
        /// Sample before, s.
        before_s: f64,
        /// Sample after, s.
        after_s: f64,
    },
    /// The samples are finite but so far apart (coordinates near `f64::MAX`) that the interpolated
    /// pose overflows: corrupt odometry, no pose.
    Overflow {
        /// Sample before, s.
        before_s: f64,
        /// Sample after, s.
        after_s: f64,
    },
}

impl fmt::Display for PoseGap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PoseGap::NoOdometry => write!(f, "no odometry received"),
            PoseGap::BeforeFirst { first_s } => {
                write!(f, "before the first odometry sample ({first_s:.3} s)")
            }
            PoseGap::AfterLast { last_s } => write!(f, "after the last odometry sample ({last_s:.3} s)"),
            PoseGap::Gap { before_s, after_s } => {
                write!(f, "inside an odometry gap ({before_s:.3} s .. {after_s:.3} s)")
            }
            PoseGap::Overflow { before_s, after_s } => {
                write!(
                    f,
                    "odometry between {before_s:.3} s and {after_s:.3} s interpolates to a non-finite pose"
                )
            }
        }
    }
}

/// A sample went back in time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backwards {
    /// The previous sample's stamp, s.
    pub previous_s: f64,
    /// The offending stamp, s.
    pub stamp_s: f64,
}

/// Odometry samples in stamp order.
#[derive(Debug, Clone)]
pub struct History {
    samples: VecDeque<(f64, Pose2)>,
    max_extrapolation_s: f64,
    max_gap_s: f64,
}

impl History {
    /// An empty history with the interpolation limits, s.
    pub fn new(max_extrapolation_s: f64, max_gap_s: f64) -> Self {
        Self { samples: VecDeque::new(), max_extrapolation_s, max_gap_s }
    }

    /// Adds a sample. A repeated stamp replaces nothing (the first is kept); an older one is refused.
    pub fn push(&mut self, stamp_s: f64, pose: Pose2) -> Result<(), Backwards> {
        if let Some(&(last, _)) = self.samples.back() {
            if stamp_s < last {
                return Err(Backwards { previous_s: last, stamp_s });
            }
            if stamp_s == last {
                return Ok(());
            }
        }
        self.samples.push_back((stamp_s, pose));
        Ok(())
    }

    /// Stamp of the newest sample, s.
    pub fn latest_s(&self) -> Option<f64> {
        self.samples.back().map(|s| s.0)
    }

    /// Drops samples no longer needed for stamps at or after `stamp_s` (keeps one before it).
    pub fn forget_before(&mut self, stamp_s: f64) {
        while self.samples.len() > 2 && self.samples.get(1).is_some_and(|s| s.0 <= stamp_s) {
            self.samples.pop_front();
        }
    }

    /// The pose at `stamp_s`; always finite ([`PoseGap::Overflow`] otherwise).
    pub fn pose_at(&self, stamp_s: f64) -> Result<Pose2, PoseGap> {
        let ((a, b), pose) = self.blend_at(stamp_s)?;
        if pose.is_finite() { Ok(pose) } else { Err(PoseGap::Overflow { before_s: a, after_s: b }) }
    }

    /// The body twist at `stamp_s` (v, ω in `base_link`) from the difference of the two samples the
    /// pose there is blended from; `None` where there is no pose or the two samples share a stamp.
    pub fn twist_at(&self, stamp_s: f64) -> Option<Twist2> {
        let ((a, b), _) = self.blend_at(stamp_s).ok()?;
        let find = |t: f64| self.samples.iter().find(|s| s.0 == t).map(|s| s.1);
        let (pa, pb) = (find(a)?, find(b)?);
        let dt = b - a;
        if dt <= 0.0 {
            return None;
        }
        // The chord's direction is the mean heading over the interval: its projection on it is the
        // forward speed of a planar body.
        let mid = pa.yaw + 0.5 * wrap_angle(pb.yaw - pa.yaw);
        let (dx, dy) = (pb.x - pa.x, pb.y - pa.y);
        let twist = Twist2::new((dx * mid.cos() + dy * mid.sin()) / dt, wrap_angle(pb.yaw - pa.yaw) / dt);
        twist.is_finite().then_some(twist)
    }

    /// The blended pose at `stamp_s` and the stamps of the two samples it came from.
    fn blend_at(&self, stamp_s: f64) -> Result<((f64, f64), Pose2), PoseGap> {
        let (Some(&first), Some(&last)) = (self.samples.front(), self.samples.back()) else {
            return Err(PoseGap::NoOdometry);
        };
        if stamp_s < first.0 {
            if first.0 - stamp_s > self.max_extrapolation_s {
                return Err(PoseGap::BeforeFirst { first_s: first.0 });
            }
            let second = self.samples.get(1).copied().unwrap_or(first);
            return Ok(((first.0, second.0), blend(first, second, stamp_s)));
        }
        if stamp_s > last.0 {
            if stamp_s - last.0 > self.max_extrapolation_s {
                return Err(PoseGap::AfterLast { last_s: last.0 });
            }
            let before = self.samples.len().checked_sub(2).and_then(|i| self.samples.get(i)).copied();
            let before = before.unwrap_or(last);
            return Ok(((before.0, last.0), blend(before, last, stamp_s)));
        }
        // First sample at or after the stamp; the one before it brackets the stamp.
        let i = self.samples.partition_point(|s| s.0 < stamp_s);
        let after = self.samples.get(i).copied().unwrap_or(last);
        let before = i.checked_sub(1).and_then(|j| self.samples.get(j)).copied().unwrap_or(after);
        if after.0 - before.0 > self.max_gap_s {
            return Err(PoseGap::Gap { before_s: before.0, after_s: after.0 });
        }
        Ok(((before.0, after.0), blend(before, after, stamp_s)))
    }
}

/// Linear blend (or extrapolation) of two stamped poses at `t`: x, y linear, yaw on the shortest arc.
fn blend(a: (f64, Pose2), b: (f64, Pose2), t: f64) -> Pose2 {
    let dt = b.0 - a.0;
    if dt <= 0.0 {
        return a.1;
    }
    let s = (t - a.0) / dt;
    let dyaw = wrap_angle(b.1.yaw - a.1.yaw);
    Pose2::new(a.1.x + s * (b.1.x - a.1.x), a.1.y + s * (b.1.y - a.1.y), wrap_angle(a.1.yaw + s * dyaw))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn history() -> History {
        let mut h = History::new(0.05, 0.5);
        h.push(1.0, Pose2::new(0.0, 0.0, 3.0)).unwrap();
        h.push(1.1, Pose2::new(1.0, 2.0, -3.0)).unwrap();
        h
    }

    #[test]
    fn interpolates_linearly_and_on_the_short_arc() {
        let p = history().pose_at(1.025).unwrap();
        assert!((p.x - 0.25).abs() < 1e-9 && (p.y - 0.5).abs() < 1e-9);
        // 3.0 -> -3.0 is +0.283 rad across ±π, not -6 rad.
        let short = wrap_angle(3.0 + 0.25 * wrap_angle(-3.0 - 3.0));
        assert!((p.yaw - short).abs() < 1e-9, "{p:?}");
        assert!(p.yaw > 3.0);
    }

    #[test]
    fn twist_is_the_samples_difference_in_base_link() {
        let mut h = History::new(0.05, 0.5);
        h.push(1.0, Pose2::new(0.0, 0.0, 1.0)).unwrap();
        h.push(1.1, Pose2::new(0.05 * 1.02_f64.cos(), 0.05 * 1.02_f64.sin(), 1.04)).unwrap();
        let t = h.twist_at(1.05).unwrap();
        assert!((t.v - 0.5).abs() < 1e-9 && (t.omega - 0.4).abs() < 1e-9, "{t:?}");
        assert_eq!(History::new(0.05, 0.5).twist_at(1.0), None);
    }

    #[test]
    fn exact_samples_are_returned() {
        let h = history();
        assert_eq!(h.pose_at(1.0).unwrap(), Pose2::new(0.0, 0.0, 3.0));
        assert_eq!(h.pose_at(1.1).unwrap(), Pose2::new(1.0, 2.0, -3.0));
    }

    #[test]
    fn extrapolates_only_inside_the_window() {
        let h = history();
        let p = h.pose_at(1.14).unwrap();
        assert!((p.x - 1.4).abs() < 1e-9);
        assert_eq!(h.pose_at(1.2), Err(PoseGap::AfterLast { last_s: 1.1 }));
        assert_eq!(h.pose_at(0.9), Err(PoseGap::BeforeFirst { first_s: 1.0 }));
        assert_eq!(History::new(0.05, 0.5).pose_at(1.0), Err(PoseGap::NoOdometry));
    }

    #[test]
    fn long_gaps_are_not_bridged() {
        let mut h = history();
        h.push(2.0, Pose2::default()).unwrap();
        assert_eq!(h.pose_at(1.5), Err(PoseGap::Gap { before_s: 1.1, after_s: 2.0 }));
    }

    #[test]
    fn time_going_backwards_is_refused() {
        let mut h = history();
        assert_eq!(h.push(1.05, Pose2::default()), Err(Backwards { previous_s: 1.1, stamp_s: 1.05 }));
        assert!(h.push(1.1, Pose2::default()).is_ok());
        assert_eq!(h.pose_at(1.1).unwrap(), Pose2::new(1.0, 2.0, -3.0));
    }

    #[test]
    fn overflowing_interpolation_is_a_gap_not_infinity() {
        let mut h = History::new(0.05, 0.5);
        h.push(1.0, Pose2::new(f64::MAX, 0.0, 0.0)).unwrap();
        h.push(1.1, Pose2::new(f64::MIN, 0.0, 0.0)).unwrap();
        assert_eq!(h.pose_at(1.05), Err(PoseGap::Overflow { before_s: 1.0, after_s: 1.1 }));
        assert_eq!(h.pose_at(1.0).unwrap().x, f64::MAX);
    }

    #[test]
    fn forgetting_keeps_the_bracketing_sample() {
        let mut h = history();
        h.push(1.2, Pose2::new(2.0, 0.0, 0.0)).unwrap();
        h.push(1.3, Pose2::new(3.0, 0.0, 0.0)).unwrap();
        h.forget_before(1.25);
        assert!((h.pose_at(1.25).unwrap().x - 2.5).abs() < 1e-9);
    }
}
