//! Shared by the `safety_*` property tests: the ways a detection, a stamp and an odometry pose can go
//! wrong, as proptest strategies, applied to the ideal detections of the synthetic field
//! (`control_field`).
#![allow(dead_code)]

use croprow_core::{Detection, Pose2, RowEstimate, RowStatus};
use proptest::prelude::*;

/// Bounds of the small errors of [`Corruption::Noise`]: row offset (m), heading (rad), row end (m).
pub const NOISE_OFFSET_M: f64 = 0.03;
pub const NOISE_HEADING_RAD: f64 = 0.02;
pub const NOISE_END_M: f64 = 0.1;

/// A value that may be absurd: mostly plausible, sometimes NaN, ±inf or huge.
pub fn wild_f64(plausible: std::ops::Range<f64>) -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => plausible,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => prop_oneof![Just(1e300), Just(-1e300), Just(f64::MAX), Just(f64::MIN_POSITIVE)],
    ]
}

/// What happens to one step's detection.
#[derive(Debug, Clone)]
pub enum Corruption {
    /// The ideal detection.
    None,
    /// No scan this step.
    Drop,
    /// The detector found nothing, with this status.
    Empty(RowStatus),
    /// Every row field replaced by these (possibly absurd) numbers.
    Garbage { offset_m: f64, heading_rad: f64, curvature_per_m: f64, spacing_m: f64 },
    /// The rows seen one lane (two spacings) to the side: a neighbouring lane.
    LaneShift(f64),
    /// Small errors on the rows and the row end, m / rad.
    Noise { offset_m: f64, heading_rad: f64, end_m: f64 },
    /// The row end reported at this (possibly absurd) distance ahead.
    RowEnd(f64),
    /// The status replaced, rows kept.
    Status(RowStatus),
}

pub fn status() -> impl Strategy<Value = RowStatus> {
    prop_oneof![
        Just(RowStatus::Searching),
        Just(RowStatus::Tracking),
        Just(RowStatus::EndOfRow),
        Just(RowStatus::Lost),
        Just(RowStatus::InvalidInput),
    ]
}

/// Any corruption, the ideal detection most often.
pub fn corruption() -> impl Strategy<Value = Corruption> {
    prop_oneof![
        60 => Just(Corruption::None),
        2 => Just(Corruption::Drop),
        2 => status().prop_map(Corruption::Empty),
        1 => (wild_f64(-2.0..2.0), wild_f64(-1.5..1.5), wild_f64(-1.0..1.0), wild_f64(-1.0..3.0)).prop_map(
            |(offset_m, heading_rad, curvature_per_m, spacing_m)| Corruption::Garbage {
                offset_m,
                heading_rad,
                curvature_per_m,
                spacing_m
            }
        ),
        1 => prop_oneof![Just(-1.5), Just(1.5)].prop_map(Corruption::LaneShift),
        3 => (-NOISE_OFFSET_M..NOISE_OFFSET_M, -NOISE_HEADING_RAD..NOISE_HEADING_RAD, -NOISE_END_M..NOISE_END_M)
            .prop_map(|(offset_m, heading_rad, end_m)| Corruption::Noise { offset_m, heading_rad, end_m }),
        1 => wild_f64(-5.0..8.0).prop_map(Corruption::RowEnd),
        1 => status().prop_map(Corruption::Status),
    ]
}

/// Corruptions that a sound detector may produce: dropouts, empty results, small noise (no invented
/// geometry).
pub fn honest_corruption() -> impl Strategy<Value = Corruption> {
    prop_oneof![
        12 => Just(Corruption::None),
        2 => Just(Corruption::Drop),
        2 => prop_oneof![Just(RowStatus::Searching), Just(RowStatus::InvalidInput)].prop_map(Corruption::Empty),
        3 => (-NOISE_OFFSET_M..NOISE_OFFSET_M, -NOISE_HEADING_RAD..NOISE_HEADING_RAD, -NOISE_END_M..NOISE_END_M)
            .prop_map(|(offset_m, heading_rad, end_m)| Corruption::Noise { offset_m, heading_rad, end_m }),
    ]
}

/// Applies a corruption to the ideal detection `d`.
pub fn corrupt(d: Detection, c: &Corruption) -> Option<Detection> {
    let map_rows = |d: Detection, f: &dyn Fn(RowEstimate) -> RowEstimate| Detection {
        left: d.left.map(f),
        right: d.right.map(f),
        ..d
    };
    match c {
        Corruption::None => Some(d),
        Corruption::Drop => None,
        Corruption::Empty(s) => Some(Detection::empty(d.stamp_s, *s)),
        Corruption::Garbage { offset_m, heading_rad, curvature_per_m, spacing_m } => {
            let row = |r: RowEstimate| RowEstimate {
                offset_m: r.offset_m.signum() * offset_m.abs(),
                heading_rad: *heading_rad,
                curvature_per_m: *curvature_per_m,
                line: [0.0, *offset_m, 4.0, *offset_m],
                ..r
            };
            Some(Detection { row_spacing_m: Some(*spacing_m), ..map_rows(d, &row) })
        }
        Corruption::LaneShift(dy) => Some(map_rows(d, &|r| RowEstimate { offset_m: r.offset_m + dy, ..r })),
        Corruption::Noise { offset_m, heading_rad, end_m } => Some(Detection {
            row_end_ahead_m: d.row_end_ahead_m.map(|e| e + end_m),
            ..map_rows(d, &|r| RowEstimate {
                offset_m: r.offset_m + offset_m,
                heading_rad: r.heading_rad + heading_rad,
                ..r
            })
        }),
        Corruption::RowEnd(e) => Some(Detection { row_end_ahead_m: Some(*e), ..d }),
        Corruption::Status(s) => Some(Detection { status: *s, ..d }),
    }
}

/// What happens to one step's stamp and odometry.
#[derive(Debug, Clone)]
pub enum InputGlitch {
    None,
    /// The stamp is NaN or ±inf.
    BadStamp(f64),
    /// The stamp goes back by this much, s.
    Backwards(f64),
    /// The clock jumps forward by this much for good, s.
    ClockJump(f64),
    /// The same stamp as the previous step.
    Repeat,
    /// The odometry pose has a non-finite component.
    BadPose(Pose2),
    /// The odometry twist is not finite.
    BadTwist,
    /// The odometry pose jumps by this much for this step, m.
    Teleport(f64, f64),
}

pub fn glitch() -> impl Strategy<Value = InputGlitch> {
    let non_finite = prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)];
    prop_oneof![
        120 => Just(InputGlitch::None),
        1 => non_finite.clone().prop_map(InputGlitch::BadStamp),
        1 => (0.001..5.0).prop_map(InputGlitch::Backwards),
        1 => (0.001..3.0).prop_map(InputGlitch::ClockJump),
        1 => Just(InputGlitch::Repeat),
        1 => (non_finite, 0..3usize).prop_map(|(v, i)| {
            let mut p = [0.0; 3];
            p[i] = v;
            InputGlitch::BadPose(Pose2::new(p[0], p[1], p[2]))
        }),
        1 => Just(InputGlitch::BadTwist),
        1 => (-3.0..3.0, -3.0..3.0).prop_map(|(x, y)| InputGlitch::Teleport(x, y)),
    ]
}

/// The proptest settings of the safety tests: `cases` cases from a fixed seed (deterministic runs;
/// `PROPTEST_RNG_SEED=n` explores others), no failure files (a failure found is kept as a named test).
pub fn config(cases: u32) -> ProptestConfig {
    let default = ProptestConfig::default();
    let rng_seed = match default.rng_seed {
        proptest::test_runner::RngSeed::Random => proptest::test_runner::RngSeed::Fixed(0x5AFE_C0DE),
        fixed => fixed,
    };
    ProptestConfig { cases, rng_seed, failure_persistence: None, ..default }
}
