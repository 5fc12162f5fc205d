//! A bounding volume hierarchy over the scene's primitives, for the beam packets (`packet`): a binary
//! tree of axis-aligned boxes built with the binned surface area heuristic, stored as a flat array
//! (the two children of a node side by side), its leaves spans of at most `LEAF_MAX` primitives of
//! the scene's primitive array, which the build reorders to match (so that a leaf's primitives lie
//! together in memory).
//!
//! Boxes are the primitives' bounds widened by `MARGIN_M`, so that a slab test rounded in f32 never
//! rejects a box holding a hit that the exact primitive test finds (a horizontal leaf's box has no
//! height of its own).

use super::Prim;

/// Primitives per leaf at most. A packet of 16 rays pays less for a primitive test than for a node (a
/// likely mispredicted branch and a cache line), so leaves hold more than the 2-4 taken for 8 rays.
const LEAF_MAX: usize = 8;
/// Leaves with this many primitives or fewer are not split further.
const LEAF_MIN: usize = 4;
/// Bins of the surface area heuristic, per axis.
const BINS: usize = 12;
/// Every box is its primitives' bounds widened by this, m (f32 rounding of the slab tests: a ray of
/// 100 m rounds by ~10 µm).
const MARGIN_M: f32 = 1e-3;
/// Depth of the deepest node at most: the traversal's stack holds one entry per level. Below
/// `BALANCED_BELOW` the spans are split at their median, which ends any span of the largest fields
/// (2^22 primitives) within 20 more levels.
pub(super) const MAX_DEPTH: usize = 64;
const BALANCED_BELOW: usize = 40;
/// Spans of more primitives than this are halved in space (at the middle of their centroids' widest
/// extent) instead of by the surface area heuristic: one pass instead of four over a span, where a
/// field's primitives spread evenly, so that both pick nearly the same plane.
const SAH_MAX: usize = 8192;
/// Cost of visiting a node, relative to testing one primitive (surface area heuristic).
const TRAVERSAL_COST: f32 = 2.0;

/// A node: a box and either two children or a span of primitives.
#[derive(Debug, Clone, Copy)]
pub(super) struct Node {
    /// Box corners `[x, y, z]`, field frame, m.
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    /// A leaf's first primitive, or an inner node's first child (the second follows it).
    pub first: u32,
    /// A leaf's primitive count (≥ 1), or 0 for an inner node.
    pub count: u16,
    /// The axis an inner node's children were split along (0: x, 1: y, 2: z): a ray going the
    /// positive way along it visits the first child first.
    pub axis: u16,
}

/// The hierarchy: `nodes[0]` is the root (absent for a scene without primitives).
#[derive(Debug, Clone, Default)]
pub(super) struct Bvh {
    pub nodes: Vec<Node>,
}

/// Bounds and centroid of a primitive, for the build.
#[derive(Debug, Clone, Copy)]
struct Item {
    lo: [f32; 3],
    hi: [f32; 3],
    centre: [f32; 3],
    prim: u32,
}

/// Running bounds.
#[derive(Debug, Clone, Copy)]
struct Aabb {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl Aabb {
    const EMPTY: Self = Self { lo: [f32::INFINITY; 3], hi: [f32::NEG_INFINITY; 3] };

    /// Plain comparisons, not `f32::min`: they compile to one instruction each (the build spends
    /// most of its time here) and a NaN bound is simply not taken.
    #[inline]
    fn grow(&mut self, lo: [f32; 3], hi: [f32; 3]) {
        for k in 0..3 {
            self.lo[k] = if lo[k] < self.lo[k] { lo[k] } else { self.lo[k] };
            self.hi[k] = if hi[k] > self.hi[k] { hi[k] } else { self.hi[k] };
        }
    }

    /// Half the surface area (the heuristic needs only ratios); 0 for an empty box.
    fn half_area(&self) -> f32 {
        let e = [0, 1, 2].map(|k| (self.hi[k] - self.lo[k]).max(0.0));
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }
}

impl Bvh {
    /// Builds the hierarchy over `prims` and returns it with the primitives reordered to its leaves.
    pub fn build(prims: Vec<Prim>) -> (Self, Vec<Prim>) {
        let mut items: Vec<Item> = prims
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let b = p.bounds();
                let lo = [b[0] - MARGIN_M, b[1] - MARGIN_M, b[2] - MARGIN_M];
                let hi = [b[3] + MARGIN_M, b[4] + MARGIN_M, b[5] + MARGIN_M];
                let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
                Item { lo, hi, centre, prim: k as u32 }
            })
            .collect();
        if items.is_empty() {
            return (Self::default(), prims);
        }
        let mut nodes = Vec::with_capacity(2 * items.len() / LEAF_MIN + 1);
        nodes.push(Node { lo: [0.0; 3], hi: [0.0; 3], first: 0, count: 0, axis: 0 });
        // (node, first item, end, depth): the nodes whose span is not yet split or made a leaf.
        let mut todo = vec![(0usize, 0usize, items.len(), 0usize)];
        while let Some((node, start, end, depth)) = todo.pop() {
            let span = items.get_mut(start..end).unwrap_or(&mut []);
            let (bounds, centres) = span.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(mut b, mut c), it| {
                b.grow(it.lo, it.hi);
                c.grow(it.centre, it.centre);
                (b, c)
            });
            let split = if span.len() <= LEAF_MIN || depth >= BALANCED_BELOW {
                None
            } else if span.len() > SAH_MAX {
                middle(&centres)
            } else {
                best_split(span, &bounds, &centres)
            };
            let mid = match split {
                Some((axis, bin)) => Some((axis, start + partition(span, axis, bin, &centres))),
                // No worthwhile split: a leaf if it is small enough, else halves at the median.
                None if span.len() <= LEAF_MAX => None,
                None => {
                    let (axis, half) = (widest(&centres), span.len() / 2);
                    span.select_nth_unstable_by(half, |p, q| p.centre[axis].total_cmp(&q.centre[axis]));
                    Some((axis, start + half))
                }
            };
            let first = nodes.len();
            let Some(n) = nodes.get_mut(node) else { continue };
            (n.lo, n.hi) = (bounds.lo, bounds.hi);
            match mid {
                Some((axis, mid)) => {
                    (n.first, n.count, n.axis) = (first as u32, 0, axis as u16);
                    nodes.push(Node { lo: [0.0; 3], hi: [0.0; 3], first: 0, count: 0, axis: 0 });
                    nodes.push(Node { lo: [0.0; 3], hi: [0.0; 3], first: 0, count: 0, axis: 0 });
                    todo.push((first + 1, mid, end, depth + 1));
                    todo.push((first, start, mid, depth + 1));
                }
                None => (n.first, n.count) = (start as u32, span.len() as u16),
            }
        }
        // The primitives in leaf order.
        let mut slots: Vec<Option<Prim>> = prims.into_iter().map(Some).collect();
        let ordered =
            items.iter().filter_map(|it| slots.get_mut(it.prim as usize).and_then(Option::take)).collect();
        (Self { nodes }, ordered)
    }
}

/// The bin of a centroid coordinate `c` along a span `[lo, lo + BINS / scale)`.
fn bin_of(c: f32, lo: f32, scale: f32) -> usize {
    // `as` saturates (and maps NaN to 0); the clamp keeps the top edge in the last bin.
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// The axis along which the centroids spread widest.
fn widest(centres: &Aabb) -> usize {
    let e = [0, 1, 2].map(|k| centres.hi[k] - centres.lo[k]);
    if e[0] >= e[1] && e[0] >= e[2] {
        0
    } else if e[1] >= e[2] {
        1
    } else {
        2
    }
}

/// The split at the middle of the centroids' widest extent, as an axis and a bin for `partition`;
/// `None` when every centroid coincides.
fn middle(centres: &Aabb) -> Option<(usize, usize)> {
    let axis = widest(centres);
    (centres.hi[axis] - centres.lo[axis] > 0.0).then_some((axis, BINS / 2))
}

/// The binned surface-area split of `span` (bounds `bounds`, centroid bounds `centres`): the axis and
/// the first bin of the second half, or `None` when not splitting costs less.
fn best_split(span: &[Item], bounds: &Aabb, centres: &Aabb) -> Option<(usize, usize)> {
    let leaf_cost = span.len() as f32;
    let parent_area = bounds.half_area();
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        let extent = centres.hi[axis] - centres.lo[axis];
        // Coincident centroids (or NaN bounds): nothing to bin along this axis.
        if extent.is_nan() || extent <= 0.0 {
            continue;
        }
        let scale = BINS as f32 / extent;
        let mut boxes = [Aabb::EMPTY; BINS];
        let mut counts = [0usize; BINS];
        for it in span {
            let b = bin_of(it.centre[axis], centres.lo[axis], scale);
            if let (Some(bx), Some(n)) = (boxes.get_mut(b), counts.get_mut(b)) {
                bx.grow(it.lo, it.hi);
                *n += 1;
            }
        }
        // Areas and counts of the bins right of each boundary, then a sweep from the left.
        let mut right = [(0f32, 0usize); BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc.grow(boxes[b].lo, boxes[b].hi);
            n += counts[b];
            right[b] = (acc.half_area(), n);
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in 1..BINS {
            acc.grow(boxes[b - 1].lo, boxes[b - 1].hi);
            n += counts[b - 1];
            let (ra, rn) = right[b];
            if n == 0 || rn == 0 {
                continue;
            }
            let cost =
                TRAVERSAL_COST + (acc.half_area() * n as f32 + ra * rn as f32) / parent_area.max(1e-12);
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }
    match best {
        Some((cost, axis, bin)) if cost < leaf_cost || span.len() > LEAF_MAX => Some((axis, bin)),
        _ => None,
    }
}

/// Moves the items whose centroid falls in a bin before `bin` along `axis` to the front; returns how
/// many there are (both halves are non-empty: `best_split` only picks such bins, and the middle bin
/// of a positive extent has the centroids of its two ends on either side).
fn partition(span: &mut [Item], axis: usize, bin: usize, centres: &Aabb) -> usize {
    let scale = BINS as f32 / (centres.hi[axis] - centres.lo[axis]);
    let mut front = 0;
    for k in 0..span.len() {
        if bin_of(span[k].centre[axis], centres.lo[axis], scale) < bin {
            span.swap(front, k);
            front += 1;
        }
    }
    front
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Class;
    use rand::{RngExt, SeedableRng};

    fn leaves(bvh: &Bvh) -> impl Iterator<Item = &Node> {
        bvh.nodes.iter().filter(|n| n.count > 0)
    }

    #[test]
    fn every_primitive_lies_in_one_leaf_inside_every_box_above_it() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let prims: Vec<Prim> = (0..2000)
            .map(|_| {
                let c =
                    [rng.random_range(0.0..20.0), rng.random_range(-3.0..3.0), rng.random_range(0.0..1.0)];
                Prim::spheroid(c, rng.random_range(0.01..0.2), 0.05, Class::Weed)
            })
            .collect();
        let (bvh, ordered) = Bvh::build(prims);
        assert_eq!(ordered.len(), 2000);
        // Leaves partition the reordered array, hold at most LEAF_MAX primitives and bound them.
        let mut covered = vec![0; ordered.len()];
        for leaf in leaves(&bvh) {
            assert!((leaf.count as usize) <= LEAF_MAX);
            for k in leaf.first as usize..(leaf.first + leaf.count as u32) as usize {
                covered[k] += 1;
                let b = ordered[k].bounds();
                for a in 0..3 {
                    assert!(leaf.lo[a] <= b[a] && leaf.hi[a] >= b[a + 3], "primitive {k} outside its leaf");
                }
            }
        }
        assert!(covered.iter().all(|&c| c == 1));
        // Every inner node's box holds its children's.
        for n in bvh.nodes.iter().filter(|n| n.count == 0) {
            for child in &bvh.nodes[n.first as usize..n.first as usize + 2] {
                for a in 0..3 {
                    assert!(n.lo[a] <= child.lo[a] && n.hi[a] >= child.hi[a]);
                }
            }
        }
    }

    #[test]
    fn coincident_primitives_still_make_small_leaves() {
        // 100 copies of one stalk: no split separates them, so the halves are taken in order.
        let prims = vec![Prim::cylinder(1.0, 1.0, 0.01, 0.0, 1.0, Class::Crop); 100];
        let (bvh, ordered) = Bvh::build(prims);
        assert_eq!(ordered.len(), 100);
        assert!(leaves(&bvh).all(|l| (l.count as usize) <= LEAF_MAX));
        assert_eq!(leaves(&bvh).map(|l| l.count as usize).sum::<usize>(), 100);
    }

    #[test]
    fn no_primitives_no_nodes() {
        let (bvh, ordered) = Bvh::build(Vec::new());
        assert!(bvh.nodes.is_empty() && ordered.is_empty());
    }
}
