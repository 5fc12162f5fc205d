//! The counting loops of the perception pass (voxel counts, height histogram, visible returns per
//! bin) visit their points in four interleaved streams: the points of a ring come one after the other,
//! and neighbours usually raise the same counter, so in scan order each increment waits for the last
//! one's store. Visited a quarter of the scan apart, four increments are in flight at once. The
//! counters are integers, so the order of the visits changes no count.
//!
//! ```text
//! for_each_interleaved([p0 p1 p2 p3 p4 p5 p6 p7 p8], f):  f(p0) f(p2) f(p4) f(p6)  f(p1) f(p3) f(p5) f(p7)  f(p8)
//! ```

/// Calls `f` once on every item: the `i`-th of each quarter of `items` together, quarter by quarter,
/// then the one to three left over. Only for an `f` whose effect does not depend on the order.
pub(crate) fn for_each_interleaved<T>(items: &[T], mut f: impl FnMut(&T)) {
    let quarter = items.len() / 4;
    let (a, rest) = items.split_at(quarter);
    let (b, rest) = rest.split_at(quarter);
    let (c, rest) = rest.split_at(quarter);
    let (d, tail) = rest.split_at(quarter);
    for (((a, b), c), d) in a.iter().zip(b).zip(c).zip(d) {
        f(a);
        f(b);
        f(c);
        f(d);
    }
    tail.iter().for_each(f);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_item_is_visited_once() {
        for n in 0..13 {
            let items: Vec<usize> = (0..n).collect();
            let mut seen = Vec::new();
            for_each_interleaved(&items, |&i| seen.push(i));
            seen.sort_unstable();
            assert_eq!(seen, items, "{n} items");
        }
    }

    #[test]
    fn quarters_are_visited_side_by_side() {
        let items: Vec<usize> = (0..9).collect();
        let mut seen = Vec::new();
        for_each_interleaved(&items, |&i| seen.push(i));
        assert_eq!(seen, [0, 2, 4, 6, 1, 3, 5, 7, 8]);
    }
}
