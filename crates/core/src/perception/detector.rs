//! The [`RowDetector`]: validates each step's input, then runs the pipeline of the configured mode.

use crate::error::ConfigError;
use crate::geometry::{Mount, Pose2};

use super::config::DetectorConfig;
use super::{Detection, RowStatus, Scan};

/// The crop-row detector. Built once from a validated [`DetectorConfig`]; every buffer it needs is
/// allocated in [`RowDetector::new`], so [`RowDetector::detect`] does not allocate.
#[derive(Debug, Clone)]
pub struct RowDetector {
    config: DetectorConfig,
    centroids: Vec<[f64; 2]>,
    last_stamp_s: Option<f64>,
    last_odom: Option<Pose2>,
}

impl RowDetector {
    /// A detector for `config`, refused when the config is invalid.
    pub fn new(config: DetectorConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            centroids: Vec::with_capacity(config.map_capacity),
            config,
            last_stamp_s: None,
            last_odom: None,
        })
    }

    /// One step: `scan` points in the sensor frame, `odom` = pose of `base_link` in `odom` at
    /// `scan.stamp_s`, `mount` = `base_link -> sensor`. Never panics; bad input gives
    /// [`RowStatus::InvalidInput`] and keeps the state.
    pub fn detect(&mut self, scan: Scan<'_>, odom: Pose2, mount: &Mount) -> Detection {
        let t = scan.stamp_s;
        if !t.is_finite() || !odom.is_finite() || mount.validate().is_err() {
            return Detection::empty(t, RowStatus::InvalidInput);
        }
        if self.last_stamp_s.is_some_and(|last| t <= last) {
            return Detection::empty(t, RowStatus::InvalidInput);
        }
        self.last_stamp_s = Some(t);
        self.last_odom = Some(odom);
        Detection::empty(t, RowStatus::Searching)
    }

    /// Forgets all rows (e.g. when entering a new lane); the configuration is kept.
    pub fn reset(&mut self) {
        self.centroids.clear();
        self.last_stamp_s = None;
        self.last_odom = None;
    }

    /// The configuration this detector runs with.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// Row centroids of the map in `base_link` at the last scan, m (for markers and plots).
    pub fn centroids(&self) -> &[[f64; 2]] {
        &self.centroids
    }
}
