//! Beam packets: a few rays that share an origin and nearly a direction (one VLP-16 laser fired at
//! consecutive azimuths) cast together through the scene's bounding volume hierarchy (`bvh`), so that
//! they share the traversal and each primitive's load, and the tests run on all rays at once (lanes the
//! compiler vectorises).
//!
//! The traversal keeps a stack of nodes; a node's box is slab-tested against every lane at once (the
//! rays share the origin, so the box's offsets from it are computed once), and the node is entered
//! when some searching lane meets the box between its start and its nearest hit so far. Children are
//! visited near side first along their split axis (the packet's rays go nearly one way), so that far
//! boxes are usually culled by the hits already found. A leaf's primitives are tested against every
//! lane with the arithmetic of [`Scene::cast`], so a packet returns what [`Scene::cast`] returns for
//! each ray, bit for bit where the nearest hit is unique (the tests compare whole revolutions ray by
//! ray).
//!
//! The code is one source compiled twice ([`Isa`]): for the target's baseline (SSE2 on x86-64, where
//! the 16 lanes take four registers) and for AVX2 (two), picked at run time when the scene is
//! built. Neither uses FMA, so both return the same bits (a test compares them ray by ray).
//!
//! Rays the packet does not suit go to [`Scene::cast`]: rays that rise or are near vertical, and relief
//! (the packet takes the flat ground analytically).
//!
//! Cost (AVX2): young corn 11.5M instructions a revolution, grown corn 17.4M; the boxes of a closed
//! canopy's leaves overlap along the crest every downward ray skims, and the nodes a packet visits are
//! nearly all ones it must visit (given each ray's final hit from the start, it pops 5 % fewer), so
//! packets of 16 rays, which share that walk among twice the rays of 8 for a few more instructions,
//! cut the time more than any reordering tried. The measurements and what was tried are written down
//! in `benches/lidar.rs`.

use super::{Class, Prim, Scene, Shape};

/// Rays per packet at most (the lanes of the per-primitive tests).
pub(crate) const LANES: usize = 16;

/// Rays whose horizontal component is below this (steeper than ~87°) are cast alone.
const MIN_HORIZONTAL: f32 = 0.05;

/// What a lane's ray has hit so far: a primitive's index, or one of these.
const WIN_NONE: u32 = u32::MAX;
const WIN_GROUND: u32 = u32::MAX - 1;

/// The rays of a packet, one lane each, structure of arrays so that a primitive test runs on all lanes
/// at once. A lane counts a hit at `t` when `lo < t < best`; an idle lane (no ray, or one whose answer
/// is final) has `lo = +∞`.
#[derive(Debug, Clone)]
struct Lanes {
    /// Unit directions.
    dx: [f32; LANES],
    dy: [f32; LANES],
    dz: [f32; LANES],
    lo: [f32; LANES],
    /// Nearest hit so far, or the end of the ray's stretch while `win` is `WIN_NONE`.
    best: [f32; LANES],
    /// What `best` is: a primitive's index, `WIN_GROUND` or `WIN_NONE`.
    win: [u32; LANES],
}

impl Lanes {
    const IDLE: Self = Self {
        dx: [0.0; LANES],
        dy: [0.0; LANES],
        dz: [0.0; LANES],
        lo: [f32::INFINITY; LANES],
        best: [0.0; LANES],
        win: [WIN_NONE; LANES],
    };

    #[inline(always)]
    fn searching(&self, k: usize) -> bool {
        self.lo[k] < f32::INFINITY
    }

    /// Whether some searching lane's ray meets the box `[lo, hi]` between its `lo` and its best hit
    /// (both ends included: the box bounds the hits with a margin). `inv`: the reciprocal directions
    /// per axis.
    #[inline(always)]
    // Indexed loops over plain arrays are the shape the compiler vectorises.
    #[allow(clippy::needless_range_loop)]
    fn reach(&self, o: [f32; 3], inv: &[[f32; LANES]; 3], lo: [f32; 3], hi: [f32; 3]) -> bool {
        let a = [lo[0] - o[0], lo[1] - o[1], lo[2] - o[2]];
        let b = [hi[0] - o[0], hi[1] - o[1], hi[2] - o[2]];
        let mut any = 0u32;
        for k in 0..LANES {
            let (x0, x1) = (a[0] * inv[0][k], b[0] * inv[0][k]);
            let (y0, y1) = (a[1] * inv[1][k], b[1] * inv[1][k]);
            let (z0, z1) = (a[2] * inv[2][k], b[2] * inv[2][k]);
            let near = max2(max2(min2(x0, x1), min2(y0, y1)), max2(min2(z0, z1), self.lo[k]));
            let far = min2(min2(max2(x0, x1), max2(y0, y1)), min2(max2(z0, z1), self.best[k]));
            any |= (near <= far) as u32;
        }
        any != 0
    }

    /// A stalk or weed clump (primitive `index`) against every searching lane, one at a time. They are
    /// few, and out of line: inlined, its unrolled lanes had the compiler hoist all the lanes' direction
    /// components out of the cell loop and copy them at every strip (~80 instructions a strip, 9 % of
    /// a grown-corn revolution).
    #[inline(never)]
    fn each(&mut self, p: &Prim, o: [f32; 3], index: u32) {
        for k in 0..LANES {
            let d = [self.dx[k], self.dy[k], self.dz[k]];
            if self.searching(k)
                && let Some(t) = p.intersect(o, d, self.lo[k], self.best[k])
            {
                (self.best[k], self.win[k]) = (t, index);
            }
        }
    }

    /// A flat patch (primitive `index`) against every lane, with `Prim::intersect`'s arithmetic
    /// operation for operation.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn patch<const ELLIPSE: bool, const WIDTH: usize>(
        &mut self,
        o: [f32; 3],
        po: [f32; 3],
        n: [f32; 3],
        ua: [f32; 3],
        wa: [f32; 3],
        index: u32,
    ) {
        let num = n[0] * (po[0] - o[0]) + n[1] * (po[1] - o[1]) + n[2] * (po[2] - o[2]);
        // Two passes over plain arrays with the hit as a bit mask: this shape the compiler vectorises
        // (`if`/`&&` per lane, or bool arrays, keep it scalar).
        let (mut t, mut mask) = ([0f32; WIDTH], [0u32; WIDTH]);
        for k in 0..WIDTH {
            let (dx, dy, dz) = (self.dx[k], self.dy[k], self.dz[k]);
            let denom = n[0] * dx + n[1] * dy + n[2] * dz;
            let tk = num / denom;
            let q0 = o[0] + tk * dx - po[0];
            let q1 = o[1] + tk * dy - po[1];
            let q2 = o[2] + tk * dz - po[2];
            let s = q0 * ua[0] + q1 * ua[1] + q2 * ua[2];
            let r = q0 * wa[0] + q1 * wa[1] + q2 * wa[2];
            let inside = if ELLIPSE {
                (s * s + r * r <= 1.0) as u32
            } else {
                (s.abs() <= 1.0) as u32 & (r.abs() <= 1.0) as u32
            };
            let hit = (denom.abs() >= 1e-12) as u32
                & (tk > self.lo[k]) as u32
                & (tk < self.best[k]) as u32
                & inside;
            mask[k] = 0u32.wrapping_sub(hit);
            t[k] = tk;
        }
        for k in 0..WIDTH {
            let m = mask[k];
            self.best[k] = f32::from_bits((t[k].to_bits() & m) | (self.best[k].to_bits() & !m));
            self.win[k] = (index & m) | (self.win[k] & !m);
        }
    }
}

#[inline(always)]
fn min2(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

#[inline(always)]
fn max2(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// How a ray enters a packet.
enum Start {
    /// Its answer is known already.
    Done(Option<(f32, Class)>),
    /// The packet does not handle it.
    Alone,
    /// It searches with the packet from `t_lo`; its stretch ends at `t_hi`, on the ground if `ground`.
    Search { t_lo: f32, t_hi: f32, ground: bool },
}

/// The instruction sets the packet code is compiled for. The code is one source, compiled once per
/// variant; a scene picks the best its CPU has when it is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Isa {
    /// The build target's baseline (SSE2 on x86-64): a lane array is two 4-wide registers.
    Baseline,
    /// x86-64 AVX2: a lane array is one 8-wide register. Without FMA: Rust never contracts `a * b + c`,
    /// so both variants round every operation alike and return the same bits.
    Avx2,
}

impl Isa {
    /// The best variant this CPU runs (the standard library caches the CPUID probe).
    pub(crate) fn detect() -> Self {
        if Self::Avx2.available() { Self::Avx2 } else { Self::Baseline }
    }

    /// Whether this CPU runs the variant.
    pub(crate) fn available(self) -> bool {
        match self {
            Self::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(not(target_arch = "x86_64"))]
            Self::Avx2 => false,
        }
    }
}

impl Scene {
    /// Casts the unit rays `o + t·dirs[k]` (field frame, at most [`LANES`]) and writes each one's first
    /// hit with `t ≤ t_max` to `out[k]`, as [`Scene::cast`] would, with the scene's [`Isa`].
    pub(crate) fn cast_packet(
        &self,
        o: [f32; 3],
        dirs: &[[f32; 3]],
        t_max: f32,
        out: &mut [Option<(f32, Class)>],
    ) {
        match self.isa {
            // The workspace's one `unsafe`: calling code compiled for a CPU feature.
            // SAFETY: `Scene::build` and `Scene::set_isa` store `Isa::Avx2` only where the CPU has AVX2.
            #[cfg(target_arch = "x86_64")]
            #[allow(unsafe_code)]
            Isa::Avx2 => unsafe { self.cast_packet_avx2(o, dirs, t_max, out) },
            _ => self.cast_packet_with(o, dirs, t_max, out),
        }
    }

    /// Picks the packet code's variant; one the CPU lacks falls back to [`Isa::Baseline`].
    #[cfg(test)]
    pub(crate) fn set_isa(&mut self, isa: Isa) {
        self.isa = if isa.available() { isa } else { Isa::Baseline };
    }

    /// The scene's variant of the packet code.
    #[cfg(test)]
    pub(crate) fn isa(&self) -> Isa {
        self.isa
    }

    /// [`Scene::cast_packet`] compiled for AVX2: the same body, whose callees are all inlined into it.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn cast_packet_avx2(&self, o: [f32; 3], dirs: &[[f32; 3]], t_max: f32, out: &mut [Option<(f32, Class)>]) {
        self.cast_packet_with(o, dirs, t_max, out)
    }

    /// The packet code, inlined (with everything it calls but the single-ray caster) into each
    /// variant's wrapper so that it compiles for the wrapper's instruction set.
    #[inline(always)]
    fn cast_packet_with(&self, o: [f32; 3], dirs: &[[f32; 3]], t_max: f32, out: &mut [Option<(f32, Class)>]) {
        // Most packets behind the sensor rise: settle them before setting up any lanes.
        let mut starts = [const { None }; LANES];
        for ((&d, slot), start) in dirs.iter().zip(out.iter_mut()).zip(&mut starts) {
            *slot = None;
            match self.packet_ray(o, d, t_max) {
                Start::Done(hit) => *slot = hit,
                Start::Alone => *slot = self.cast(o, d, t_max),
                search => *start = Some(search),
            }
        }
        if starts.iter().all(Option::is_none) {
            return;
        }
        let mut lanes = Lanes::IDLE;
        for (k, (&d, start)) in dirs.iter().zip(&starts).enumerate() {
            if let Some(Start::Search { t_lo, t_hi, ground, .. }) = *start {
                (lanes.dx[k], lanes.dy[k], lanes.dz[k]) = (d[0], d[1], d[2]);
                (lanes.lo[k], lanes.best[k]) = (t_lo, t_hi);
                lanes.win[k] = if ground { WIN_GROUND } else { WIN_NONE };
            }
        }
        self.trace(o, &mut lanes);
        for (slot, (win, best)) in out.iter_mut().zip(lanes.win.iter().zip(lanes.best)) {
            match *win {
                // An idle lane, or a ray whose stretch ended before the ground: `out` holds its answer.
                WIN_NONE => {}
                WIN_GROUND => *slot = Some((best, Class::Ground)),
                i => *slot = self.prims.get(i as usize).map(|p| (best, p.class)),
            }
        }
    }

    /// Traverses the hierarchy with every searching lane: a node is entered when some lane's ray
    /// meets its box between the lane's `lo` and its best hit so far, near child first.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    fn trace(&self, o: [f32; 3], lanes: &mut Lanes) {
        let (nodes, prims) = (self.bvh.nodes.as_slice(), self.prims.as_slice());
        // Reciprocals for the slab tests; an axis the ray does not move along gets a huge one, so that
        // its slab spans everything or nothing as the origin lies in it or not.
        let recip = |d: f32| if d.abs() < 1e-20 { 1e20 } else { 1.0 / d };
        let mut inv = [[0f32; LANES]; 3];
        for k in 0..LANES {
            inv[0][k] = recip(lanes.dx[k]);
            inv[1][k] = recip(lanes.dy[k]);
            inv[2][k] = recip(lanes.dz[k]);
        }
        // The packet's rays go nearly one way: its first searching ray's signs order the children.
        let Some(k) = (0..LANES).find(|&k| lanes.searching(k)) else { return };
        let back = [lanes.dx[k] < 0.0, lanes.dy[k] < 0.0, lanes.dz[k] < 0.0];
        let mut stack = [0u32; super::bvh::MAX_DEPTH + 1];
        let mut top = usize::from(!nodes.is_empty());
        while top > 0 {
            top -= 1;
            let Some(node) = stack.get(top).and_then(|&n| nodes.get(n as usize)) else { break };
            if !lanes.reach(o, &inv, node.lo, node.hi) {
                continue;
            }
            if node.count > 0 {
                let first = node.first as usize;
                for (i, p) in prims.get(first..first + node.count as usize).unwrap_or(&[]).iter().enumerate()
                {
                    let prim = (first + i) as u32;
                    match p.shape {
                        Shape::Patch { o: po, n, ua, wa, ellipse: true } => {
                            lanes.patch::<true, LANES>(o, po, n, ua, wa, prim)
                        }
                        Shape::Patch { o: po, n, ua, wa, ellipse: false } => {
                            lanes.patch::<false, LANES>(o, po, n, ua, wa, prim)
                        }
                        _ => lanes.each(p, o, prim),
                    }
                }
            } else if let Some(slots) = stack.get_mut(top..top + 2) {
                let near_second = back.get(node.axis as usize) == Some(&true);
                let (near, far) =
                    if near_second { (node.first + 1, node.first) } else { (node.first, node.first + 1) };
                slots.copy_from_slice(&[far, near]);
                top += 2;
            }
        }
    }

    /// How a ray enters a packet.
    #[inline(always)]
    fn packet_ray(&self, o: [f32; 3], d: [f32; 3], t_max: f32) -> Start {
        let horizontal = (d[0] * d[0] + d[1] * d[1]).sqrt();
        // Written so that NaN directions go alone too.
        let descends = d[2] < 0.0 && horizontal >= MIN_HORIZONTAL;
        if !self.relief.is_flat() || !descends {
            // A rising ray from above everything meets nothing; the packet does not handle the rest.
            if d[2] >= 0.0 && o[2] > self.top_z {
                return Start::Done(None);
            }
            return Start::Alone;
        }
        // The stretch through the height slab, clipped as `Scene::cast` clips it (d[2] < 0 here).
        let ta = (self.top_z - o[2]) / d[2];
        let tb = (self.bottom_z - o[2]) / d[2];
        let t_lo = 0f32.max(ta.min(tb));
        let t_hi = t_max.min(ta.max(tb));
        if t_lo >= t_hi || t_lo.is_nan() || t_hi.is_nan() {
            return Start::Done(None);
        }
        // Flat ground: the crossing `Scene::cast` finds, in or out of the grid.
        let t_ground = -o[2] / d[2];
        if t_ground >= t_lo && t_ground <= t_hi {
            Start::Search { t_lo, t_hi: t_ground, ground: true }
        } else {
            Start::Search { t_lo, t_hi, ground: false }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Crop, Field, FieldConfig, Stage};

    /// The rays of one VLP-16 revolution (16 beams, 1800 columns, column-major) from a sensor 1.5 m over
    /// `(x, y)`, heading `yaw`, pitched 30° down, in the field frame.
    fn revolution(yaw: f32) -> Vec<[f32; 3]> {
        let (sp, cp) = 30f32.to_radians().sin_cos();
        let (sy, cy) = yaw.sin_cos();
        let mut dirs = Vec::with_capacity(1800 * 16);
        for c in 0..1800 {
            let az = (180.0 - c as f32 * 0.2).to_radians();
            for b in 0..16 {
                let el = (-15.0 + 2.0 * b as f32).to_radians();
                let s = [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()];
                // Pitch down about y, then yaw about z.
                let p = [cp * s[0] + sp * s[2], s[1], -sp * s[0] + cp * s[2]];
                dirs.push([cy * p[0] - sy * p[1], sy * p[0] + cy * p[1], p[2]]);
            }
        }
        dirs
    }

    /// The packets of whole revolutions from sensors 1.5 m over `(x, y)` heading `yaw`: each laser's
    /// rays of `LANES` consecutive columns, with their origin.
    fn packets(poses: &[(f32, f32, f32)]) -> Vec<([f32; 3], Vec<[f32; 3]>)> {
        let mut packets = Vec::new();
        for &(x, y, yaw) in poses {
            let dirs = revolution(yaw);
            for beam in 0..16 {
                let rays: Vec<[f32; 3]> = dirs.iter().skip(beam).step_by(16).copied().collect();
                packets.extend(rays.chunks(LANES).map(|chunk| ([x, y, 1.5], chunk.to_vec())));
            }
        }
        packets
    }

    /// The scene of a generated field, casting packets with `isa`.
    fn scene_with(field: &Field, isa: Isa) -> Scene {
        let mut s = field.scene().clone();
        s.set_isa(isa);
        s
    }

    /// Every ray of whole revolutions cast in packets (with each variant of the packet code) and alone:
    /// same hits (within 1 mm) and classes.
    fn packets_match_single_rays(config: FieldConfig, poses: &[(f32, f32, f32)], min_crop_hits: usize) {
        let field = Field::generate(&config, 3).unwrap();
        let packets = packets(poses);
        for isa in [Isa::Baseline, Isa::detect()] {
            let s = scene_with(&field, isa);
            let (mut crop, mut mismatches) = (0, Vec::new());
            for (o, chunk) in &packets {
                let mut out = [None; LANES];
                s.cast_packet(*o, chunk, 100.0, &mut out[..chunk.len()]);
                for (d, packet) in chunk.iter().zip(out) {
                    let alone = s.cast(*o, *d, 100.0);
                    let same = match (packet, alone) {
                        (None, None) => true,
                        (Some((tp, cp)), Some((ta, ca))) => (tp - ta).abs() < 1e-3 && cp == ca,
                        _ => false,
                    };
                    crop += usize::from(matches!(alone, Some((_, Class::Crop))));
                    if !same {
                        mismatches.push((*o, *d, packet, alone));
                    }
                }
            }
            assert!(
                mismatches.is_empty(),
                "{isa:?}: {} mismatches, first {:?}",
                mismatches.len(),
                mismatches.first()
            );
            // The rays must exercise the plants, not only the ground.
            assert!(crop > min_crop_hits, "{isa:?}: {crop} crop hits");
        }
    }

    /// 8 rows of grown corn, 12 m long, with weeds.
    fn grown_corn() -> FieldConfig {
        FieldConfig {
            crop: Crop::Corn,
            stage: Stage::Grown,
            rows: 8,
            length_m: 12.0,
            weeds_per_m2: 2.0,
            ..FieldConfig::default()
        }
    }

    #[test]
    fn packets_match_single_rays_over_grown_corn() {
        packets_match_single_rays(
            grown_corn(),
            &[(4.0, 2.625, 0.0), (6.0, 2.3, 0.3), (11.5, 0.0, -2.5)],
            10_000,
        );
    }

    #[test]
    fn packets_match_single_rays_over_young_soybean() {
        let config = FieldConfig {
            crop: Crop::Soybean,
            stage: Stage::Young,
            rows: 8,
            length_m: 12.0,
            weeds_per_m2: 2.0,
            ..FieldConfig::default()
        };
        packets_match_single_rays(config, &[(4.0, 2.625, 0.0), (-1.0, 3.0, 0.8)], 2_000);
    }

    #[test]
    fn packets_over_relief_fall_back_to_single_rays() {
        let config = FieldConfig {
            crop: Crop::Corn,
            stage: Stage::Young,
            rows: 4,
            length_m: 6.0,
            relief_m: 0.15,
            relief_wavelength_m: 5.0,
            ..FieldConfig::default()
        };
        packets_match_single_rays(config, &[(3.0, 1.125, 0.2)], 500);
    }

    #[test]
    fn a_variant_the_cpu_lacks_falls_back_to_the_baseline() {
        let field =
            Field::generate(&FieldConfig { rows: 2, length_m: 2.0, ..FieldConfig::default() }, 1).unwrap();
        assert_eq!(scene_with(&field, Isa::Baseline).isa(), Isa::Baseline);
        let avx2 = scene_with(&field, Isa::Avx2).isa();
        assert_eq!(avx2, if Isa::Avx2.available() { Isa::Avx2 } else { Isa::Baseline });
        // A freshly built scene takes the best variant there is.
        assert_eq!(field.scene().isa(), Isa::detect());
    }

    #[test]
    fn every_variant_returns_the_same_bits() {
        // Grown corn with weeds from inside, across and outside the field: every ray of each pose's
        // revolution, compared bit for bit (distance and class) between the variants.
        let field = Field::generate(&grown_corn(), 4).unwrap();
        let (baseline, best) = (scene_with(&field, Isa::Baseline), field.scene());
        let mut hits = 0;
        for (o, chunk) in packets(&[(4.0, 2.625, 0.0), (6.0, 2.3, 0.3), (11.5, 0.0, -2.5), (-1.0, 3.0, 0.8)])
        {
            let (mut a, mut b) = ([None; LANES], [None; LANES]);
            baseline.cast_packet(o, &chunk, 100.0, &mut a[..chunk.len()]);
            best.cast_packet(o, &chunk, 100.0, &mut b[..chunk.len()]);
            let bits = |h: Option<(f32, Class)>| h.map(|(t, c)| (t.to_bits(), c));
            assert_eq!(a.map(bits), b.map(bits), "{:?} vs {:?} from {o:?}", baseline.isa(), best.isa());
            hits += a.iter().flatten().count();
        }
        assert!(hits > 40_000, "{hits} hits");
    }
}
