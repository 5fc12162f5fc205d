//! The centroid map of both pipelines (paper Sec. III-A-2): row centroids stored in `odom` so that
//! odometry carries them while the robot drives, in a ring buffer allocated once.

use crate::geometry::Pose2;

/// A ring buffer of weighted points in `odom`, m, each with a tag (the default pipeline stores the
/// odometer reading, to age its centroids). The oldest point is overwritten when full.
#[derive(Debug, Clone)]
pub(crate) struct CentroidMap {
    points: Vec<[f64; 4]>,
    next: usize,
    capacity: usize,
}

impl CentroidMap {
    pub(crate) fn new(capacity: usize) -> Self {
        Self { points: Vec::with_capacity(capacity), next: 0, capacity: capacity.max(1) }
    }

    /// Stores a point given in `base_link` at `pose` (the `odom` pose of `base_link`), with a weight
    /// and a tag.
    pub(crate) fn push(&mut self, pose: &Pose2, x: f64, y: f64, weight: f64, tag: f64) {
        let (ox, oy) = pose.transform_point(x, y);
        let p = [ox, oy, weight, tag];
        if self.points.len() < self.capacity {
            self.points.push(p);
        } else if let Some(slot) = self.points.get_mut(self.next) {
            *slot = p;
        }
        self.next = (self.next + 1) % self.capacity;
    }

    /// Every stored point `[x_odom, y_odom, weight, tag]`, in no particular order.
    pub(crate) fn points(&self) -> &[[f64; 4]] {
        &self.points
    }

    pub(crate) fn clear(&mut self) {
        self.points.clear();
        self.next = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stores_in_odom_and_overwrites_the_oldest() {
        let mut m = CentroidMap::new(2);
        let pose = Pose2::new(1.0, 2.0, std::f64::consts::FRAC_PI_2);
        m.push(&pose, 1.0, 0.0, 1.0, 0.0);
        let p = m.points()[0];
        assert!((p[0] - 1.0).abs() < 1e-12 && (p[1] - 3.0).abs() < 1e-12);
        m.push(&pose, 0.0, 0.0, 2.0, 0.0);
        m.push(&pose, 0.0, 0.0, 3.0, 0.0);
        assert_eq!(m.points().len(), 2);
        assert_eq!(m.points()[0][2], 3.0);
        m.clear();
        assert!(m.points().is_empty());
    }
}
