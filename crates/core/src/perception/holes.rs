//! Holes in a scan: sectors of the sensor's azimuth with no return although the scan has returns on
//! both sides of them (a packet the driver dropped, a part of the window blocked by mud; the
//! simulator's `fault-partial-scan`). A row that crosses the edge of a hole is seen in part, and the
//! centroid of the part seen leans away from the hole, bin after bin along the edge's ray: the joint
//! fit turns with them (soak seed 1140, grown corn, an 86° sector missing over 2 m: the fit turned
//! 0.1 rad and narrowed by 15 %, and the robot followed it into a row). The lanes leave the bins a hole
//! touches out of the scan's evidence and let the map, carried by the odometry, hold them; once a
//! hole hides the lane's own rows and the map runs short ahead, the scan does not see the rows.
//!
//! Azimuths are binned by the diamond angle, a monotonic stand-in for `atan2` that costs one division.

use nalgebra::{Isometry3, Point3 as P3};

use crate::geometry::{Mount, Point3};

use super::interleave::for_each_interleaved;

/// Azimuth bins over the sensor's full turn: about 0.7° ahead of the sensor and 1.4° at 45° to its
/// side, where a VLP-16 at 10 Hz fires three to seven columns.
const BINS: usize = 512;
/// Fewest consecutive empty bins that make a hole: about 3° ahead. A bin holds a few columns of 16
/// rings, so a return lost here and there (dust, the driver's random dropouts) never empties one.
const MIN_HOLE_BINS: usize = 4;
/// Bins added to each side of a hole when a region is tested against it: the edge of a hole falls
/// anywhere inside its last bin, and the levelling turns the points by up to a few degrees.
const MARGIN_BINS: i32 = 2;

/// The holes of the last scan, and the frame to test `base_link` regions against them.
#[derive(Debug, Clone)]
pub(crate) struct Holes {
    counts: Vec<u32>,
    /// Inclusive bin ranges with no return, margins not included.
    found: Vec<(i32, i32)>,
    base_to_sensor: Isometry3<f64>,
    /// Heights between which the canopy of the scan lies, `base_link` z, m.
    canopy_z_m: [f64; 2],
}

impl Default for Holes {
    fn default() -> Self {
        Self {
            counts: vec![0; BINS],
            found: Vec::new(),
            base_to_sensor: Isometry3::identity(),
            canopy_z_m: [0.0; 2],
        }
    }
}

/// The diamond angle of the direction (x, y), in [0, 4]: 2 straight ahead (+x), rising to the left,
/// wrapping behind the sensor, so that the frontal returns of a scan never straddle the wrap.
/// Branch-free: the returns of a scan sweep every quadrant.
fn diamond(x: f32, y: f32) -> f32 {
    let p = y / (x.abs() + y.abs()).max(f32::MIN_POSITIVE);
    let behind = 2.0f32.copysign(y) - p;
    2.0 + if x >= 0.0 { p } else { behind }
}

fn bin(x: f32, y: f32) -> usize {
    ((diamond(x, y) * (BINS as f32 / 4.0)) as usize).min(BINS - 1)
}

impl Holes {
    /// Starts a scan seen from `mount`.
    pub(crate) fn begin(&mut self, mount: &Mount) {
        self.counts.iter_mut().for_each(|c| *c = 0);
        self.found.clear();
        self.base_to_sensor = mount.isometry().inverse();
    }

    /// Counts the finite returns of a scan, sensor frame.
    pub(crate) fn count(&mut self, points: &[Point3]) {
        let counts = &mut self.counts;
        // A column's returns share a bin: interleaved, the increments do not wait on each other.
        for_each_interleaved(points, |p| {
            if p.is_finite()
                && let Some(c) = counts.get_mut(bin(p.x, p.y))
            {
                *c += 1;
            }
        });
    }

    /// Finds the holes among the returns counted since [`Holes::begin`].
    pub(crate) fn finish(&mut self) {
        let Some(first) = self.counts.iter().position(|&c| c > 0) else { return };
        let last = self.counts.iter().rposition(|&c| c > 0).unwrap_or(first);
        let mut run_start = None;
        for i in first..=last {
            match (self.counts[i] == 0, run_start) {
                (true, None) => run_start = Some(i),
                (false, Some(s)) => {
                    if i - s >= MIN_HOLE_BINS {
                        self.found.push((s as i32, i as i32 - 1));
                    }
                    run_start = None;
                }
                _ => {}
            }
        }
    }

    /// Sets the heights between which the scan's canopy lies, `base_link` z, m.
    pub(crate) fn set_canopy(&mut self, lo_m: f64, hi_m: f64) {
        let hi_m = if hi_m.is_finite() { hi_m.max(lo_m) } else { lo_m };
        self.canopy_z_m = [lo_m, hi_m];
    }

    /// True when the scan has a hole.
    pub(crate) fn any(&self) -> bool {
        !self.found.is_empty()
    }

    /// Each hole's width, degrees, counting every bin as 360/512°.
    #[cfg(test)]
    fn widths_deg(&self) -> Vec<f64> {
        self.found.iter().map(|&(a, b)| f64::from(b - a + 1) * 360.0 / BINS as f64).collect()
    }

    /// True when a hole (with its margin) reaches into the canopy over the box `x`, `y` (`base_link`,
    /// m): the sensor's azimuths of the corners of the box up to the canopy's heights span a range that
    /// meets it.
    pub(crate) fn touches(&self, x: [f64; 2], y: [f64; 2]) -> bool {
        if self.found.is_empty() {
            return false;
        }
        let (mut lo, mut hi) = (i32::MAX, i32::MIN);
        for (&x, &y, &z) in corners(&x, &y, &self.canopy_z_m) {
            let s = self.base_to_sensor * P3::new(x, y, z);
            let b = bin(s.x as f32, s.y as f32) as i32;
            lo = lo.min(b);
            hi = hi.max(b);
        }
        self.found.iter().any(|&(a, b)| lo <= b + MARGIN_BINS && hi >= a - MARGIN_BINS)
    }
}

/// The eight corners of a box.
fn corners<'a>(
    x: &'a [f64; 2],
    y: &'a [f64; 2],
    z: &'a [f64; 2],
) -> impl Iterator<Item = (&'a f64, &'a f64, &'a f64)> {
    x.iter().flat_map(move |a| y.iter().flat_map(move |b| z.iter().map(move |c| (a, b, c))))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A VLP-16-like revolution on the paper's mount over flat ground: 16 rings, 0.2° columns,
    /// returns where the ray meets the ground within 10 m, none at sensor azimuths in `missing`
    /// (degrees, counter-clockwise from the sensor's +x) and none for every `drop_every`-th return.
    fn scan(mount: &Mount, missing: Option<(f64, f64)>, drop_every: usize) -> Vec<Point3> {
        let to_base = mount.isometry();
        let mut out = vec![];
        let mut k = 0usize;
        for col in 0..1800 {
            let az = f64::from(col) * 0.2 - 180.0;
            if missing.is_some_and(|(a, b)| (a..=b).contains(&az)) {
                continue;
            }
            for ring in 0..16 {
                k += 1;
                if drop_every > 0 && k.is_multiple_of(drop_every) {
                    continue;
                }
                let el = (-15.0 + 2.0 * f64::from(ring)).to_radians();
                let d = nalgebra::Vector3::new(
                    el.cos() * az.to_radians().cos(),
                    el.cos() * az.to_radians().sin(),
                    el.sin(),
                );
                let w = to_base.rotation * d;
                // Ground at base_link z = 0.
                if w.z >= -1e-3 {
                    continue;
                }
                let r = -mount.z_m / w.z;
                if r <= 10.0 {
                    out.push(Point3::new((d.x * r) as f32, (d.y * r) as f32, (d.z * r) as f32));
                }
            }
        }
        out
    }

    fn holes_of(points: &[Point3], mount: &Mount) -> Holes {
        let mut h = Holes::default();
        h.begin(mount);
        h.set_canopy(0.0, 0.6);
        h.count(points);
        h.finish();
        h
    }

    #[test]
    fn a_whole_scan_has_no_hole_even_with_returns_lost_here_and_there() {
        let mount = Mount::default();
        for drop_every in [0, 10, 3] {
            let h = holes_of(&scan(&mount, None, drop_every), &mount);
            assert!(!h.any(), "dropping every {drop_every}th return: {:?}", h.widths_deg());
        }
    }

    #[test]
    fn a_missing_sector_is_one_hole_of_its_width() {
        let mount = Mount::default();
        let h = holes_of(&scan(&mount, Some((-64.0, 22.0)), 0), &mount);
        let widths = h.widths_deg();
        // Diamond-angle bins are narrower than degrees at the side: the width reads high there.
        assert!(widths.len() == 1 && (80.0..=130.0).contains(&widths[0]), "{widths:?}");
        // A box on a row 1 m left and 3 m ahead lies at about +25° from the sensor (0.6 m ahead
        // of base_link): the sector's edge at +22° reaches it; one on the far left does not.
        assert!(h.touches([2.9, 3.1], [0.9, 1.1]));
        assert!(!h.touches([2.9, 3.1], [2.9, 3.1]));
        // Straight ahead, inside the sector.
        assert!(h.touches([2.9, 3.1], [-0.1, 0.1]));
        // The same boxes in a whole scan.
        let whole = holes_of(&scan(&mount, None, 0), &mount);
        assert!(!whole.touches([2.9, 3.1], [-0.1, 0.1]));
    }

    #[test]
    fn the_diamond_angle_rises_with_the_azimuth_and_is_two_straight_ahead() {
        let mut last = -1.0;
        for k in -179..180 {
            let a = f64::from(k).to_radians();
            let d = diamond(a.cos() as f32, a.sin() as f32);
            assert!(d > last, "azimuth {k}°: {d} after {last}");
            last = d;
        }
        assert_eq!(diamond(1.0, 0.0), 2.0);
    }
}
