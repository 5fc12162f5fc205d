//! Control: the centre-line reference between the detected rows, a nonlinear MPC that outputs
//! `(v, ω)`, and the lane-switching state machine that covers a whole field.
