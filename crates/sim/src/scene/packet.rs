//! Beam packets: a few rays that share an origin and nearly a direction (one VLP-16 laser fired at
//! consecutive azimuths) cast together through the scene's grid, so that they share the cell walk, the
//! scan of each cell's primitive list and each primitive's load, and the flat-patch test runs on all
//! rays at once (lanes the compiler vectorises).
//!
//! Seen from above, the rays of a packet fan out in a thin wedge from the sensor. The walk cuts the grid
//! into strips one cell wide across the wedge's main axis (x or y, whichever the wedge runs closer to)
//! and visits them outwards; in each strip it visits the cells between the wedge's two boundary rays.
//! Every primitive listed in a visited cell at the packet's height and reaching into the wedge's width
//! there is tested against every ray still searching, with the same arithmetic as [`Scene::cast`], once
//! per packet (a small table remembers the primitives tested: a leaf lies in several cells of the
//! walk, and testing it again could not find a nearer hit). A ray
//! stops once its best hit lies before the next strip: a hit it has not found lies in a cell not yet
//! visited, hence farther along the axis. So a packet returns what [`Scene::cast`] returns for each ray,
//! bit for bit where the nearest hit is unique (the tests compare whole revolutions ray by ray). As rays
//! stop, the wedge narrows to the rays still searching, and in the baseline build, once they fit in
//! half the lanes, the tests run on that half only (4 lanes are one SSE register).
//!
//! The code is one source compiled twice ([`Isa`]): for the target's baseline (SSE2 on x86-64, where
//! the 8 lanes take two registers) and for AVX2 (one register), picked at run time when the scene is
//! built. Neither uses FMA, so both return the same bits (a test compares them ray by ray).
//!
//! Rays the wedge does not suit go to [`Scene::cast`]: rays that rise or are near vertical, relief (the
//! packet takes the flat ground analytically), and packets fanning wider than ~25°; rays still searching
//! `REACH_M` out along the axis (grazing side beams, whose wedge grows wide far out) continue alone from
//! there.
//!
//! Cost (AVX2, grown corn): 16.1M instructions a revolution, 13.3M of them here, at about two a
//! cycle. The stalls split between cache misses (77k D1 a revolution: cell references, primitives,
//! footprints) and mispredicted branches (136k: whether a reference passes its height, footprint and
//! table tests goes either way at random); storing the data in grid order, smaller references,
//! prefetching and branch-free sifting each traded one for the other or for instructions, at the same
//! CPU time. The measurements and what was tried are written down in `benches/lidar.rs`.

use super::{Class, Prim, Scene, Shape};

/// Rays per packet at most (the lanes of the per-primitive tests).
pub(crate) const LANES: usize = 8;

/// Rays still searching this far from the sensor along the walk's axis continue alone, m.
const REACH_M: f32 = 6.0;
/// Slack of the strips' cell ranges and of the stopping rule, m: covers f32 rounding.
const SLACK_M: f32 = 1e-3;
/// Cosine of the widest angle a packet's ray may make with the packet's mean direction (25°).
const MIN_COS: f32 = 0.906;
/// Rays whose horizontal component is below this (steeper than ~87°) are cast alone.
const MIN_HORIZONTAL: f32 = 0.05;

/// Entries of a packet's table of tested primitives.
const SEEN: usize = 64;

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
    /// |component of the direction along the walk's axis|: the ray advances `t · along` along it.
    along: [f32; LANES],
    /// Per metre along the axis: the ray's sideways drift (signed, along the other axis) and its
    /// descent (negative).
    drift: [f32; LANES],
    descent: [f32; LANES],
    /// The nearest distance along the axis of a searching lane's `best`: before it no lane stops.
    /// Recomputed when read after hits (`stale`), not at each hit: a strip takes several.
    settled: f32,
    stale: bool,
    /// The ray (index into the packet) in each lane: lanes are compacted as rays stop.
    ray: [usize; LANES],
    /// Lanes the primitive tests cover: all, or (baseline build) the first half once every searching
    /// ray is there.
    width: usize,
    /// The primitives tested last, direct-mapped by index: a primitive listed in several cells of the
    /// walk is tested once (testing it again could not find a nearer hit).
    seen: [u32; SEEN],
}

impl Lanes {
    const IDLE: Self = Self {
        dx: [0.0; LANES],
        dy: [0.0; LANES],
        dz: [0.0; LANES],
        lo: [f32::INFINITY; LANES],
        best: [0.0; LANES],
        win: [WIN_NONE; LANES],
        along: [0.0; LANES],
        drift: [0.0; LANES],
        descent: [0.0; LANES],
        settled: f32::INFINITY,
        stale: false,
        ray: {
            let mut ray = [0; LANES];
            let mut k = 0;
            while k < LANES {
                ray[k] = k;
                k += 1;
            }
            ray
        },
        width: LANES,
        seen: [u32::MAX; SEEN],
    };

    #[inline(always)]
    fn searching(&self, k: usize) -> bool {
        self.lo[k] < f32::INFINITY
    }

    /// Recomputes `settled`.
    #[inline(always)]
    fn settle(&mut self) {
        let a = std::array::from_fn(|k| {
            if self.lo[k] < f32::INFINITY { self.best[k] * self.along[k] } else { f32::INFINITY }
        });
        self.settled = min_of(a);
        self.stale = false;
    }

    /// Stops the rays whose best hit (or end) lies before `dist` along the axis: no strip from there on
    /// can hold a nearer hit. Whether any stopped. With `HALVE`, moves the rays left to the first half
    /// of the lanes once they fit there.
    #[inline(always)]
    fn retire<const HALVE: bool>(&mut self, dist: f32) -> bool {
        if self.stale {
            self.settle();
        }
        if dist - SLACK_M <= self.settled {
            return false;
        }
        let limit = dist - SLACK_M;
        for k in 0..LANES {
            self.lo[k] = if self.best[k] * self.along[k] < limit { f32::INFINITY } else { self.lo[k] };
        }
        self.settle();
        if HALVE && self.width == LANES && (0..LANES).filter(|&k| self.searching(k)).count() <= LANES / 2 {
            self.compact();
        }
        true
    }

    /// Moves the searching rays to the first half of the lanes, which the tests then cover alone
    /// (half the vector work). Stopped rays keep their answers in the other lanes.
    #[inline(always)]
    fn compact(&mut self) {
        let mut front = 0;
        for k in 0..LANES {
            if self.searching(k) {
                self.swap(front, k);
                front += 1;
            }
        }
        self.width = LANES / 2;
    }

    #[inline(always)]
    fn swap(&mut self, i: usize, j: usize) {
        self.dx.swap(i, j);
        self.dy.swap(i, j);
        self.dz.swap(i, j);
        self.lo.swap(i, j);
        self.best.swap(i, j);
        self.win.swap(i, j);
        self.along.swap(i, j);
        self.drift.swap(i, j);
        self.descent.swap(i, j);
        self.ray.swap(i, j);
    }

    /// The searching rays' extreme drifts and descents: `(left, right, steep, flat)`; `None` when no
    /// ray searches.
    #[inline(always)]
    fn spread(&self) -> Option<(f32, f32, f32, f32)> {
        // Stopped lanes take neutral values, so that the loop has no branch and vectorises.
        let (mut l, mut r, mut st, mut fl) =
            ([f32::INFINITY; LANES], [f32::NEG_INFINITY; LANES], [0f32; LANES], [0f32; LANES]);
        for k in 0..LANES {
            let on = self.lo[k] < f32::INFINITY;
            l[k] = if on { self.drift[k] } else { f32::INFINITY };
            r[k] = if on { self.drift[k] } else { f32::NEG_INFINITY };
            st[k] = if on { self.descent[k] } else { f32::INFINITY };
            fl[k] = if on { self.descent[k] } else { f32::NEG_INFINITY };
        }
        let b = (min_of(l), max_of(r), min_of(st), max_of(fl));
        (b.0 <= b.1).then_some(b)
    }

    /// A stalk or weed clump (primitive `index`) against every searching lane, one at a time. They are
    /// few, and out of line: inlined, its unrolled lanes had the compiler hoist all 24 direction
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
                self.stale = true;
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
        let mut any = 0;
        for k in 0..WIDTH {
            let m = mask[k];
            self.best[k] = f32::from_bits((t[k].to_bits() & m) | (self.best[k].to_bits() & !m));
            self.win[k] = (index & m) | (self.win[k] & !m);
            any |= m;
        }
        self.stale |= any != 0;
    }
}

/// The least of the lanes (none is NaN). Halving, not a running minimum: each step is one packed
/// minimum, where a running minimum stays a chain of scalar compares (the compiler may not reorder
/// it). The minimum of a set is one value whatever the order, so the result is the same bits, but
/// for the sign of a zero, which only ever meets comparisons and sums with a non-zero term.
#[inline(always)]
fn min_of(mut a: [f32; LANES]) -> f32 {
    let mut half = LANES / 2;
    while half > 0 {
        for k in 0..half {
            a[k] = if a[k + half] < a[k] { a[k + half] } else { a[k] };
        }
        half /= 2;
    }
    a[0]
}

/// The greatest of the lanes (none is NaN), as [`min_of`].
#[inline(always)]
fn max_of(mut a: [f32; LANES]) -> f32 {
    let mut half = LANES / 2;
    while half > 0 {
        for k in 0..half {
            a[k] = if a[k + half] > a[k] { a[k + half] } else { a[k] };
        }
        half /= 2;
    }
    a[0]
}

/// How a ray enters a packet.
enum Start {
    /// Its answer is known already.
    Done(Option<(f32, Class)>),
    /// The packet does not handle it.
    Alone,
    /// It searches with the packet from `t_lo`; its stretch ends at `t_hi`, on the ground if `ground`.
    Search { t_lo: f32, t_hi: f32, ground: bool, horizontal: f32 },
}

/// How far a walk went.
enum Searched {
    /// Every ray's answer is final.
    All,
    /// The rays still searching may hit nothing nearer than this distance along the walk's axis.
    UpTo(f32),
}

/// The geometry of a packet's walk, seen from above.
#[derive(Debug, Clone, Copy)]
struct Walk {
    /// The axis the strips cut across (0: x, 1: y) and the other one.
    a: usize,
    b: usize,
    /// +1 or -1: the direction the rays go along `a`.
    sign: f32,
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
            _ => self.cast_packet_with::<true>(o, dirs, t_max, out),
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
    /// The 8 lanes fill one register, so running the tests on half of them would save nothing: the
    /// lanes are never compacted (-2.5 % instructions).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn cast_packet_avx2(&self, o: [f32; 3], dirs: &[[f32; 3]], t_max: f32, out: &mut [Option<(f32, Class)>]) {
        self.cast_packet_with::<false>(o, dirs, t_max, out)
    }

    /// The packet code, inlined (with everything it calls but the single-ray caster) into each
    /// variant's wrapper so that it compiles for the wrapper's instruction set; `HALVE`: see
    /// `Lanes::retire`.
    #[inline(always)]
    fn cast_packet_with<const HALVE: bool>(
        &self,
        o: [f32; 3],
        dirs: &[[f32; 3]],
        t_max: f32,
        out: &mut [Option<(f32, Class)>],
    ) {
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
        let mut units = [[0f32; 2]; LANES];
        let mut mean = [0f32; 2];
        for (k, (&d, start)) in dirs.iter().zip(&starts).enumerate() {
            match *start {
                None | Some(Start::Done(_) | Start::Alone) => {}
                Some(Start::Search { t_lo, t_hi, ground, horizontal }) => {
                    let u = [d[0] / horizontal, d[1] / horizontal];
                    mean = [mean[0] + u[0], mean[1] + u[1]];
                    units[k] = u;
                    (lanes.dx[k], lanes.dy[k], lanes.dz[k]) = (d[0], d[1], d[2]);
                    (lanes.lo[k], lanes.best[k]) = (t_lo, t_hi);
                    lanes.win[k] = if ground { WIN_GROUND } else { WIN_NONE };
                }
            }
        }
        let norm = (mean[0] * mean[0] + mean[1] * mean[1]).sqrt();
        if norm == 0.0 {
            return;
        }
        let walk = self.plan(&mut lanes, &units, [mean[0] / norm, mean[1] / norm]);
        // Everything the walk has not settled lies at least this far along its axis.
        let searched = match walk {
            Some(w) => self.walk::<HALVE>(o, &w, &mut lanes),
            None => Searched::UpTo(0.0),
        };
        for k in 0..LANES {
            let (Some(slot), Some(&d)) = (out.get_mut(lanes.ray[k]), dirs.get(lanes.ray[k])) else {
                continue;
            };
            if lanes.searching(k)
                && let Searched::UpTo(dist) = searched
            {
                // Nothing nearer is left to find: the ray goes on alone from there.
                let t_from =
                    if lanes.along[k] > 0.0 { ((dist - SLACK_M) / lanes.along[k]).max(0.0) } else { 0.0 };
                *slot = self.cast_from(o, d, t_from, t_max);
            } else {
                match lanes.win[k] {
                    // An idle lane, or a ray whose stretch ended before the ground: `out` holds its answer.
                    WIN_NONE => {}
                    WIN_GROUND => *slot = Some((lanes.best[k], Class::Ground)),
                    i => *slot = self.prims.get(i as usize).map(|p| (lanes.best[k], p.class)),
                }
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
            Start::Search { t_lo, t_hi: t_ground, ground: true, horizontal }
        } else {
            Start::Search { t_lo, t_hi, ground: false, horizontal }
        }
    }

    /// The walk's axis and wedge for the searching lanes (unit horizontal directions `units`, mean
    /// direction `centre`); `None` when the packet fans wider than `MIN_COS`.
    #[inline(always)]
    fn plan(&self, lanes: &mut Lanes, units: &[[f32; 2]; LANES], centre: [f32; 2]) -> Option<Walk> {
        let (a, b) = if centre[0].abs() >= centre[1].abs() { (0, 1) } else { (1, 0) };
        let sign = if centre[a] >= 0.0 { 1f32 } else { -1.0 };
        for (k, u) in units.iter().enumerate() {
            if !lanes.searching(k) {
                continue;
            }
            if centre[0] * u[0] + centre[1] * u[1] < MIN_COS {
                return None;
            }
            // Within 25° of a direction within 45° of the axis: |u[a]| > sin 20°.
            lanes.drift[k] = sign * u[b] / u[a];
            lanes.along[k] = [lanes.dx[k], lanes.dy[k]][a].abs();
            lanes.descent[k] = lanes.dz[k] / lanes.along[k];
        }
        lanes.settle();
        Some(Walk { a, b, sign })
    }

    /// Visits the strips outwards and, in each, the wedge's cells, until no ray searches or the packet's
    /// reach is passed.
    #[inline(always)]
    fn walk<const HALVE: bool>(&self, o: [f32; 3], w: &Walk, lanes: &mut Lanes) -> Searched {
        let (a, b) = (w.a, w.b);
        let cell = self.cell_m;
        let (origin, n) = ([self.x0, self.y0], [self.nx, self.ny]);
        // Cell index of a coordinate, clamped to [-1, n]: `as` truncates towards zero, hence the shift.
        let index =
            |v: f32, k: usize| (((v - origin[k]) * self.inv_cell + 1.0).max(0.0) as i32 - 1).min(n[k]);
        // Nothing lies above top_z: start at the strip where the first ray dips under it.
        let start = (0..LANES)
            .filter(|&k| lanes.searching(k))
            .map(|k| lanes.lo[k] * lanes.along[k])
            .fold(f32::INFINITY, f32::min);
        let mut s = index(o[a] + w.sign * start, a);
        let step = if w.sign > 0.0 { 1 } else { -1 };
        // The searching rays' extreme drifts and descents: the wedge narrows as rays stop.
        let Some(mut spread) = lanes.spread() else { return Searched::All };
        while (0..n[a]).contains(&s) {
            let e0 = origin[a] + s as f32 * cell;
            let (near, far) = if w.sign > 0.0 { (e0, e0 + cell) } else { (e0 + cell, e0) };
            let (d_near, d_far) = ((w.sign * (near - o[a])).max(0.0), (w.sign * (far - o[a])).max(0.0));
            if lanes.retire::<HALVE>(d_near) {
                match lanes.spread() {
                    Some(narrower) => spread = narrower,
                    None => return Searched::All,
                }
            }
            if d_near >= REACH_M {
                return Searched::UpTo(d_near);
            }
            // Across the strip the wedge lies between its boundary rays at the strip's edges.
            let (left, right, steep, flat) = spread;
            // `left ≤ right` and both distances are ≥ 0: the leftmost end is on the left ray, the
            // rightmost on the right one (rounding is monotonic).
            let (l0, l1, r0, r1) = (d_near * left, d_far * left, d_near * right, d_far * right);
            let (lo, hi) = (if l1 < l0 { l1 } else { l0 }, if r1 > r0 { r1 } else { r0 });
            let t0 = index(o[b] + lo - SLACK_M, b).max(0);
            let t1 = index(o[b] + hi + SLACK_M, b).min(n[b] - 1);
            // The rays descend: across the strip they lie between their heights at its edges.
            let z = (o[2] + steep * d_far, o[2] + flat * d_near);
            // A primitive can meet a ray in this strip only if it reaches into the wedge's width here.
            let across = (b, o[b] + lo - SLACK_M, o[b] + hi + SLACK_M);
            // Cells across the strip: a column of the grid (x strips) or a run of a row (y strips).
            let (first, stride) = if a == 0 { (t0 * self.nx + s, self.nx) } else { (s * self.nx + t0, 1) };
            let mut c = first;
            for _ in t0..=t1 {
                self.visit(o, lanes, c as usize, z, across);
                c += stride;
            }
            s += step;
        }
        Searched::All
    }

    /// Tests the primitives of cell `c` that reach into the rays' height range `(z_low, z_high)` over
    /// it and into their range `(lo, hi)` along axis `b` against every searching ray, each primitive
    /// once per packet.
    #[inline(always)]
    fn visit(
        &self,
        o: [f32; 3],
        lanes: &mut Lanes,
        c: usize,
        (z_low, z_high): (f32, f32),
        (b, lo, hi): (usize, f32, f32),
    ) {
        match self.heights.get(c) {
            Some(&h) if z_low <= h => {}
            _ => return,
        }
        let Some(info) = self.cells.get(c) else { return };
        let (refs, prims) = (self.refs.as_slice(), self.prims.as_slice());
        let footprints = if b == 0 { self.footprints[0].as_slice() } else { self.footprints[1].as_slice() };
        for r in refs.get(info.start as usize..info.end as usize).unwrap_or(&[]) {
            if r.z_max < z_low {
                break;
            }
            if r.z_min > z_high {
                continue;
            }
            match footprints.get(r.prim as usize) {
                Some(f) if f[0] <= hi && f[1] >= lo => {}
                _ => continue,
            }
            let slot = (r.prim as usize) % SEEN;
            if lanes.seen.get(slot) == Some(&r.prim) {
                continue;
            }
            if let Some(s) = lanes.seen.get_mut(slot) {
                *s = r.prim;
            }
            let Some(p) = prims.get(r.prim as usize) else { continue };
            match p.shape {
                Shape::Patch { o: po, n, ua, wa, ellipse: true } => {
                    if lanes.width == LANES {
                        lanes.patch::<true, LANES>(o, po, n, ua, wa, r.prim)
                    } else {
                        lanes.patch::<true, { LANES / 2 }>(o, po, n, ua, wa, r.prim)
                    }
                }
                Shape::Patch { o: po, n, ua, wa, ellipse: false } => {
                    if lanes.width == LANES {
                        lanes.patch::<false, LANES>(o, po, n, ua, wa, r.prim)
                    } else {
                        lanes.patch::<false, { LANES / 2 }>(o, po, n, ua, wa, r.prim)
                    }
                }
                _ => lanes.each(p, o, r.prim),
            }
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
    /// rays of 8 consecutive columns, with their origin.
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
