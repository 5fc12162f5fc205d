//! A tiny seeded random generator for RANSAC and K-means: deterministic, allocation-free, no dependency.
//! Quality needs are modest (picking sample indices), so xorshift64* is enough.

/// xorshift64* (Vigna 2016). Same seed, same sequence, on every platform.
#[derive(Debug, Clone)]
pub(crate) struct Rng(u64);

impl Rng {
    /// A generator from a seed; zero (a fixed point of xorshift) is replaced by a constant.
    pub(crate) fn new(seed: u64) -> Self {
        Self(if seed == 0 { 0x9E37_79B9_7F4A_7C15 } else { seed })
    }

    fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// A uniform index in `0..n`; 0 when `n == 0`. Multiply-shift keeps the modulo bias below 2^-32.
    pub(crate) fn below(&mut self, n: usize) -> usize {
        (((self.next_u64() >> 32) * n as u64) >> 32) as usize
    }

    /// A uniform number in [0, 1).
    pub(crate) fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_sequence_and_in_range() {
        let (mut a, mut b) = (Rng::new(7), Rng::new(7));
        for _ in 0..1000 {
            let i = a.below(13);
            assert_eq!(i, b.below(13));
            assert!(i < 13);
        }
        assert_eq!(Rng::new(0).below(0), 0);
    }

    #[test]
    fn indices_are_roughly_uniform() {
        // 10 buckets, 100k draws: each within 5 % of 10k (binomial σ ≈ 95, so 50σ of slack per bucket).
        let mut r = Rng::new(1);
        let mut counts = [0usize; 10];
        for _ in 0..100_000 {
            counts[r.below(10)] += 1;
        }
        assert!(counts.iter().all(|&c| (9_500..10_500).contains(&c)), "{counts:?}");
        let u = r.unit();
        assert!((0.0..1.0).contains(&u));
    }
}
