//! Gentle terrain relief: a smooth height field `h(x, y)` in the field frame (m), the sum of three
//! plane waves with seeded phases. Plants stand on it, the LiDAR sees it, and the robot's z, roll and
//! pitch follow it. `|h| ≤ amplitude_m` everywhere.

use std::f64::consts::TAU;

/// Relative weights of the three waves; they sum to one so the amplitude bounds the height.
const WEIGHTS: [f64; 3] = [0.5, 0.3, 0.2];
/// Direction (unit) and wavelength factor of each wave.
const WAVES: [(f64, f64, f64); 3] = [(1.0, 0.0, 1.0), (0.6, 0.8, 0.7), (-0.5, 0.866_025_4, 0.45)];

/// The terrain height field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relief {
    amplitude_m: f64,
    wavelength_m: f64,
    phases: [f64; 3],
}

impl Relief {
    /// Flat ground at z = 0.
    pub fn flat() -> Self {
        Self { amplitude_m: 0.0, wavelength_m: 1.0, phases: [0.0; 3] }
    }

    /// Relief of peak amplitude `amplitude_m` and main wavelength `wavelength_m`; phases in radians.
    pub fn new(amplitude_m: f64, wavelength_m: f64, phases: [f64; 3]) -> Self {
        Self { amplitude_m, wavelength_m, phases }
    }

    /// True when the ground is the plane z = 0.
    pub fn is_flat(&self) -> bool {
        self.amplitude_m == 0.0
    }

    /// Peak amplitude, m.
    pub fn amplitude_m(&self) -> f64 {
        self.amplitude_m
    }

    /// Ground height at `(x, y)` (field frame), m.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        if self.is_flat() {
            return 0.0;
        }
        let mut h = 0.0;
        for k in 0..3 {
            let (ux, uy, f) = WAVES[k];
            let kk = TAU / (self.wavelength_m * f);
            h += WEIGHTS[k] * (kk * (ux * x + uy * y) + self.phases[k]).sin();
        }
        self.amplitude_m * h
    }

    /// Ground gradient `(∂h/∂x, ∂h/∂y)` at `(x, y)`.
    pub fn gradient(&self, x: f64, y: f64) -> (f64, f64) {
        if self.is_flat() {
            return (0.0, 0.0);
        }
        let (mut gx, mut gy) = (0.0, 0.0);
        for k in 0..3 {
            let (ux, uy, f) = WAVES[k];
            let kk = TAU / (self.wavelength_m * f);
            let c = WEIGHTS[k] * kk * (kk * (ux * x + uy * y) + self.phases[k]).cos();
            gx += c * ux;
            gy += c * uy;
        }
        (self.amplitude_m * gx, self.amplitude_m * gy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn height_is_bounded_and_gradient_matches_finite_differences() {
        let r = Relief::new(0.2, 20.0, [0.3, 1.1, 2.0]);
        for i in 0..200 {
            let (x, y) = (i as f64 * 0.37, (i as f64 * 0.91).sin() * 5.0);
            assert!(r.height(x, y).abs() <= 0.2 + 1e-12);
            let (gx, gy) = r.gradient(x, y);
            let e = 1e-5;
            let fx = (r.height(x + e, y) - r.height(x - e, y)) / (2.0 * e);
            let fy = (r.height(x, y + e) - r.height(x, y - e)) / (2.0 * e);
            // Central differences are exact to ~1e-9 at this step.
            assert!((gx - fx).abs() < 1e-7 && (gy - fy).abs() < 1e-7);
        }
        assert_eq!(Relief::flat().height(3.0, 4.0), 0.0);
    }
}
