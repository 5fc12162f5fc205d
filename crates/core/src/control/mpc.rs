//! Nonlinear model predictive control of a unicycle / skid-steer robot along a [`Path`], solved with
//! PANOC (optimization_engine).
//!
//! Where it sits: the lane switcher hands over a path in `odom` (the row centre line or a headland
//! turn) and a cruise speed; [`Mpc::solve`] returns the `(v, ω)` command for `base_link`.
//!
//! # Model (path / Frenet frame)
//! With lateral offset `e_y` (m, left positive), heading error `e_ψ` (rad) and path curvature `κ`:
//!
//! ```text
//! ṡ = v cos e_ψ / (1 − κ e_y),   ė_y = v sin e_ψ,   ė_ψ = ω − κ ṡ
//! ```
//!
//! integrated with forward Euler over `N` steps of `step_s`. The curvature of stage `k` is read at the
//! arc length the previous (shifted) plan predicts, a real-time-iteration choice that keeps the
//! gradient exact and cheap.
//!
//! # Cost
//! `Σ w_k (q_y e_y² + q_ψ e_ψ²) + r_v (v − v_ref)² + r_ω (ω − κ v_ref)² + s_v v̇² + s_ω ω̇²`, with the
//! last stage weighted by `terminal_factor`, plus a stiff quadratic penalty on rates beyond their limits.
//!
//! When the path is a lane centre line ([`Path::row_spacing_m`]), a wheel-corridor term keeps the
//! tyres off the crop: each tyre patch, at `e_y + x_w sin e_ψ + y_w cos e_ψ` from the centre line,
//! should stay inside its inter-row, the band between two rows (rows stand `(k + ½)·spacing` to the
//! side) narrowed by half a tyre and `row_clearance_m`; every metre outside costs
//! `corridor_weight · excess²` per stage, and every metre further out than the tyre was when the
//! solve began (or than its band, when it was inside) costs `corridor_hold_weight` in all (opt-in): a
//! tyre is held where it is and brought back gently. It matters when the robot starts or drifts far
//! off the centre line, or the lane moves under it at once: the lateral term alone would swing the
//! rear tyres across a row on the way back. Under a slide `e_ψ` is the course's error and the body
//! points a crab angle off it ([`Mpc::solve_crabbing`]): the tyres are placed by the body, `e_ψ − crab`.
//!
//! # Constraints
//! Decision variables are the absolute inputs `(v_k, ω_k)`. Their magnitude bounds are hard: a box
//! (`Rectangle`) whose projection is exact. Rate bounds are enforced inside the horizon by the penalty
//! (soft, so a sudden reference change never makes the problem infeasible) and exactly on the command
//! that leaves [`Mpc::solve`], which is clamped to `previous ± limit · step_s`. Both are tested.
//!
//! # Real time
//! One `PANOCCache`, the bounds, the warm start and the curvature profile are allocated in
//! [`Mpc::new`]; a solve allocates nothing. Every solve is warm-started from the previous solution
//! shifted by one step. Iterations are capped by `mpc.max_iterations` (deterministic, used in tests);
//! the caller may also pass a time budget, which OpEn enforces with its own monotonic clock (the only
//! clock read in the core). Whatever happens, the command is finite: on failure it is zero.

use std::time::Duration;

use optimization_engine::{
    SolverError,
    constraints::Rectangle,
    core::{ExitStatus, Problem, panoc::PANOCCache, panoc::PANOCOptimizer},
};
use serde::{Deserialize, Serialize};

use crate::control::path::{Frenet, Path};
use crate::error::{ConfigError, check_range};
use crate::geometry::Twist2;

/// Longest horizon the stack-allocated rollout buffers hold.
pub const MAX_HORIZON: usize = 100;

/// `1 − κ e_y` is floored here: beyond it the robot would be past the centre of curvature.
const MIN_DENOMINATOR: f64 = 0.2;

/// MPC settings: horizon, weights, bounds and solver budget.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MpcConfig {
    /// Number of steps N in the horizon. Default 20 (2 s with the default step).
    pub horizon_steps: usize,
    /// Step of the prediction model, s. Default 0.1.
    pub step_s: f64,
    /// Weight on the lateral error, 1/m². Default 60.
    pub lateral_weight: f64,
    /// Weight on the heading error, 1/rad². Default 8.
    pub heading_weight: f64,
    /// Factor on `heading_weight` while the detector reads a wheel slide, and for `sliding_hold_m`
    /// after (see [`Mpc::set_sliding`]). Default 1: off. Under a slide the lane under the robot lags
    /// the crop (registration reads part of the slide and applies it in steps), so the lane jumps
    /// sideways under the robot as the reading catches up; at the plain weight the MPC then turned
    /// back 0.25 rad at once and swung a rear tyre over a row (soak seeds 13 and 1106). At 5 (a weight
    /// of 40) the robot turns back along a flatter arc and both are clean, but it also corrects a true
    /// offset more slowly wherever a false slide is read: the held-out soak seeds 1000-1999 ran over
    /// 10 plants in 3 runs instead of 2 in 2 (a mount error read as a slide, 1384: 6 plants), while
    /// seeds 0-999 went from 3 plants in 1 run to none (docs/faults.md, session 44).
    pub sliding_heading_factor: f64,
    /// Distance driven after the detector last read a slide over which the heading still weighs
    /// `sliding_heading_factor`, m: the lane keeps catching up with the slide after the reading
    /// lapses. Default 1.0.
    pub sliding_hold_m: f64,
    /// Weight on the speed error v − v_ref, s²/m². Default 2.
    pub speed_weight: f64,
    /// Weight on the yaw rate beyond the path's feed-forward κ·v_ref, s²/rad². Default 0.2.
    pub yaw_rate_weight: f64,
    /// Weight on the acceleration v̇, s⁴/m². Default 0.05.
    pub accel_weight: f64,
    /// Weight on the yaw acceleration ω̇, s⁴/rad². Default 0.02.
    pub yaw_accel_weight: f64,
    /// Multiplier of the state cost of the last stage. Default 5.
    pub terminal_factor: f64,
    /// Lowest forward speed, m/s. Default 0 (no reversing in the crop).
    pub speed_min_mps: f64,
    /// Highest forward speed, m/s. Default 1.0.
    pub speed_max_mps: f64,
    /// Highest yaw rate magnitude, rad/s. Default 1.0.
    pub yaw_rate_max_radps: f64,
    /// Highest acceleration magnitude, m/s². Default 0.8.
    pub accel_max_mps2: f64,
    /// Highest yaw acceleration magnitude, rad/s². Default 2.0.
    pub yaw_accel_max_radps2: f64,
    /// Weight of the quadratic penalty on rates beyond their limits. Default 100.
    pub rate_penalty_weight: f64,
    /// Weight of a tyre's intrusion into a crop row, per stage, 1/m² (see the module docs); 0 turns
    /// the wheel corridor off. Default 600, measured on the `recovery` scenario (0.3 m and 8° off)
    /// with seeds 7, 1 and 2: 0 crushed 13, 12 and 11 plants and settled under 2 cm after 1.1-1.2 m;
    /// 600 crushed 10, 11 and 10 and settled after 1.96, 1.85 and 2.37 m; 1000 crushed 9, 9 and 9 but
    /// settled after 2.27, 5.31 and 4.45 m: a heavier corridor holds the rear tyre at the band edge
    /// and creeps to the centre line, past the issue's 3 m.
    pub corridor_weight: f64,
    /// Weight of a tyre's move further over a row than it was when the MPC solves, per stage, 1/m²:
    /// a tyre in its inter-row is held in its band this hard, and one already over a row is kept from
    /// going further, while its whole excess is brought back at `corridor_weight` (a heavier pull
    /// there keeps a robot that starts off the line from turning back to it, see above). It matters
    /// when the lane moves under the robot at once (a canopy registration correction, a slide just
    /// measured): the lateral term alone turns it back hard enough to swing a rear tyre over a row
    /// (unit test `a_lane_that_moves_sideways_does_not_swing_a_rear_tyre_over_a_row`: at 6000, 0.2 m
    /// off, the rear tyre went 5 mm past its band instead of 12). Default 0 (off: at most
    /// `corridor_weight` has no effect): at 6000 the soak's 2000 seeds ran over 27 plants instead of
    /// 45, but in 13 runs instead of 9, and `recovery` over 10 plants instead of 9 (docs/faults.md,
    /// session 36).
    pub corridor_hold_weight: f64,
    /// Distance of the wheel contact points ahead of and behind `base_link`, m. Default 0.6095.
    pub wheel_x_m: f64,
    /// Distance of the wheel contact points to the side of `base_link`, m. Default 0.762.
    pub wheel_y_m: f64,
    /// Width of a tyre's contact patch, m. Default 0.15.
    pub tire_width_m: f64,
    /// Lateral distance kept between a tyre and the line of a row's stems, m. Default 0.03 (the stems
    /// stray a few centimetres off the row line).
    pub row_clearance_m: f64,
    /// PANOC tolerance on the fixed-point residual. Default 1e-3: warm solves converge in 1-10
    /// iterations, while 1e-4 makes cold solves hit the iteration cap for no visible tracking gain.
    pub tolerance: f64,
    /// Iteration cap per solve (deterministic budget). Default 60.
    pub max_iterations: usize,
    /// L-BFGS memory of PANOC. Default 8.
    pub lbfgs_memory: usize,
}

impl Default for MpcConfig {
    fn default() -> Self {
        Self {
            horizon_steps: 20,
            step_s: 0.1,
            lateral_weight: 60.0,
            heading_weight: 8.0,
            sliding_heading_factor: 1.0,
            sliding_hold_m: 1.0,
            speed_weight: 2.0,
            yaw_rate_weight: 0.2,
            accel_weight: 0.05,
            yaw_accel_weight: 0.02,
            terminal_factor: 5.0,
            speed_min_mps: 0.0,
            speed_max_mps: 1.0,
            yaw_rate_max_radps: 1.0,
            accel_max_mps2: 0.8,
            yaw_accel_max_radps2: 2.0,
            rate_penalty_weight: 100.0,
            corridor_weight: 600.0,
            corridor_hold_weight: 0.0,
            wheel_x_m: 0.6095,
            wheel_y_m: 0.762,
            tire_width_m: 0.15,
            row_clearance_m: 0.03,
            tolerance: 1e-3,
            max_iterations: 60,
            lbfgs_memory: 8,
        }
    }
}

impl MpcConfig {
    /// Checks every field, naming the first bad one (`mpc.<field>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("mpc.horizon_steps", self.horizon_steps as f64, 2.0, MAX_HORIZON as f64)?;
        check_range("mpc.step_s", self.step_s, 0.005, 1.0)?;
        for (name, w) in [
            ("mpc.lateral_weight", self.lateral_weight),
            ("mpc.heading_weight", self.heading_weight),
            ("mpc.speed_weight", self.speed_weight),
            ("mpc.yaw_rate_weight", self.yaw_rate_weight),
            ("mpc.accel_weight", self.accel_weight),
            ("mpc.yaw_accel_weight", self.yaw_accel_weight),
            ("mpc.terminal_factor", self.terminal_factor),
            ("mpc.rate_penalty_weight", self.rate_penalty_weight),
            ("mpc.corridor_weight", self.corridor_weight),
            ("mpc.corridor_hold_weight", self.corridor_hold_weight),
        ] {
            check_range(name, w, 0.0, 1e6)?;
        }
        check_range("mpc.wheel_x_m", self.wheel_x_m, 0.0, 5.0)?;
        check_range("mpc.wheel_y_m", self.wheel_y_m, 0.0, 5.0)?;
        check_range("mpc.tire_width_m", self.tire_width_m, 0.0, 2.0)?;
        check_range("mpc.row_clearance_m", self.row_clearance_m, 0.0, 1.0)?;
        check_range("mpc.sliding_heading_factor", self.sliding_heading_factor, 0.0, 1000.0)?;
        check_range("mpc.sliding_hold_m", self.sliding_hold_m, 0.0, 1000.0)?;
        check_range("mpc.speed_min_mps", self.speed_min_mps, -5.0, 5.0)?;
        check_range("mpc.speed_max_mps", self.speed_max_mps, self.speed_min_mps + 1e-3, 5.0)?;
        check_range("mpc.yaw_rate_max_radps", self.yaw_rate_max_radps, 1e-3, 10.0)?;
        check_range("mpc.accel_max_mps2", self.accel_max_mps2, 1e-3, 20.0)?;
        check_range("mpc.yaw_accel_max_radps2", self.yaw_accel_max_radps2, 1e-3, 50.0)?;
        check_range("mpc.tolerance", self.tolerance, 1e-12, 1.0)?;
        check_range("mpc.max_iterations", self.max_iterations as f64, 1.0, 1e6)?;
        check_range("mpc.lbfgs_memory", self.lbfgs_memory as f64, 1.0, 100.0)?;
        Ok(())
    }
}

/// How a solve ended. Every status but `Failed` comes with a usable (finite, bounded) command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SolveStatus {
    /// PANOC met its tolerance.
    Converged,
    /// The iteration cap was hit; the best feasible iterate is used.
    MaxIterations,
    /// The time budget ran out; the best feasible iterate is used.
    OutOfTime,
    /// Non-finite input or a solver error: the command is zero (stop).
    Failed,
}

/// The result of one solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solution {
    /// Command for `base_link`: always finite and inside the speed, yaw-rate and rate bounds.
    pub cmd: Twist2,
    /// How the solve ended.
    pub status: SolveStatus,
    /// PANOC iterations used.
    pub iterations: usize,
    /// Cost of the returned plan (NaN when `Failed`).
    pub cost: f64,
}

/// The parameters of one solve: everything the cost depends on besides the inputs.
#[derive(Debug, Clone)]
struct Stage {
    n: usize,
    dt: f64,
    q_y: f64,
    q_psi: f64,
    r_v: f64,
    r_w: f64,
    s_v: f64,
    s_w: f64,
    terminal: f64,
    accel_max: f64,
    yaw_accel_max: f64,
    penalty: f64,
    lateral0: f64,
    heading0: f64,
    v_ref: f64,
    v_prev: f64,
    w_prev: f64,
    kappa: Vec<f64>,
    corridor: Corridor,
}

/// The wheel corridor of one solve: tyre positions in `base_link` and the inter-row band each must
/// stay in, as offsets from the lane centre line (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Corridor {
    /// 0 when the path has no rows along it.
    weight: f64,
    /// The body's angle to the motion the MPC plans with, rad: under a slide the state's heading is the
    /// course over the ground and the body points `crab` off it (see [`Mpc::solve_crabbing`]).
    crab_rad: f64,
    /// Weight added past a tyre's allowance, 1/m² (see [`MpcConfig::corridor_hold_weight`]).
    hold_weight: f64,
    /// `(x, y)` of each tyre in `base_link`, m, the centre of its inter-row, m, and its allowance: how
    /// far from that centre it may go before `hold_weight` applies, m (its band, or where it is at the
    /// solve when that is farther).
    tyres: [(f64, f64, f64, f64); 4],
    /// Half-width of the band a tyre centre may use, m.
    half_band: f64,
}

impl Corridor {
    const OFF: Corridor = Corridor {
        weight: 0.0,
        hold_weight: 0.0,
        crab_rad: 0.0,
        tyres: [(0.0, 0.0, 0.0, 0.0); 4],
        half_band: 0.0,
    };

    /// The corridor for rows `spacing` apart, or none when the tyres do not fit between them, for a
    /// body `crab_rad` off the planned motion, with the robot at `now` = `(e_y, e_ψ)`.
    fn new(cfg: &MpcConfig, spacing: Option<f64>, crab_rad: f64, now: (f64, f64)) -> Self {
        let Some(s) = spacing.filter(|s| s.is_finite() && *s > 0.0) else { return Self::OFF };
        let half_band = 0.5 * s - 0.5 * cfg.tire_width_m - cfg.row_clearance_m;
        if cfg.corridor_weight <= 0.0 || half_band <= 0.0 {
            return Self::OFF;
        }
        // Inter-row centres are whole spacings from the lane centre; each tyre belongs to the nearest.
        let band = (cfg.wheel_y_m / s).round() * s;
        let (x, y) = (cfg.wheel_x_m, cfg.wheel_y_m);
        // Each tyre may use its band, or as far out as it is now when it is already over a row; past
        // that it is held (`corridor_hold_weight`), while the whole excess is brought back at
        // `corridor_weight`, which leaves a robot off the line room to turn back to it.
        let (sn, cs) = (now.1 - crab_rad).sin_cos();
        let allowed = |x: f64, y: f64, band: f64| (now.0 + x * sn + y * cs - band).abs().max(half_band);
        Self {
            weight: cfg.corridor_weight,
            hold_weight: (cfg.corridor_hold_weight - cfg.corridor_weight).max(0.0),
            crab_rad,
            tyres: [
                (x, y, band, allowed(x, y, band)),
                (x, -y, -band, allowed(x, -y, -band)),
                (-x, y, band, allowed(-x, y, band)),
                (-x, -y, -band, allowed(-x, -y, -band)),
            ],
            half_band,
        }
    }

    /// Cost of the tyres at state `(e_y, e_ψ)` and its partial derivatives.
    fn cost(&self, ey: f64, ep: f64) -> (f64, f64, f64) {
        if self.weight <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        // The tyres sit where the body points, not where it moves.
        let (sn, cs) = (ep - self.crab_rad).sin_cos();
        let (mut j, mut d_ey, mut d_ep) = (0.0, 0.0, 0.0);
        for &(x, y, band, allowed) in &self.tyres {
            let off = ey + x * sn + y * cs - band;
            let excess = off.abs() - self.half_band;
            if excess > 0.0 {
                let worse = (off.abs() - allowed).max(0.0);
                j += self.weight * excess * excess + self.hold_weight * worse * worse;
                let g = 2.0 * (self.weight * excess + self.hold_weight * worse) * off.signum();
                d_ey += g;
                d_ep += g * (x * cs - y * sn);
            }
        }
        (j, d_ey, d_ep)
    }
}

impl Stage {
    fn from_config(cfg: &MpcConfig) -> Self {
        Self {
            n: cfg.horizon_steps,
            dt: cfg.step_s,
            q_y: cfg.lateral_weight,
            q_psi: cfg.heading_weight,
            r_v: cfg.speed_weight,
            r_w: cfg.yaw_rate_weight,
            s_v: cfg.accel_weight,
            s_w: cfg.yaw_accel_weight,
            terminal: cfg.terminal_factor,
            accel_max: cfg.accel_max_mps2,
            yaw_accel_max: cfg.yaw_accel_max_radps2,
            penalty: cfg.rate_penalty_weight,
            lateral0: 0.0,
            heading0: 0.0,
            v_ref: 0.0,
            v_prev: 0.0,
            w_prev: 0.0,
            kappa: vec![0.0; cfg.horizon_steps],
            corridor: Corridor::OFF,
        }
    }

    fn weight(&self, k: usize) -> f64 {
        if k + 1 == self.n { self.terminal } else { 1.0 }
    }

    /// One Euler step; returns the next state and the floored denominator with a flag telling
    /// whether the floor was active (then its derivative is zero).
    fn step(&self, ey: f64, ep: f64, v: f64, w: f64, kappa: f64) -> (f64, f64, f64, bool) {
        let raw = 1.0 - kappa * ey;
        let floored = raw < MIN_DENOMINATOR;
        let den = if floored { MIN_DENOMINATOR } else { raw };
        let (sn, cs) = ep.sin_cos();
        (ey + self.dt * v * sn, ep + self.dt * (w - kappa * v * cs / den), den, floored)
    }

    /// Soft rate penalty and its derivative with respect to the rate.
    fn excess(&self, rate: f64, limit: f64) -> (f64, f64) {
        let over = rate.abs() - limit;
        if over > 0.0 {
            (self.penalty * over * over, 2.0 * self.penalty * over * rate.signum())
        } else {
            (0.0, 0.0)
        }
    }

    fn cost(&self, u: &[f64]) -> f64 {
        let (mut ey, mut ep) = (self.lateral0, self.heading0);
        let (mut vp, mut wp) = (self.v_prev, self.w_prev);
        let mut j = 0.0;
        for (k, (uk, &kappa)) in u.chunks_exact(2).zip(&self.kappa).enumerate() {
            let (v, w) = (uk[0], uk[1]);
            let (ey1, ep1, _, _) = self.step(ey, ep, v, w, kappa);
            (ey, ep) = (ey1, ep1);
            j += self.weight(k) * (self.q_y * ey * ey + self.q_psi * ep * ep);
            j += self.corridor.cost(ey, ep).0;
            let (dv, dw) = (v - self.v_ref, w - kappa * self.v_ref);
            j += self.r_v * dv * dv + self.r_w * dw * dw;
            let (av, aw) = ((v - vp) / self.dt, (w - wp) / self.dt);
            j += self.s_v * av * av + self.s_w * aw * aw;
            j += self.excess(av, self.accel_max).0 + self.excess(aw, self.yaw_accel_max).0;
            (vp, wp) = (v, w);
        }
        j
    }

    /// Adjoint (reverse-mode) gradient of [`Stage::cost`].
    fn gradient(&self, u: &[f64], grad: &mut [f64]) {
        let mut states = [[0.0f64; 2]; MAX_HORIZON + 1];
        let n = self.n.min(u.len() / 2).min(grad.len() / 2).min(self.kappa.len());
        if let Some(first) = states.first_mut() {
            *first = [self.lateral0, self.heading0];
        }
        for k in 0..n {
            let [ey, ep] = states[k];
            let (ey1, ep1, _, _) = self.step(ey, ep, u[2 * k], u[2 * k + 1], self.kappa[k]);
            states[k + 1] = [ey1, ep1];
        }
        // Direct input terms first: effort and rates (each rate touches u_k and u_{k-1}).
        let (mut vp, mut wp) = (self.v_prev, self.w_prev);
        for k in 0..n {
            let (v, w, kappa) = (u[2 * k], u[2 * k + 1], self.kappa[k]);
            grad[2 * k] = 2.0 * self.r_v * (v - self.v_ref);
            grad[2 * k + 1] = 2.0 * self.r_w * (w - kappa * self.v_ref);
            let (av, aw) = ((v - vp) / self.dt, (w - wp) / self.dt);
            let gv = (2.0 * self.s_v * av + self.excess(av, self.accel_max).1) / self.dt;
            let gw = (2.0 * self.s_w * aw + self.excess(aw, self.yaw_accel_max).1) / self.dt;
            grad[2 * k] += gv;
            grad[2 * k + 1] += gw;
            if k > 0 {
                grad[2 * k - 2] -= gv;
                grad[2 * k - 1] -= gw;
            }
            (vp, wp) = (v, w);
        }
        // Backward pass: lambda is dJ/dz_{k+1}.
        let (mut ly, mut lp) = (0.0, 0.0);
        for k in (0..n).rev() {
            let [ey1, ep1] = states[k + 1];
            let wk = self.weight(k);
            let (_, c_ey, c_ep) = self.corridor.cost(ey1, ep1);
            ly += 2.0 * wk * self.q_y * ey1 + c_ey;
            lp += 2.0 * wk * self.q_psi * ep1 + c_ep;
            let [ey, ep] = states[k];
            let (v, kappa) = (u[2 * k], self.kappa[k]);
            let (_, _, den, floored) = self.step(ey, ep, v, u[2 * k + 1], kappa);
            let (sn, cs) = ep.sin_cos();
            grad[2 * k] += self.dt * (sn * ly - kappa * cs / den * lp);
            grad[2 * k + 1] += self.dt * lp;
            let d_ey = if floored { 0.0 } else { -kappa * kappa * v * cs / (den * den) };
            let d_ep_y = v * cs;
            let d_ep_p = kappa * v * sn / den;
            (ly, lp) = (ly + self.dt * d_ey * lp, lp + self.dt * (d_ep_y * ly + d_ep_p * lp));
        }
    }
}

/// The controller: configuration, solver cache and warm start, reused every cycle.
pub struct Mpc {
    cfg: MpcConfig,
    stage: Stage,
    cache: PANOCCache,
    u: Vec<f64>,
    u_min: Vec<f64>,
    u_max: Vec<f64>,
}

impl std::fmt::Debug for Mpc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mpc").field("cfg", &self.cfg).field("plan", &self.u).finish_non_exhaustive()
    }
}

impl Mpc {
    /// Validates the configuration and allocates everything a solve needs.
    pub fn new(cfg: MpcConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let n = cfg.horizon_steps;
        let u_min = (0..2 * n)
            .map(|i| if i % 2 == 0 { cfg.speed_min_mps } else { -cfg.yaw_rate_max_radps })
            .collect();
        let u_max =
            (0..2 * n).map(|i| if i % 2 == 0 { cfg.speed_max_mps } else { cfg.yaw_rate_max_radps }).collect();
        Ok(Self {
            stage: Stage::from_config(&cfg),
            cache: PANOCCache::new(2 * n, cfg.tolerance, cfg.lbfgs_memory),
            u: vec![0.0; 2 * n],
            u_min,
            u_max,
            cfg,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &MpcConfig {
        &self.cfg
    }

    /// The current plan `[v_0, ω_0, v_1, ω_1, …]` (m/s, rad/s), the warm start of the next solve.
    pub fn plan(&self) -> &[f64] {
        &self.u
    }

    /// Forgets the warm start (after a stop or a jump of the reference).
    pub fn reset(&mut self) {
        self.u.fill(0.0);
    }

    /// Weighs the heading error of the next solves by `heading_weight` times `sliding_heading_factor`
    /// (true: a wheel slide is being read) or by `heading_weight` alone (false, the default).
    pub fn set_sliding(&mut self, sliding: bool) {
        let factor = if sliding { self.cfg.sliding_heading_factor } else { 1.0 };
        self.stage.q_psi = factor * self.cfg.heading_weight;
    }

    /// Solves for the command that tracks `path` from the robot's place `state` on it at cruise speed
    /// `speed_mps`, given the `previous` command (the one applied one step ago) for the rate terms.
    /// `time_budget` caps the wall time of this solve (OpEn's clock); `None` relies on the iteration cap.
    pub fn solve(
        &mut self,
        state: &Frenet,
        path: &Path,
        speed_mps: f64,
        previous: Twist2,
        time_budget: Option<Duration>,
    ) -> Solution {
        self.solve_crabbing(state, 0.0, path, speed_mps, previous, time_budget)
    }

    /// [`Mpc::solve`] for a robot that slides sideways: `state`'s heading is its course over the ground
    /// (the direction it moves, which the unicycle model follows), and its body points `crab_rad` off
    /// it (heading = course − crab), which places the tyres for the wheel corridor. Under a slide of
    /// 0.2 m per metre the body turns 11° into it, and a 1.2 m long robot then swings its corner tyres
    /// 12 cm across the rows.
    pub fn solve_crabbing(
        &mut self,
        state: &Frenet,
        crab_rad: f64,
        path: &Path,
        speed_mps: f64,
        previous: Twist2,
        time_budget: Option<Duration>,
    ) -> Solution {
        let finite = crab_rad.is_finite()
            && state.lateral_m.is_finite()
            && state.heading_rad.is_finite()
            && state.s_m.is_finite()
            && speed_mps.is_finite()
            && previous.is_finite()
            && path
                .segments()
                .iter()
                .all(|s| s.start.is_finite() && s.length_m.is_finite() && s.curvature_per_m.is_finite());
        if !finite {
            return self.fail();
        }
        let v_ref = speed_mps.clamp(self.cfg.speed_min_mps, self.cfg.speed_max_mps);
        let previous = Twist2::new(
            previous.v.clamp(self.cfg.speed_min_mps, self.cfg.speed_max_mps),
            previous.omega.clamp(-self.cfg.yaw_rate_max_radps, self.cfg.yaw_rate_max_radps),
        );
        // The mode's speed is a limit, not only a reference: without it the MPC may speed up to pull a
        // tyre back into its corridor sooner (measured: 0.94 m/s at a row end with a 0.5 m/s cruise,
        // and crop contacts; 10 % over it still gave 3 contacts after a LiDAR dropout). A zero speed (a
        // pivot) stays zero.
        let v_cap = v_ref;
        for hi in self.u_max.iter_mut().step_by(2) {
            *hi = v_cap;
        }
        self.shift_warm_start(v_ref);
        for v in self.u.iter_mut().step_by(2) {
            *v = v.min(v_cap);
        }
        self.stage.lateral0 = state.lateral_m;
        self.stage.heading0 = state.heading_rad;
        self.stage.v_ref = v_ref;
        self.stage.v_prev = previous.v;
        self.stage.w_prev = previous.omega;
        self.stage.corridor =
            Corridor::new(&self.cfg, path.row_spacing_m(), crab_rad, (state.lateral_m, state.heading_rad));
        // Curvature where the warm-start plan expects to be at each stage.
        let mut s = state.s_m;
        for (kappa, uk) in self.stage.kappa.iter_mut().zip(self.u.chunks_exact(2)) {
            *kappa = path.curvature_at(s);
            s += uk[0].max(0.0) * self.cfg.step_s;
        }

        let stage = &self.stage;
        let bounds = Rectangle::new(Some(&self.u_min), Some(&self.u_max));
        let cost = |u: &[f64], c: &mut f64| -> Result<(), SolverError> {
            *c = stage.cost(u);
            Ok(())
        };
        let grad = |u: &[f64], g: &mut [f64]| -> Result<(), SolverError> {
            stage.gradient(u, g);
            Ok(())
        };
        let problem = Problem::new(&bounds, grad, cost);
        let mut optimizer =
            PANOCOptimizer::new(problem, &mut self.cache).with_max_iter(self.cfg.max_iterations);
        if let Some(budget) = time_budget {
            optimizer = optimizer.with_max_duration(budget);
        }
        let result = optimizer.solve(&mut self.u);
        let Ok(report) = result else { return self.fail() };
        let status = match report.exit_status() {
            ExitStatus::Converged => SolveStatus::Converged,
            ExitStatus::NotConvergedIterations => SolveStatus::MaxIterations,
            ExitStatus::NotConvergedOutOfTime => SolveStatus::OutOfTime,
        };
        let (Some(&v), Some(&w)) = (self.u.first(), self.u.get(1)) else { return self.fail() };
        let dv = self.cfg.accel_max_mps2 * self.cfg.step_s;
        let dw = self.cfg.yaw_accel_max_radps2 * self.cfg.step_s;
        let cmd = Twist2::new(
            v.clamp(previous.v - dv, previous.v + dv).clamp(self.cfg.speed_min_mps, self.cfg.speed_max_mps),
            w.clamp(previous.omega - dw, previous.omega + dw)
                .clamp(-self.cfg.yaw_rate_max_radps, self.cfg.yaw_rate_max_radps),
        );
        if !cmd.is_finite() {
            return self.fail();
        }
        Solution { cmd, status, iterations: report.iterations(), cost: report.cost_value() }
    }

    /// Shifts the previous plan one step earlier; a cold plan starts at the cruise speed.
    fn shift_warm_start(&mut self, v_ref: f64) {
        if self.u.iter().all(|&x| x == 0.0) {
            for uk in self.u.chunks_exact_mut(2) {
                uk[0] = v_ref;
            }
            return;
        }
        let len = self.u.len();
        self.u.copy_within(2..len, 0);
        if len >= 4 {
            let (head, tail) = self.u.split_at_mut(len - 2);
            tail.copy_from_slice(&head[len - 4..]);
        }
    }

    fn fail(&mut self) -> Solution {
        self.reset();
        Solution { cmd: Twist2::ZERO, status: SolveStatus::Failed, iterations: 0, cost: f64::NAN }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose2;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Robot states at a solve: on the centre line (every tyre in its band), and 0.3 m left of it
    /// (every tyre over a row at 0.75 m spacing, so each is costed at `corridor_weight`).
    const CENTRED: (f64, f64) = (0.0, 0.0);
    const OVER_A_ROW: (f64, f64) = (0.3, 0.0);

    fn straight() -> Path {
        let mut p = Path::with_capacity(1);
        p.push(Pose2::new(-1.0, 0.0, 0.0), 50.0, 0.0);
        p
    }

    #[test]
    fn adjoint_gradient_matches_finite_differences() {
        // With the tyres held (the opt-in term), which the default config leaves out.
        let cfg = held();
        let mut stage = Stage::from_config(&cfg);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        stage.lateral0 = 0.25;
        stage.heading0 = -0.12;
        stage.v_ref = 0.6;
        stage.v_prev = 0.4;
        stage.w_prev = 0.1;
        for k in stage.kappa.iter_mut() {
            *k = rng.random_range(-0.8..0.8);
        }
        let u: Vec<f64> = (0..2 * cfg.horizon_steps).map(|_| rng.random_range(-0.9..0.9)).collect();
        // Far enough off the centre line for the tyres to leave their corridors; and the same with the
        // body crabbing 0.15 rad off the planned motion (a slide).
        for crab in [0.0, 0.15] {
            stage.corridor = Corridor::new(&cfg, Some(0.75), crab, (stage.lateral0, stage.heading0));
            assert!(stage.corridor.cost(0.25, -0.12).0 > 0.0);
            let mut g = vec![0.0; u.len()];
            stage.gradient(&u, &mut g);
            let h = 1e-6;
            for i in 0..u.len() {
                let (mut up, mut um) = (u.clone(), u.clone());
                up[i] += h;
                um[i] -= h;
                let fd = (stage.cost(&up) - stage.cost(&um)) / (2.0 * h);
                // Central differences: O(h²) truncation plus round-off ~ 1e-10 / h on costs of order 10.
                assert!(
                    (fd - g[i]).abs() < 1e-5 * (1.0 + fd.abs()),
                    "crab {crab}, component {i}: adjoint {} vs fd {fd}",
                    g[i]
                );
            }
        }
    }

    #[test]
    fn a_crabbing_body_places_its_tyres_by_its_heading_not_its_course() {
        // Sliding left at 0.2 m/m, the body points atan(0.2) ≈ 0.2 rad right of its motion: its tyres
        // sit where a robot turned by -0.2 rad would have them.
        let cfg = MpcConfig::default();
        let crabbing = Corridor::new(&cfg, Some(0.75), 0.2, OVER_A_ROW);
        let aligned = Corridor::new(&cfg, Some(0.75), 0.0, (OVER_A_ROW.0, OVER_A_ROW.1 - 0.2));
        for (ey, ep) in [(0.1, 0.0), (0.25, 0.05), (-0.2, -0.1)] {
            assert_eq!(crabbing.cost(ey, ep), aligned.cost(ey, ep - 0.2), "{ey} {ep}");
        }
        // 0.25 m left of the line, moving along it: aligned, the left tyres are 0.262 m from their
        // inter-row centre, inside the 0.27 m band; crabbing, the rear tyres swing 0.12 m further left
        // (0.368 and 0.374 m off), out of their bands.
        assert_eq!(aligned.cost(0.25, 0.0).0, 0.0);
        assert!(crabbing.cost(0.25, 0.0).0 > 0.0);
    }

    #[test]
    fn the_wheel_corridor_costs_only_tyres_over_a_row() {
        let cfg = MpcConfig::default();
        let corridor = Corridor::new(&cfg, Some(0.75), 0.0, OVER_A_ROW);
        // Centred: every tyre 0.762 m out, in its inter-row 0.375-1.125 m (band half-width 0.27 m).
        assert_eq!(corridor.cost(0.0, 0.0), (0.0, 0.0, 0.0));
        // 0.3 m left: the left tyres are 0.312 m from their inter-row centre, 0.042 m too far; the
        // right ones 0.288 m, 0.018 m too far (within 3 cm of the lane's right row).
        let (j, d_ey, d_ep) = corridor.cost(0.3, 0.0);
        let expected = 2.0 * cfg.corridor_weight * (0.042f64.powi(2) + 0.018f64.powi(2));
        assert!((j - expected).abs() < 1e-9, "{j} vs {expected}");
        assert!(d_ey > 0.0 && d_ep.abs() < 1e-9, "{d_ey} {d_ep}");
        // No rows along the path, or rows too narrow for a tyre: no corridor.
        assert_eq!(Corridor::new(&cfg, None, 0.0, CENTRED).cost(0.3, 0.2), (0.0, 0.0, 0.0));
        assert_eq!(Corridor::new(&cfg, Some(0.2), 0.0, CENTRED).cost(0.3, 0.2), (0.0, 0.0, 0.0));
    }

    /// The default MPC with tyres held in their inter-rows (`corridor_hold_weight`, opt-in).
    fn held() -> MpcConfig {
        MpcConfig { corridor_hold_weight: 6000.0, ..MpcConfig::default() }
    }

    #[test]
    fn a_tyre_is_held_where_it_was_and_brought_back_gently() {
        let cfg = held();
        let extra = cfg.corridor_hold_weight - cfg.corridor_weight;
        assert!(extra > 0.0);
        // 0.3 m left the tyres are over the rows (see above). From the centre line that is a move out
        // of their bands, held at `corridor_hold_weight`; for a robot already there it costs only the
        // pull back, `corridor_weight`.
        let from_centre = Corridor::new(&cfg, Some(0.75), 0.0, CENTRED).cost(0.3, 0.0);
        let from_there = Corridor::new(&cfg, Some(0.75), 0.0, OVER_A_ROW).cost(0.3, 0.0);
        let ratio = cfg.corridor_hold_weight / cfg.corridor_weight;
        assert!((from_centre.0 - ratio * from_there.0).abs() < 1e-9, "{from_centre:?} {from_there:?}");
        assert!((from_centre.1 - ratio * from_there.1).abs() < 1e-6, "{from_centre:?} {from_there:?}");
        // From there, 5 cm further left is held again: each tyre's extra 0.05 m (the right ones lean
        // towards the lane's right row) costs `extra · 0.05²` on top of the pull back.
        let further = Corridor::new(&cfg, Some(0.75), 0.0, OVER_A_ROW).cost(0.35, 0.0).0;
        let pull = Corridor::new(&cfg, Some(0.75), 0.0, (0.35, 0.0)).cost(0.35, 0.0).0;
        assert!((further - pull - 4.0 * extra * 0.05f64.powi(2)).abs() < 1e-9, "{further} {pull}");
    }

    /// Drives the Frenet model on a straight lane 0.75 m wide from `lateral_m` off its centre line for
    /// 4 s and returns the farthest any tyre went over its inter-row's band (`Corridor` geometry), m.
    fn worst_tyre_excess(cfg: &MpcConfig, lateral_m: f64) -> f64 {
        rejoin(cfg, lateral_m, false).0
    }

    /// [`worst_tyre_excess`] with the heading weighed as under a slide (`sliding`, see
    /// [`Mpc::set_sliding`]), and the largest heading off the lane on the way back, rad.
    fn rejoin(cfg: &MpcConfig, lateral_m: f64, sliding: bool) -> (f64, f64) {
        let mut path = straight();
        path.set_row_spacing(Some(0.75));
        let corridor = Corridor::new(cfg, Some(0.75), 0.0, OVER_A_ROW);
        let mut mpc = Mpc::new(cfg.clone()).unwrap();
        mpc.set_sliding(sliding);
        let (mut state, mut prev, mut worst, mut turned) =
            (Frenet { lateral_m, ..Frenet::default() }, Twist2::new(0.5, 0.0), 0.0f64, 0.0f64);
        for _ in 0..40 {
            let sol = mpc.solve(&state, &path, 0.5, prev, None);
            assert_ne!(sol.status, SolveStatus::Failed);
            prev = sol.cmd;
            state.lateral_m += cfg.step_s * prev.v * state.heading_rad.sin();
            state.heading_rad += cfg.step_s * prev.omega;
            state.s_m += cfg.step_s * prev.v;
            let (sn, cs) = state.heading_rad.sin_cos();
            for &(x, y, band, _) in &corridor.tyres {
                worst = worst.max((state.lateral_m + x * sn + y * cs - band).abs() - corridor.half_band);
            }
            turned = turned.max(state.heading_rad.abs());
        }
        (worst, turned)
    }

    #[test]
    fn a_slide_being_read_turns_back_to_the_lane_along_a_flatter_arc_when_opted_in() {
        // The lane moved 0.2 or 0.25 m under the robot as registration caught up with a slide. At
        // the plain heading weight the robot turns back 0.23 rad and its worst tyre goes 12 and 38 mm
        // past its band; under the opt-in slide factor of 5 (a weight of 40), 0.16 rad, 8 and 33 mm.
        // By default the factor is 1.
        let defaults = MpcConfig::default();
        assert_eq!(rejoin(&defaults, 0.2, true), rejoin(&defaults, 0.2, false), "opt-in");
        let cfg = MpcConfig { sliding_heading_factor: 5.0, ..defaults };
        for lateral_m in [0.2, 0.25] {
            let ((plain_excess, plain_turn), (excess, turn)) =
                (rejoin(&cfg, lateral_m, false), rejoin(&cfg, lateral_m, true));
            assert!(turn < 0.8 * plain_turn && excess < plain_excess, "{lateral_m}: {turn} vs {plain_turn}");
        }
    }

    #[test]
    fn a_lane_that_moves_sideways_does_not_swing_a_rear_tyre_over_a_row() {
        // The lane moved 0.2 m right under the robot (a registration correction): its tyres are still
        // in their bands (the left ones 0.212 m off their inter-row centre, inside 0.27 m), but turning
        // back swings the rear left tyre outwards. Held, it goes 5 mm past its band; with the single
        // corridor weight, 12 mm. From 0.25 m (0.262 m, nearly out): 26 mm against 38. The band keeps
        // `row_clearance_m` (30 mm) from the row line, so only the unheld tyre from 0.25 m crosses it.
        let cfg = held();
        let single = MpcConfig::default();
        assert!(single.corridor_hold_weight <= single.corridor_weight, "holding is opt-in");
        for (lateral_m, most_m) in [(0.2, 0.006), (0.25, 0.03)] {
            let (held, unheld) = (worst_tyre_excess(&cfg, lateral_m), worst_tyre_excess(&single, lateral_m));
            assert!(held < most_m && held < 0.7 * unheld, "{lateral_m}: held {held} vs {unheld}");
        }
    }

    #[test]
    fn non_finite_state_stops() {
        let mut mpc = Mpc::new(MpcConfig::default()).unwrap();
        let s = Frenet { lateral_m: f64::NAN, ..Frenet::default() };
        let sol = mpc.solve(&s, &straight(), 0.5, Twist2::new(0.5, 0.0), None);
        assert_eq!(sol.status, SolveStatus::Failed);
        assert_eq!(sol.cmd, Twist2::ZERO);
        let sol = mpc.solve(&Frenet::default(), &straight(), f64::INFINITY, Twist2::ZERO, None);
        assert_eq!(sol.status, SolveStatus::Failed);
        assert_eq!(sol.cmd, Twist2::ZERO);
    }

    #[test]
    fn on_the_line_it_drives_straight() {
        let mut mpc = Mpc::new(MpcConfig::default()).unwrap();
        let mut prev = Twist2::new(0.5, 0.0);
        for _ in 0..5 {
            let sol = mpc.solve(&Frenet::default(), &straight(), 0.5, prev, None);
            assert_ne!(sol.status, SolveStatus::Failed);
            prev = sol.cmd;
        }
        // Tolerance: the converged plan is within PANOC's 1e-4 residual of the exact (0.5, 0).
        assert!((prev.v - 0.5).abs() < 1e-3 && prev.omega.abs() < 1e-3, "{prev:?}");
    }

    #[test]
    fn absurd_config_is_refused() {
        let cfg = MpcConfig { horizon_steps: 0, ..MpcConfig::default() };
        assert!(Mpc::new(cfg).unwrap_err().to_string().contains("mpc.horizon_steps"));
        let cfg = MpcConfig { speed_max_mps: -1.0, ..MpcConfig::default() };
        assert!(Mpc::new(cfg).unwrap_err().to_string().contains("mpc.speed_max_mps"));
        let cfg = MpcConfig { sliding_heading_factor: f64::NAN, ..MpcConfig::default() };
        assert!(Mpc::new(cfg).unwrap_err().to_string().contains("mpc.sliding_heading_factor"));
        let cfg = MpcConfig { sliding_hold_m: -1.0, ..MpcConfig::default() };
        assert!(Mpc::new(cfg).unwrap_err().to_string().contains("mpc.sliding_hold_m"));
    }
}
