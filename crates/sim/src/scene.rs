//! The ray-casting scene: plant primitives binned in a 2-D uniform grid with a per-cell height bound, and
//! the terrain. It sits between the field generator (which fills it) and the LiDAR (which casts rays).
//!
//! Speed comes from culling, so that a ray tests few primitives:
//! - rays start where they first dip below the tallest thing in the field (rays going up never enter
//!   the grid), then cross blocks of 4 × 4 cells while they pass over the blocks' height bounds, and
//!   cells whose height bound lies under the ray are skipped without touching a primitive;
//! - each cell lists a primitive with the height range of the part of it that lies over that cell (a
//!   tilted leaf spans 20 cm of height but a few cm over one 10 cm cell), sorted from the highest top
//!   down, so a ray coming down scans only the primitives reaching above it and tests only those whose
//!   range meets its own height range across the cell;
//! - only hits inside the current cell count (a hit farther on is found in the cell it lies in), and
//!   the first one ends the ray.
//!
//! [`Scene::cast`] casts one ray that way. The LiDAR casts beam packets instead (`packet`: a laser's
//! rays at 16 consecutive azimuths traverse a bounding volume hierarchy over the primitives together,
//! `bvh`, each box and each primitive tested on all 16 at once, in two AVX2 registers where the CPU
//! has them), which return exactly what `cast` returns ray by ray; `cast` stays the path of the rays
//! packets do not suit (rising or near-vertical rays, relief) and the reference the packet tests
//! compare against. The scene's primitives are stored in the order of the hierarchy's leaves.

//! Primitives are cheap to intersect: flat patches (rectangles and ellipses) for leaves, vertical
//! cylinders for stalks, axis-aligned spheroids for weed clumps. All geometry is `f32` in the field frame
//! (metres). A test checks the grid against a brute-force caster (every primitive, no grid).

use crate::terrain::Relief;

mod bvh;
mod packet;

use bvh::Bvh;

pub(crate) use packet::Isa;
pub(crate) use packet::LANES as PACKET_LANES;

/// What a LiDAR return hit. For evaluation only: a real sensor does not know it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Class {
    /// Bare soil.
    Ground,
    /// A crop plant (stalk, leaf, leaflet).
    Crop,
    /// A weed clump.
    Weed,
}

/// One primitive's geometry, field frame, metres.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Shape {
    /// A flat patch `o + s·u + t·w`, `u ⟂ w`, stored as the plane normal and the dual axes
    /// `ua = u/|u|²`, `wa = w/|w|²` so that the patch coordinates of a point are two dot products.
    Patch { o: [f32; 3], n: [f32; 3], ua: [f32; 3], wa: [f32; 3], ellipse: bool },
    /// A vertical cylinder (stalk) with a flat top.
    Cylinder { cx: f32, cy: f32, r2: f32, z0: f32, z1: f32 },
    /// An axis-aligned spheroid: centre and inverse radii (horizontal, vertical).
    Spheroid { c: [f32; 3], inv_r: f32, inv_rz: f32 },
}

/// A primitive and its class.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Prim {
    pub shape: Shape,
    pub class: Class,
}

impl Prim {
    /// A rectangle (`ellipse == false`) or ellipse with centre `o` and half-axes `u ⟂ w`.
    pub fn patch(o: [f64; 3], u: [f64; 3], w: [f64; 3], ellipse: bool, class: Class) -> Self {
        let n = cross(u, w);
        let (uu, ww) = (dot(u, u).max(1e-12), dot(w, w).max(1e-12));
        Self {
            shape: Shape::Patch {
                o: f32s(o),
                n: f32s(n),
                ua: f32s([u[0] / uu, u[1] / uu, u[2] / uu]),
                wa: f32s([w[0] / ww, w[1] / ww, w[2] / ww]),
                ellipse,
            },
            class,
        }
    }

    /// A vertical cylinder of radius `r` from `z0` to `z1`.
    pub fn cylinder(cx: f64, cy: f64, r: f64, z0: f64, z1: f64, class: Class) -> Self {
        Self {
            shape: Shape::Cylinder {
                cx: cx as f32,
                cy: cy as f32,
                r2: (r * r) as f32,
                z0: z0 as f32,
                z1: z1 as f32,
            },
            class,
        }
    }

    /// An axis-aligned spheroid with horizontal radius `r` and vertical radius `rz`.
    pub fn spheroid(c: [f64; 3], r: f64, rz: f64, class: Class) -> Self {
        Self {
            shape: Shape::Spheroid { c: f32s(c), inv_r: (1.0 / r) as f32, inv_rz: (1.0 / rz) as f32 },
            class,
        }
    }

    /// Axis-aligned bounds `[xmin, ymin, zmin, xmax, ymax, zmax]`.
    fn bounds(&self) -> [f32; 6] {
        match self.shape {
            Shape::Patch { o, ua, wa, .. } => {
                // Recover the half-axes from the dual axes: u = ua / |ua|².
                let (u, w) = (undual(ua), undual(wa));
                let mut b = [f32::MAX, f32::MAX, f32::MAX, f32::MIN, f32::MIN, f32::MIN];
                for k in 0..3 {
                    let e = u[k].abs() + w[k].abs();
                    b[k] = o[k] - e;
                    b[k + 3] = o[k] + e;
                }
                b
            }
            Shape::Cylinder { cx, cy, r2, z0, z1 } => {
                let r = r2.sqrt();
                [cx - r, cy - r, z0, cx + r, cy + r, z1]
            }
            Shape::Spheroid { c, inv_r, inv_rz } => {
                let (r, rz) = (1.0 / inv_r, 1.0 / inv_rz);
                [c[0] - r, c[1] - r, c[2] - rz, c[0] + r, c[1] + r, c[2] + rz]
            }
        }
    }

    /// Distance along the unit ray `o + t·d` to the primitive, if hit with `t_min < t < t_best`.
    #[inline]
    fn intersect(&self, o: [f32; 3], d: [f32; 3], t_min: f32, t_best: f32) -> Option<f32> {
        match self.shape {
            Shape::Patch { o: po, n, ua, wa, ellipse } => {
                let denom = dot32(n, d);
                if denom.abs() < 1e-12 {
                    return None;
                }
                let t = dot32(n, sub32(po, o)) / denom;
                if !(t > t_min && t < t_best) {
                    return None;
                }
                let q = [o[0] + t * d[0] - po[0], o[1] + t * d[1] - po[1], o[2] + t * d[2] - po[2]];
                let (s, r) = (dot32(q, ua), dot32(q, wa));
                let inside = if ellipse { s * s + r * r <= 1.0 } else { s.abs() <= 1.0 && r.abs() <= 1.0 };
                inside.then_some(t)
            }
            Shape::Cylinder { cx, cy, r2, z0, z1 } => {
                let (ox, oy) = (o[0] - cx, o[1] - cy);
                let mut hit = None;
                let a = d[0] * d[0] + d[1] * d[1];
                if a > 1e-12 {
                    let b = ox * d[0] + oy * d[1];
                    let c = ox * ox + oy * oy - r2;
                    let disc = b * b - a * c;
                    if disc >= 0.0 {
                        let t = (-b - disc.sqrt()) / a;
                        let z = o[2] + t * d[2];
                        if t > t_min && t < t_best && z >= z0 && z <= z1 {
                            hit = Some(t);
                        }
                    }
                }
                // The flat top, seen from above. At the rim, f32 rounding can put it a hair before the
                // wall: the nearer of the two counts, so that the answer does not depend on `t_best`
                // (beam packets test a primitive again with a nearer `t_best`).
                if d[2] < 0.0 {
                    let t = (z1 - o[2]) / d[2];
                    if t > t_min && t < hit.unwrap_or(t_best) {
                        let (x, y) = (ox + t * d[0], oy + t * d[1]);
                        if x * x + y * y <= r2 {
                            hit = Some(t);
                        }
                    }
                }
                hit
            }
            Shape::Spheroid { c, inv_r, inv_rz } => {
                let oo = [(o[0] - c[0]) * inv_r, (o[1] - c[1]) * inv_r, (o[2] - c[2]) * inv_rz];
                let dd = [d[0] * inv_r, d[1] * inv_r, d[2] * inv_rz];
                let a = dot32(dd, dd);
                let b = dot32(oo, dd);
                let cc = dot32(oo, oo) - 1.0;
                let disc = b * b - a * cc;
                if disc < 0.0 {
                    return None;
                }
                let t = (-b - disc.sqrt()) / a;
                (t > t_min && t < t_best).then_some(t)
            }
        }
    }
}

/// Cells per side of a block of the coarse height grid.
const BLOCK: i32 = 4;

/// Slack of the per-cell hit window along the ray, m: covers the f32 rounding of the DDA's cell
/// boundaries (well under a millimetre over 100 m of ray).
const WINDOW_SLACK_M: f32 = 2e-3;
/// Primitives are listed in every cell they come this close to, m; must exceed `WINDOW_SLACK_M`.
const FOOTPRINT_MARGIN_M: f64 = 3e-3;

/// What the grid builder needs of a primitive: its bounding box and, for a flat patch, its plane as
/// `z = gx·x + gy·y + z0` (field frame, m), so that the height range over one small cell is that of the
/// plane over the cell, not the patch's whole height range.
struct Footprint {
    /// `[xmin, ymin, zmin, xmax, ymax, zmax]`.
    b: [f64; 6],
    /// `(gx, gy, z0)` for a patch that is not near vertical.
    plane: Option<(f64, f64, f64)>,
}

impl Footprint {
    fn of(p: &Prim) -> Self {
        let b = p.bounds().map(f64::from);
        let plane = match p.shape {
            // Steeper than ~80°: the plane's height over a cell says nothing the bounds do not.
            Shape::Patch { o, n, .. } if (n[2] as f64).abs() > 0.17 * norm(n) => {
                let (nx, ny, nz) = (n[0] as f64, n[1] as f64, n[2] as f64);
                let (gx, gy) = (-nx / nz, -ny / nz);
                Some((gx, gy, o[2] as f64 - gx * o[0] as f64 - gy * o[1] as f64))
            }
            _ => None,
        };
        Self { b, plane }
    }

    /// Height range `(z_min, z_max)` over the box `[x0, x1] × [y0, y1]`, or `None` when the bounds do
    /// not reach over it. Conservative.
    fn z_range_over(&self, x0: f64, x1: f64, y0: f64, y1: f64) -> Option<(f64, f64)> {
        // Margin: a point within this of a cell edge belongs to both cells, which covers the rounding of
        // the caster's f32 cell boundaries (see `traverse`).
        let m = FOOTPRINT_MARGIN_M;
        let (x0, x1, y0, y1) = (x0 - m, x1 + m, y0 - m, y1 + m);
        let b = &self.b;
        if b[0] > x1 || b[3] < x0 || b[1] > y1 || b[4] < y0 {
            return None;
        }
        let Some((gx, gy, z0)) = self.plane else { return Some((b[2], b[5])) };
        // A linear function over the (clipped) box peaks at its corners.
        let (xa, xb) = (x0.max(b[0]), x1.min(b[3]));
        let (ya, yb) = (y0.max(b[1]), y1.min(b[4]));
        let zx = (gx * xa, gx * xb);
        let zy = (gy * ya, gy * yb);
        let lo = z0 + zx.0.min(zx.1) + zy.0.min(zy.1);
        let hi = z0 + zx.0.max(zx.1) + zy.0.max(zy.1);
        let (lo, hi) = (lo.max(b[2]), hi.min(b[5]));
        // The patch's bounds reach over the box but the patch may not: an empty range means it misses.
        (lo <= hi).then_some((lo, hi))
    }
}

/// A 2-D DDA's state: current square, step directions, ray distance to the next x and y edges and
/// between edges.
struct Dda {
    i: i32,
    j: i32,
    step_i: i32,
    step_j: i32,
    t_next_x: f32,
    t_next_y: f32,
    dt_x: f32,
    dt_y: f32,
}

/// A primitive listed in a cell, with its height range so that a ray passing above or below it within
/// the cell skips it without loading the primitive. Grazing rays (a VLP-16's side beams drop a few
/// centimetres per metre) cross many cells but meet few primitives at their height.
#[derive(Debug, Clone, Copy)]
struct Ref {
    z_min: f32,
    z_max: f32,
    prim: u32,
}

/// What a cell holds beyond its height bound: read only when a ray dips under that bound.
#[derive(Debug, Clone, Copy)]
struct CellInfo {
    /// Highest point of the ground in the cell, m: a ray that stays above it cannot meet the ground here.
    ground_z: f32,
    /// The cell's primitives are `refs[start..end]`.
    start: u32,
    end: u32,
}

/// The scene: primitives, the grid over them, and the terrain.
#[derive(Debug, Clone)]
pub(crate) struct Scene {
    /// The primitives, in the order of the leaves of `bvh`.
    prims: Vec<Prim>,
    /// The hierarchy the beam packets traverse.
    bvh: Bvh,
    relief: Relief,
    /// Upper bound of the relief's slope |∇h| (numerical, with margin), for sphere tracing.
    relief_slope: f64,
    /// Grid origin (field frame), m.
    x0: f32,
    y0: f32,
    /// Cell edge, m.
    cell_m: f32,
    inv_cell: f32,
    nx: i32,
    ny: i32,
    /// Per cell, row-major (`j * nx + i`): highest point of any primitive or of the ground, m. Apart from
    /// the rest of the cell so that the march over the canopy reads 4 bytes a cell (the array of a
    /// 200 m field fits in a 2 MB L2 cache; with the rest it would not).
    heights: Vec<f32>,
    /// Per block of `BLOCK` × `BLOCK` cells, row-major (`bj * bnx + bi`): the highest of its cells'
    /// `heights`. A ray coming down over the canopy crosses a few blocks instead of a dozen cells
    /// before it reaches anything.
    block_heights: Vec<f32>,
    bnx: i32,
    bny: i32,
    /// Per cell: the ground bound and the primitive references.
    cells: Vec<CellInfo>,
    /// CSR: primitives of cell `c` are `refs[cells[c].start..cells[c].end]`.
    refs: Vec<Ref>,
    /// Highest and lowest point of the whole scene, m.
    top_z: f32,
    bottom_z: f32,
    /// The variant of the beam-packet code this scene casts with (the best the CPU has).
    isa: Isa,
}

impl Scene {
    /// Bins `prims` into a grid of `cell_m` cells covering `[x_min, x_max] × [y_min, y_max]`, which must
    /// contain every primitive: outside the grid the caster sees only ground.
    pub fn build(
        prims: Vec<Prim>,
        relief: Relief,
        x_min: f64,
        x_max: f64,
        y_min: f64,
        y_max: f64,
        cell_m: f64,
    ) -> Self {
        let (bvh, prims) = Bvh::build(prims);
        let nx = (((x_max - x_min) / cell_m).ceil() as i32).max(1);
        let ny = (((y_max - y_min) / cell_m).ceil() as i32).max(1);
        let n_cells = (nx as usize) * (ny as usize);
        let (x0, y0, cell) = (x_min as f32, y_min as f32, cell_m as f32);
        let inv_cell = 1.0 / cell;
        // Ground bound per cell: the relief is smooth at the cell scale, so corners and centre bound it
        // to well under a millimetre; 2 mm of margin covers the rest.
        let mut max_z = vec![0f32; n_cells];
        for j in 0..ny {
            for i in 0..nx {
                let (xa, ya) = (x_min + i as f64 * cell_m, y_min + j as f64 * cell_m);
                let mut h = f64::MIN;
                for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)] {
                    h = h.max(relief.height(xa + u * cell_m, ya + v * cell_m));
                }
                max_z[(j * nx + i) as usize] = (h + 0.002) as f32;
            }
        }
        let ground_z = max_z.clone();
        let range = |b: &[f32; 6]| {
            let i0 = (((b[0] - x0) * inv_cell).floor() as i32).clamp(0, nx - 1);
            let i1 = (((b[3] - x0) * inv_cell).floor() as i32).clamp(0, nx - 1);
            let j0 = (((b[1] - y0) * inv_cell).floor() as i32).clamp(0, ny - 1);
            let j1 = (((b[4] - y0) * inv_cell).floor() as i32).clamp(0, ny - 1);
            (i0, i1, j0, j1)
        };
        // Every (cell, primitive) overlap, with the primitive's height range inside that cell's column:
        // a tilted leaf spans 20 cm of height overall but a few centimetres above any one small cell, and
        // that is what lets a ray skip it. Two passes (count, then fill) keep the build at one allocation.
        let overlaps = |p: &Prim, mut visit: Box<dyn FnMut(usize, f64, f64) + '_>| {
            let (i0, i1, j0, j1) = range(&p.bounds());
            let shape = Footprint::of(p);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let (cx0, cy0) = (x_min + i as f64 * cell_m, y_min + j as f64 * cell_m);
                    if let Some((z_lo, z_hi)) = shape.z_range_over(cx0, cx0 + cell_m, cy0, cy0 + cell_m) {
                        visit((j * nx + i) as usize, z_lo, z_hi);
                    }
                }
            }
        };
        let mut start = vec![0u32; n_cells + 1];
        for p in &prims {
            overlaps(
                p,
                Box::new(|c, _, z_hi| {
                    start[c + 1] += 1;
                    max_z[c] = max_z[c].max(z_hi as f32 + 1e-3);
                }),
            );
        }
        for c in 0..n_cells {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut refs = vec![Ref { z_min: 0.0, z_max: 0.0, prim: 0 }; start[n_cells] as usize];
        for (k, p) in prims.iter().enumerate() {
            overlaps(
                p,
                Box::new(|c, z_lo, z_hi| {
                    // 1 mm of slack: a flat leaf has z_min == z_max and the ray's f32 height must not miss it.
                    refs[fill[c] as usize] =
                        Ref { z_min: z_lo as f32 - 1e-3, z_max: z_hi as f32 + 1e-3, prim: k as u32 };
                    fill[c] += 1;
                }),
            );
        }
        // Per cell, highest top first: a ray coming down meets a cell's primitives only down to the first
        // one whose top lies under the ray. Ties by index keep the build deterministic.
        for c in 0..n_cells {
            if let Some(cell) = refs.get_mut(start[c] as usize..start[c + 1] as usize) {
                cell.sort_unstable_by(|a, b| b.z_max.total_cmp(&a.z_max).then(a.prim.cmp(&b.prim)));
            }
        }
        let top_z = max_z.iter().copied().fold(relief.amplitude_m() as f32, f32::max) + 0.01;
        let bottom_z = -(relief.amplitude_m() as f32) - 0.01;
        let cells = (0..n_cells)
            .map(|c| CellInfo { ground_z: ground_z[c], start: start[c], end: start[c + 1] })
            .collect();
        let relief_slope = slope_bound(&relief, x_min, x_max, y_min, y_max, cell_m);
        let (bnx, bny) = ((nx + BLOCK - 1) / BLOCK, (ny + BLOCK - 1) / BLOCK);
        let mut block_heights = vec![f32::MIN; (bnx as usize) * (bny as usize)];
        for j in 0..ny {
            for i in 0..nx {
                let b = ((j / BLOCK) * bnx + i / BLOCK) as usize;
                if let (Some(h), Some(bh)) = (max_z.get((j * nx + i) as usize), block_heights.get_mut(b)) {
                    *bh = bh.max(*h);
                }
            }
        }
        Self {
            prims,
            bvh,
            relief,
            relief_slope,
            x0,
            y0,
            cell_m: cell,
            inv_cell,
            nx,
            ny,
            heights: max_z,
            block_heights,
            bnx,
            bny,
            cells,
            refs,
            top_z,
            bottom_z,
            isa: Isa::detect(),
        }
    }

    /// Number of primitives.
    pub fn primitive_count(&self) -> usize {
        self.prims.len()
    }

    /// Casts the unit ray `o + t·d` (field frame) and returns the first hit with `t ≤ t_max`.
    pub fn cast(&self, o: [f32; 3], d: [f32; 3], t_max: f32) -> Option<(f32, Class)> {
        self.cast_from(o, d, 0.0, t_max)
    }

    /// Like [`Scene::cast`] but only the hits with `t ≥ t_from` (`t_from ≥ 0`), give or take
    /// `WINDOW_SLACK_M`: for a ray known to meet nothing before `t_from`.
    pub fn cast_from(&self, o: [f32; 3], d: [f32; 3], t_from: f32, t_max: f32) -> Option<(f32, Class)> {
        // Everything lies between bottom_z and top_z: clip the ray to that slab first.
        let (mut t_lo, mut t_hi) = (t_from, t_max);
        if d[2].abs() < 1e-9 {
            if o[2] > self.top_z || o[2] < self.bottom_z {
                return None;
            }
        } else {
            let ta = (self.top_z - o[2]) / d[2];
            let tb = (self.bottom_z - o[2]) / d[2];
            t_lo = t_lo.max(ta.min(tb));
            t_hi = t_hi.min(ta.max(tb));
        }
        if t_lo >= t_hi {
            return None;
        }
        // Clip to the grid rectangle.
        let (gx1, gy1) = (self.x0 + self.nx as f32 * self.cell_m, self.y0 + self.ny as f32 * self.cell_m);
        let (mut g_lo, mut g_hi) = (t_lo, t_hi);
        for (oc, dc, lo, hi) in [(o[0], d[0], self.x0, gx1), (o[1], d[1], self.y0, gy1)] {
            if dc.abs() < 1e-12 {
                if oc < lo || oc > hi {
                    g_hi = -1.0;
                }
            } else {
                let (a, b) = ((lo - oc) / dc, (hi - oc) / dc);
                g_lo = g_lo.max(a.min(b));
                g_hi = g_hi.min(a.max(b));
            }
        }
        if g_lo < g_hi {
            g_lo = self.skip_blocks(o, d, g_lo, g_hi);
        }
        if g_lo < g_hi
            && let Some(hit) = self.traverse(o, d, g_lo, g_hi)
        {
            return Some(hit);
        }
        // Outside the grid there is only ground.
        self.ground_outside(o, d, t_lo, t_hi).map(|t| (t, Class::Ground))
    }

    /// The start of a 2-D DDA at `t0` over a grid of `size` squares (`nx` × `ny`, from the grid origin).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn dda(&self, o: [f32; 3], d: [f32; 3], t0: f32, size: f32, inv_size: f32, nx: i32, ny: i32) -> Dda {
        let eps = 1e-4 * self.cell_m;
        // `as i32` saturates and maps NaN to 0; the clamp keeps the start square inside the grid.
        let square_of = |p: f32, origin: f32, n: i32| (((p - origin) * inv_size) as i32).clamp(0, n - 1);
        let i = square_of(o[0] + (t0 + eps) * d[0], self.x0, nx);
        let j = square_of(o[1] + (t0 + eps) * d[1], self.y0, ny);
        let step_i = if d[0] >= 0.0 { 1 } else { -1 };
        let step_j = if d[1] >= 0.0 { 1 } else { -1 };
        let next_boundary = |k: i32, step: i32, origin: f32, oc: f32, dc: f32| -> (f32, f32) {
            if dc.abs() < 1e-12 {
                return (f32::INFINITY, f32::INFINITY);
            }
            let edge = origin + (k + i32::from(step > 0)) as f32 * size;
            ((edge - oc) / dc, size / dc.abs())
        };
        let (t_next_x, dt_x) = next_boundary(i, step_i, self.x0, o[0], d[0]);
        let (t_next_y, dt_y) = next_boundary(j, step_j, self.y0, o[1], d[1]);
        Dda { i, j, step_i, step_j, t_next_x, t_next_y, dt_x, dt_y }
    }

    /// Where the ray first dips under a block's height bound between `t0` and `t1` (both inside the
    /// grid), less `WINDOW_SLACK_M`; `t1` when it never does. Nothing (ground included: the bounds hold
    /// the ground's) lies before that, so the cell traversal may start there.
    fn skip_blocks(&self, o: [f32; 3], d: [f32; 3], t0: f32, t1: f32) -> f32 {
        let (bnx, bny) = (self.bnx, self.bny);
        let block_m = self.cell_m * BLOCK as f32;
        let Dda { mut i, mut j, step_i, step_j, mut t_next_x, mut t_next_y, dt_x, dt_y } =
            self.dda(o, d, t0, block_m, 1.0 / block_m, bnx, bny);
        // The slack widens each block's stretch of ray backwards, against f32 rounding of the edges.
        let mut t_enter = t0;
        loop {
            let t_x = if t_next_x < t_next_y { t_next_x } else { t_next_y };
            let t_exit = if t_x < t1 { t_x } else { t1 };
            let t_from = if t_enter - WINDOW_SLACK_M > t0 { t_enter - WINDOW_SLACK_M } else { t0 };
            let (z_a, z_b) = (o[2] + t_from * d[2], o[2] + t_exit * d[2]);
            let z_low = if z_a < z_b { z_a } else { z_b };
            match self.block_heights.get((j * bnx + i) as usize) {
                Some(&h) if z_low > h => {}
                _ => return t_from,
            }
            if t_exit >= t1 {
                return t1;
            }
            t_enter = t_exit;
            if t_next_x < t_next_y {
                i += step_i;
                t_next_x += dt_x;
                if i < 0 || i >= bnx {
                    return t1;
                }
            } else {
                j += step_j;
                t_next_y += dt_y;
                if j < 0 || j >= bny {
                    return t1;
                }
            }
        }
    }

    /// 2-D DDA over the cells the ray crosses between `t0` and `t1` (both inside the grid).
    fn traverse(&self, o: [f32; 3], d: [f32; 3], t0: f32, t1: f32) -> Option<(f32, Class)> {
        let (nx, ny) = (self.nx, self.ny);
        let (heights, cells) = (self.heights.as_slice(), self.cells.as_slice());
        let (refs, prims) = (self.refs.as_slice(), self.prims.as_slice());
        let Dda { mut i, mut j, step_i, step_j, mut t_next_x, mut t_next_y, dt_x, dt_y } =
            self.dda(o, d, t0, self.cell_m, self.inv_cell, nx, ny);
        // On flat ground the ground crossing is one division per ray, not one per cell.
        let flat_ground_t = if d[2] < 0.0 { -o[2] / d[2] } else { f32::INFINITY };
        let flat = self.relief.is_flat();
        let mut t_enter = t0;
        let mut z_enter = o[2] + t0 * d[2];
        let mut best = f32::INFINITY;
        let mut best_class = Class::Ground;
        loop {
            // Plain comparisons, not f32::min: no NaN can reach here and they compile to one instruction.
            let t_x = if t_next_x < t_next_y { t_next_x } else { t_next_y };
            let t_exit = if t_x < t1 { t_x } else { t1 };
            // The lowest point of the ray within the cell is at one of its ends.
            let z_exit = o[2] + t_exit * d[2];
            let (z_low, z_high) = if z_exit < z_enter { (z_exit, z_enter) } else { (z_enter, z_exit) };
            let c = (j * nx + i) as usize;
            let Some(&max_z) = heights.get(c) else { break };
            if z_low <= max_z
                && let Some(info) = cells.get(c)
            {
                if z_low <= info.ground_z {
                    let tg = if flat {
                        (flat_ground_t >= t_enter && flat_ground_t <= t_exit).then_some(flat_ground_t)
                    } else {
                        self.ground_in(o, d, t_enter, t_exit)
                    };
                    if let Some(tg) = tg
                        && tg < best
                    {
                        best = tg;
                        best_class = Class::Ground;
                    }
                }
                // Only hits inside this cell count here: a hit farther on lies in a later cell, which lists
                // the primitive too. The window is widened by a few millimetres for f32 rounding of the
                // boundaries, and the primitives' footprints by as much (FOOTPRINT_MARGIN_M).
                let (w_lo, w_hi) = (t_enter - WINDOW_SLACK_M, t_exit + WINDOW_SLACK_M);
                for r in refs.get(info.start as usize..info.end as usize).unwrap_or(&[]) {
                    if r.z_max < z_low {
                        break;
                    }
                    if r.z_min > z_high {
                        continue;
                    }
                    if let Some(p) = prims.get(r.prim as usize)
                        && let Some(t) = p.intersect(o, d, w_lo, if best < w_hi { best } else { w_hi })
                    {
                        best = t;
                        best_class = p.class;
                    }
                }
            }
            if best <= t_exit {
                return Some((best, best_class));
            }
            if t_exit >= t1 {
                break;
            }
            t_enter = t_exit;
            z_enter = z_exit;
            if t_next_x < t_next_y {
                i += step_i;
                t_next_x += dt_x;
                if i < 0 || i >= nx {
                    break;
                }
            } else {
                j += step_j;
                t_next_y += dt_y;
                if j < 0 || j >= ny {
                    break;
                }
            }
        }
        best.is_finite().then_some((best, best_class))
    }

    /// Ground crossing between `ta` and `tb` (a short stretch: one cell).
    #[inline]
    fn ground_in(&self, o: [f32; 3], d: [f32; 3], ta: f32, tb: f32) -> Option<f32> {
        if self.relief.is_flat() {
            if d[2] >= 0.0 {
                return None;
            }
            let t = -o[2] / d[2];
            return (t >= ta && t <= tb).then_some(t);
        }
        let f = |t: f32| {
            let h = self.relief.height((o[0] + t * d[0]) as f64, (o[1] + t * d[1]) as f64) as f32;
            o[2] + t * d[2] - h
        };
        let (mut a, mut b) = (ta, tb);
        let (mut fa, mut fb) = (f(a), f(b));
        if fb > 0.0 || fa < 0.0 {
            return None;
        }
        // Regula falsi: the relief is nearly linear across a cell, two steps reach sub-millimetre.
        for _ in 0..2 {
            if (fa - fb).abs() < 1e-9 {
                break;
            }
            let t = a + (b - a) * fa / (fa - fb);
            let ft = f(t);
            if ft > 0.0 {
                a = t;
                fa = ft;
            } else {
                b = t;
                fb = ft;
            }
        }
        if (fa - fb).abs() < 1e-9 { Some(b) } else { Some(a + (b - a) * fa / (fa - fb)) }
    }

    /// Ground hit of a ray segment outside the grid (bare headland).
    fn ground_outside(&self, o: [f32; 3], d: [f32; 3], ta: f32, tb: f32) -> Option<f32> {
        let t = if self.relief.is_flat() {
            if d[2] >= 0.0 {
                return None;
            }
            -o[2] / d[2]
        } else {
            self.relief_crossing(o, d, ta, tb)?
        };
        // Points inside the grid were handled by the traversal.
        let (x, y) = (o[0] + t * d[0], o[1] + t * d[1]);
        let inside = x >= self.x0
            && y >= self.y0
            && x < self.x0 + self.nx as f32 * self.cell_m
            && y < self.y0 + self.ny as f32 * self.cell_m;
        (t >= ta && t <= tb && !inside).then_some(t)
    }

    /// First crossing of the relief between `ta` and `tb` by sphere tracing: where the ray is `f` above
    /// the ground, no crossing can lie closer than `f / L` (`L` bounds how fast `f` changes along the
    /// ray), so the ray advances by that much (at least 2 cm) until it passes under the ground; bisection
    /// then finds the crossing. Grazing rays far out over the headland need this: a fixed-point iteration
    /// on the plane crossing diverges when the ray is flatter than the relief.
    fn relief_crossing(&self, o: [f32; 3], d: [f32; 3], ta: f32, tb: f32) -> Option<f32> {
        let (o, d) = (o.map(f64::from), d.map(f64::from));
        let amp = self.relief.amplitude_m() + 1e-3;
        // Only where the ray is within the relief's height band can it meet the ground.
        let (mut a, mut b) = (ta as f64, tb as f64);
        if d[2].abs() > 1e-12 {
            let (t_up, t_down) = ((amp - o[2]) / d[2], (-amp - o[2]) / d[2]);
            a = a.max(t_up.min(t_down));
            b = b.min(t_up.max(t_down));
        } else if o[2].abs() > amp {
            return None;
        }
        if a >= b || a.is_nan() || b.is_nan() {
            return None;
        }
        let f = |t: f64| o[2] + t * d[2] - self.relief.height(o[0] + t * d[0], o[1] + t * d[1]);
        let lipschitz = d[2].abs() + self.relief_slope * (d[0] * d[0] + d[1] * d[1]).sqrt();
        let (mut t, mut ft) = (a, f(a));
        if ft <= 0.0 {
            return Some(t as f32);
        }
        while t < b {
            let t2 = (t + (ft / lipschitz).max(0.02)).min(b);
            let f2 = f(t2);
            if f2 <= 0.0 {
                let (mut lo, mut hi) = (t, t2);
                while hi - lo > 1e-5 {
                    let m = 0.5 * (lo + hi);
                    if f(m) > 0.0 {
                        lo = m;
                    } else {
                        hi = m;
                    }
                }
                return Some(hi as f32);
            }
            (t, ft) = (t2, f2);
        }
        None
    }
}

/// An upper bound of the relief's slope: the largest gradient sampled every `step` over the field plus
/// its surroundings, doubled. The relief is a sum of three plane waves, so one wavelength of samples in
/// each direction already sees its steepest slopes; the doubling covers what the sampling misses.
fn slope_bound(relief: &Relief, x_min: f64, x_max: f64, y_min: f64, y_max: f64, step: f64) -> f64 {
    if relief.is_flat() {
        return 0.0;
    }
    let (nx, ny) = (((x_max - x_min) / step) as usize + 1, ((y_max - y_min) / step) as usize + 1);
    let mut g2 = 0f64;
    for j in 0..ny {
        for i in 0..nx {
            let (gx, gy) = relief.gradient(x_min + i as f64 * step, y_min + j as f64 * step);
            g2 = g2.max(gx * gx + gy * gy);
        }
    }
    2.0 * g2.sqrt() + 1e-3
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn dot32(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn sub32(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f32; 3]) -> f64 {
    dot32(a, a).sqrt() as f64
}

fn f32s(a: [f64; 3]) -> [f32; 3] {
    [a[0] as f32, a[1] as f32, a[2] as f32]
}

fn undual(a: [f32; 3]) -> [f32; 3] {
    let n2 = dot32(a, a).max(1e-20);
    [a[0] / n2, a[1] / n2, a[2] / n2]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat() -> Relief {
        Relief::flat()
    }

    fn down(dx: f32, dz: f32) -> [f32; 3] {
        let n = (dx * dx + dz * dz).sqrt();
        [dx / n, 0.0, dz / n]
    }

    #[test]
    fn ground_only_scene_returns_the_plane_distance() {
        let s = Scene::build(vec![], flat(), 0.0, 10.0, -2.0, 2.0, 0.25);
        // 45° down from 1 m: the ground is √2 m away (tolerance 1e-5 m, f32).
        let (t, c) = s.cast([1.0, 0.0, 1.0], down(1.0, -1.0), 100.0).unwrap();
        assert!((t - 2f32.sqrt()).abs() < 1e-5, "{t}");
        assert_eq!(c, Class::Ground);
        // The same ray starting outside the grid still meets the headland ground.
        let (t, _) = s.cast([-5.0, 0.0, 1.0], down(1.0, -1.0), 100.0).unwrap();
        assert!((t - 2f32.sqrt()).abs() < 1e-5);
        assert!(s.cast([1.0, 0.0, 1.0], [0.0, 0.0, 1.0], 100.0).is_none());
    }

    #[test]
    fn a_patch_in_front_of_the_ground_is_hit_first() {
        // A horizontal 0.2 m square leaf at 0.5 m height under the ray.
        let leaf = Prim::patch([1.5, 0.0, 0.5], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], false, Class::Crop);
        let s = Scene::build(vec![leaf], flat(), 0.0, 10.0, -2.0, 2.0, 0.25);
        let (t, c) = s.cast([1.0, 0.0, 1.0], down(1.0, -1.0), 100.0).unwrap();
        assert_eq!(c, Class::Crop);
        assert!((t - 0.5 * 2f32.sqrt()).abs() < 1e-5, "{t}");
    }

    #[test]
    fn cylinders_and_spheroids_are_hit_on_their_near_side() {
        let stalk = Prim::cylinder(3.0, 0.0, 0.1, 0.0, 2.0, Class::Crop);
        let s = Scene::build(vec![stalk], flat(), 0.0, 10.0, -2.0, 2.0, 0.25);
        let (t, _) = s.cast([1.0, 0.0, 0.5], [1.0, 0.0, 0.0], 100.0).unwrap();
        assert!((t - 1.9).abs() < 1e-5, "{t}");
        let weed = Prim::spheroid([3.0, 0.0, 0.0], 0.2, 0.05, Class::Weed);
        let s = Scene::build(vec![weed], flat(), 0.0, 10.0, -2.0, 2.0, 0.25);
        let (t, c) = s.cast([3.0, 0.0, 1.0], [0.0, 0.0, -1.0], 100.0).unwrap();
        assert_eq!(c, Class::Weed);
        assert!((t - 0.95).abs() < 1e-5, "{t}");
    }

    #[test]
    fn grid_traversal_matches_brute_force() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut prims = Vec::new();
        for _ in 0..300 {
            let o = [rng.random_range(0.0..10.0), rng.random_range(-2.0..2.0), rng.random_range(0.05..0.8)];
            let u = [rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1), 0.0];
            let w = [-u[1], u[0], rng.random_range(-0.05..0.05)];
            // Make w exactly perpendicular to u.
            prims.push(Prim::patch(o, u, [w[0], w[1], 0.0], rng.random_bool(0.5), Class::Crop));
        }
        // The grid must contain every primitive (the field leaves its headlands around them).
        let s = Scene::build(prims.clone(), flat(), -1.0, 11.0, -3.0, 3.0, 0.25);
        for _ in 0..2000 {
            let o = [rng.random_range(-1.0..11.0f32), rng.random_range(-3.0..3.0f32), 1.5];
            let mut d = [
                rng.random_range(-1.0..1.0f32),
                rng.random_range(-1.0..1.0f32),
                rng.random_range(-1.0..-0.05f32),
            ];
            let n = dot32(d, d).sqrt();
            d = [d[0] / n, d[1] / n, d[2] / n];
            let fast = s.cast(o, d, 100.0).map(|h| h.0);
            let mut best = -o[2] / d[2];
            for p in &prims {
                if let Some(t) = p.intersect(o, d, 0.0, best) {
                    best = t;
                }
            }
            let fast = fast.unwrap_or(f32::NAN);
            assert!((fast - best).abs() < 1e-4, "grid {fast} vs brute {best}");
        }
    }

    /// Reference ground crossing: 1 cm steps along the ray in f64, then bisection to 1 µm.
    fn brute_ground(relief: &Relief, o: [f32; 3], d: [f32; 3], t_max: f64) -> Option<f64> {
        let f = |t: f64| {
            let p = [0, 1, 2].map(|k| o[k] as f64 + t * d[k] as f64);
            p[2] - relief.height(p[0], p[1])
        };
        let mut a = 0.0;
        while a < t_max {
            let b = (a + 0.01).min(t_max);
            if f(a) > 0.0 && f(b) <= 0.0 {
                let (mut lo, mut hi) = (a, b);
                while hi - lo > 1e-6 {
                    let m = 0.5 * (lo + hi);
                    if f(m) > 0.0 { lo = m } else { hi = m }
                }
                return Some(hi);
            }
            a = b;
        }
        None
    }

    /// Every primitive and the ground, no grid: the answer the grid must reproduce.
    fn brute_cast(s: &Scene, o: [f32; 3], d: [f32; 3], t_max: f32) -> Option<(f32, Class)> {
        let mut best = brute_ground(&s.relief, o, d, t_max as f64).map(|t| (t as f32, Class::Ground));
        for p in &s.prims {
            if let Some(t) = p.intersect(o, d, 0.0, best.map_or(t_max, |b| b.0)) {
                best = Some((t, p.class));
            }
        }
        best
    }

    #[test]
    fn grid_caster_matches_brute_force_on_real_fields() {
        use crate::field::{Crop, Field, FieldConfig, Stage};
        use rand::{RngExt, SeedableRng};
        let fields = [
            // Grown corn with weeds on flat ground, and young soybean on relief.
            FieldConfig {
                crop: Crop::Corn,
                stage: Stage::Grown,
                rows: 4,
                length_m: 4.0,
                headland_m: 1.0,
                weeds_per_m2: 2.0,
                ..FieldConfig::default()
            },
            FieldConfig {
                crop: Crop::Soybean,
                stage: Stage::Young,
                rows: 4,
                length_m: 4.0,
                headland_m: 1.0,
                weeds_per_m2: 2.0,
                relief_m: 0.15,
                relief_wavelength_m: 5.0,
                ..FieldConfig::default()
            },
        ];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        for config in fields {
            let field = Field::generate(&config, 9).unwrap();
            let s = field.scene();
            let (mut crop_hits, mut rays) = (0, 0);
            while rays < 400 {
                // Sensor-like rays from 1-2 m over the field and its surroundings: every other one aimed
                // near a random plant (to exercise leaves and stalks), the rest 0-50° down at any azimuth.
                let o = [
                    rng.random_range(-2.0..6.0f32),
                    rng.random_range(-2.0..4.5f32),
                    rng.random_range(1.0..2.0f32),
                ];
                let d = if rays % 2 == 0 {
                    let stems = field.stems();
                    let stem = stems[rng.random_range(0..stems.len())];
                    let target = [
                        stem.x_m as f32 + rng.random_range(-0.3..0.3f32),
                        stem.y_m as f32 + rng.random_range(-0.3..0.3f32),
                        rng.random_range(0.0..stem.height_m as f32),
                    ];
                    let v = sub32(target, o);
                    let n = dot32(v, v).sqrt();
                    v.map(|c| c / n)
                } else {
                    let az = rng.random_range(0.0..std::f32::consts::TAU);
                    let el = rng.random_range(-0.9..0.05f32);
                    [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]
                };
                let (fast, brute) = (s.cast(o, d, 100.0), brute_cast(s, o, d, 100.0));
                match (fast, brute) {
                    (None, None) => {}
                    (Some((tf, cf)), Some((tb, cb))) => {
                        // 1 mm: the ground reference is bisected in f64, the caster works in f32.
                        assert!(
                            (tf - tb).abs() < 1e-3 && cf == cb,
                            "ray {o:?} {d:?}: grid {tf} {cf:?}, brute {tb} {cb:?}"
                        );
                        crop_hits += usize::from(cf == Class::Crop);
                    }
                    other => panic!("ray {o:?} {d:?}: grid vs brute {other:?}"),
                }
                rays += 1;
            }
            // The rays must actually exercise the plants, not only the ground.
            assert!(crop_hits > 40, "{crop_hits} crop hits");
        }
    }
}
