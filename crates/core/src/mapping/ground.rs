//! Local ground height on a coarse grid: a low percentile of z per cell, holes filled from the
//! neighbours, then smoothed, and read back with bilinear interpolation. A low percentile (not the
//! minimum) ignores the odd point below the ground (multipath, noise) while still reaching the soil
//! between the rows under a closed canopy.

/// Ground heights on a regular grid whose cell `(0, 0)` starts at the local origin `(0, 0)`.
#[derive(Debug, Clone)]
pub(crate) struct Ground {
    cell_m: f64,
    nx: usize,
    ny: usize,
    /// Row-major (`iy * nx + ix`) ground height at each cell centre, m.
    z_m: Vec<f64>,
}

impl Ground {
    /// Estimates the ground under `xyz` (local frame, every coordinate finite and `x, y >= 0`).
    ///
    /// Two passes: the percentile per cell gives a first surface; then, per cell, the points within
    /// [`SOIL_BAND_M`] above the percentile of the residuals to that surface are averaged. The second
    /// pass removes the percentile's bias (a sloped cell's low percentile lies below its centre, and a
    /// noisy soil's below its mean) that would otherwise lift soil points above the clearance.
    ///
    /// Allocates the grid, a cell-ordered copy of the points and a scratch buffer.
    pub(crate) fn estimate(xyz: &[[f64; 3]], extent_m: [f64; 2], cell_m: f64, percentile: f64) -> Self {
        let nx = cells_along(extent_m[0], cell_m);
        let ny = cells_along(extent_m[1], cell_m);
        let cell_of = |p: &[f64; 3]| {
            let ix = ((p[0] / cell_m) as usize).min(nx - 1);
            let iy = ((p[1] / cell_m) as usize).min(ny - 1);
            iy * nx + ix
        };
        // Counting sort of the points by cell so each cell is one contiguous run.
        let mut start = vec![0usize; nx * ny + 1];
        for p in xyz {
            start[cell_of(p) + 1] += 1;
        }
        for i in 0..nx * ny {
            start[i + 1] += start[i];
        }
        // A copy in cell order: both passes then read memory sequentially (random access into a
        // multi-million-point cloud costs more than the copy).
        let mut fill = start.clone();
        let mut sorted = vec![[0.0f64; 3]; xyz.len()];
        for p in xyz {
            let c = cell_of(p);
            sorted[fill[c]] = *p;
            fill[c] += 1;
        }
        let mut ground = Self { cell_m, nx, ny, z_m: vec![f64::NAN; nx * ny] };
        let mut scratch = Vec::new();
        for c in 0..nx * ny {
            scratch.clear();
            scratch.extend(sorted[start[c]..start[c + 1]].iter().map(|p| p[2]));
            ground.z_m[c] = percentile_of(&mut scratch, percentile).unwrap_or(f64::NAN);
        }
        ground.drop_raised_cells();
        ground.fill_holes();
        ground.smooth();

        let mut correction = Self { cell_m, nx, ny, z_m: vec![f64::NAN; nx * ny] };
        for c in 0..nx * ny {
            scratch.clear();
            scratch
                .extend(sorted[start[c]..start[c + 1]].iter().map(|p| p[2] - ground.height_at(p[0], p[1])));
            let Some(low) = percentile_of(&mut scratch, percentile) else { continue };
            let (sum, n) = scratch
                .iter()
                .filter(|r| (low..=low + SOIL_BAND_M).contains(*r))
                .fold((0.0, 0usize), |(s, n), r| (s + r, n + 1));
            let dz = sum / n.max(1) as f64;
            // The correction is a bias of centimetres; a large one is a cell without soil.
            if dz.abs() <= MAX_GROUND_STEP_M / 2.0 {
                correction.z_m[c] = dz;
            }
        }
        correction.fill_holes();
        correction.smooth();
        for (z, dz) in ground.z_m.iter_mut().zip(&correction.z_m) {
            *z += dz;
        }
        ground
    }

    /// Height of the ground at a local `(x, y)`, m: bilinear between cell centres, flat over the outer
    /// half cells (extrapolating a slope from edge cells, which see the least soil, proved worse).
    pub(crate) fn height_at(&self, x: f64, y: f64) -> f64 {
        let fx = (x / self.cell_m - 0.5).clamp(0.0, (self.nx - 1) as f64);
        let fy = (y / self.cell_m - 0.5).clamp(0.0, (self.ny - 1) as f64);
        let (ix, iy) = (fx.floor() as usize, fy.floor() as usize);
        let (ix1, iy1) = ((ix + 1).min(self.nx - 1), (iy + 1).min(self.ny - 1));
        let (tx, ty) = (fx - ix as f64, fy - iy as f64);
        let at = |i: usize, j: usize| self.z_m[j * self.nx + i];
        let low = at(ix, iy) * (1.0 - tx) + at(ix1, iy) * tx;
        let high = at(ix, iy1) * (1.0 - tx) + at(ix1, iy1) * tx;
        low * (1.0 - ty) + high * ty
    }

    /// Forgets cells far above most of their neighbours: a cell that saw only canopy (no soil through
    /// it) would lift the ground, and every plant above it would vanish below the clearance.
    fn drop_raised_cells(&mut self) {
        let mut raised = Vec::new();
        let mut around = Vec::with_capacity(8);
        for iy in 0..self.ny {
            for ix in 0..self.nx {
                let own = self.z_m[iy * self.nx + ix];
                around.clear();
                for jy in iy.saturating_sub(1)..=(iy + 1).min(self.ny - 1) {
                    for jx in ix.saturating_sub(1)..=(ix + 1).min(self.nx - 1) {
                        let z = self.z_m[jy * self.nx + jx];
                        if (jx, jy) != (ix, iy) && !z.is_nan() {
                            around.push(z);
                        }
                    }
                }
                if let Some(median) = percentile_of(&mut around, 0.5)
                    && own - median > MAX_GROUND_STEP_M
                {
                    raised.push(iy * self.nx + ix);
                }
            }
        }
        for c in raised {
            self.z_m[c] = f64::NAN;
        }
    }

    /// Empty cells take the mean of their known neighbours, growing inwards until none is left.
    fn fill_holes(&mut self) {
        loop {
            let mut next = self.z_m.clone();
            let mut missing = 0;
            let mut filled = 0;
            for iy in 0..self.ny {
                for ix in 0..self.nx {
                    if !self.z_m[iy * self.nx + ix].is_nan() {
                        continue;
                    }
                    missing += 1;
                    if let Some(mean) = self.neighbour_mean(ix, iy) {
                        next[iy * self.nx + ix] = mean;
                        filled += 1;
                    }
                }
            }
            self.z_m = next;
            // `filled == 0` with cells missing only happens when no cell had a point at all, which
            // the caller rules out; stop anyway rather than loop.
            if missing == 0 || filled == 0 {
                break;
            }
        }
        for z in &mut self.z_m {
            if z.is_nan() {
                *z = 0.0;
            }
        }
    }

    /// One pass of a 3x3 mean, which removes the cell-to-cell jitter of the percentile. Edge cells
    /// keep their value: a one-sided mean would bend a slope at the field's border.
    fn smooth(&mut self) {
        let mut next = self.z_m.clone();
        for iy in 1..self.ny.saturating_sub(1) {
            for ix in 1..self.nx.saturating_sub(1) {
                let own = self.z_m[iy * self.nx + ix];
                let n = self.neighbour_mean(ix, iy).unwrap_or(own);
                next[iy * self.nx + ix] = (own + 8.0 * n) / 9.0;
            }
        }
        self.z_m = next;
    }

    /// Mean of the known (non-NaN) 8-neighbours of a cell.
    fn neighbour_mean(&self, ix: usize, iy: usize) -> Option<f64> {
        let (mut sum, mut n) = (0.0, 0usize);
        for jy in iy.saturating_sub(1)..=(iy + 1).min(self.ny - 1) {
            for jx in ix.saturating_sub(1)..=(ix + 1).min(self.nx - 1) {
                let z = self.z_m[jy * self.nx + jx];
                if (jx, jy) != (ix, iy) && !z.is_nan() {
                    sum += z;
                    n += 1;
                }
            }
        }
        (n > 0).then(|| sum / n as f64)
    }
}

/// Thickness of the soil layer above the low percentile, m: thicker than a survey scanner's range
/// noise, thinner than any crop's bulk.
const SOIL_BAND_M: f64 = 0.05;

/// Largest rise of a cell's ground above the median of its neighbours, m: steeper than any field
/// (a 15 % slope over a 1 m cell), lower than any crop that closes its canopy.
const MAX_GROUND_STEP_M: f64 = 0.15;

/// The `q`-quantile of `values` (reordered), or `None` when empty.
fn percentile_of(values: &mut [f64], q: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let k = ((values.len() - 1) as f64 * q).round() as usize;
    Some(*values.select_nth_unstable_by(k, f64::total_cmp).1)
}

/// Number of cells of `cell_m` that cover `extent_m` (at least one).
pub(crate) fn cells_along(extent_m: f64, cell_m: f64) -> usize {
    ((extent_m / cell_m).floor() as usize + 1).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_a_tilted_plane_under_clutter() {
        // Ground z = 0.05 x on a 10 m x 6 m patch, with every third sample lifted 0.5 m (plants).
        let mut pts = Vec::new();
        for i in 0..100 {
            for j in 0..60 {
                let (x, y) = (i as f64 * 0.1 + 0.05, j as f64 * 0.1 + 0.05);
                let lift = if (i + j) % 3 == 0 { 0.5 } else { 0.0 };
                pts.push([x, y, 0.05 * x + lift]);
            }
        }
        let g = Ground::estimate(&pts, [10.0, 6.0], 1.0, 0.1);
        // Away from the edges the plane is recovered to 5 mm.
        for &(x, y) in &[(2.0, 2.0), (5.5, 3.0), (8.0, 4.0)] {
            let err = g.height_at(x, y) - 0.05 * x;
            assert!(err.abs() < 0.005, "ground error {err} at ({x}, {y})");
        }
    }

    #[test]
    fn a_cell_that_sees_only_canopy_is_not_ground() {
        // Flat soil at z = 0 except one cell holding only a 1.5 m canopy.
        let mut pts = Vec::new();
        for i in 0..60 {
            for j in 0..60 {
                let (x, y) = (i as f64 * 0.1 + 0.05, j as f64 * 0.1 + 0.05);
                let z = if (3.0..4.0).contains(&x) && (3.0..4.0).contains(&y) { 1.5 } else { 0.0 };
                pts.push([x, y, z]);
            }
        }
        let g = Ground::estimate(&pts, [6.0, 6.0], 1.0, 0.05);
        assert!(g.height_at(3.5, 3.5).abs() < 1e-9, "{}", g.height_at(3.5, 3.5));
    }

    #[test]
    fn empty_cells_are_filled_from_neighbours() {
        // Points only in the left half; the right half takes the known height.
        let pts: Vec<[f64; 3]> =
            (0..50).flat_map(|i| (0..50).map(move |j| [i as f64 * 0.1, j as f64 * 0.1, 1.5])).collect();
        let g = Ground::estimate(&pts, [10.0, 5.0], 1.0, 0.1);
        assert!((g.height_at(9.5, 2.5) - 1.5).abs() < 1e-9);
    }
}
