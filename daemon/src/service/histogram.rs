//! Fixed-size log-linear histogram of nanosecond durations for the loop's
//! timing: allocated once, `record` never allocates.
//!
//! Values below 64 ns have their own bucket; above, each power of two is cut
//! into 64 buckets, so a percentile is reported within 1/64 (1.6 %) of the
//! true value, rounded up (never optimistic). The maximum is exact.

/// Sub-buckets per power of two, as a power of two.
const SUB_BITS: u32 = 6;
const SUB: usize = 1 << SUB_BITS;
/// Buckets needed to cover every `u64`.
const BUCKETS: usize = (64 - SUB_BITS as usize + 1) * SUB;

/// Counts of durations in ns. Serves `u64::MAX` without overflow.
#[derive(Clone, Debug)]
pub struct Histogram {
    buckets: Vec<u32>,
    count: u64,
    max: u64,
}

impl Default for Histogram {
    fn default() -> Self {
        Self::new()
    }
}

impl Histogram {
    /// An empty histogram (the only allocation).
    pub fn new() -> Self {
        Histogram {
            buckets: vec![0; BUCKETS],
            count: 0,
            max: 0,
        }
    }

    fn index(v: u64) -> usize {
        if v < SUB as u64 {
            return v as usize;
        }
        let msb = 63 - v.leading_zeros();
        let shift = msb - SUB_BITS;
        let sub = (v >> shift) as usize - SUB;
        (shift as usize + 1) * SUB + sub
    }

    /// Largest value that falls into bucket `i`.
    fn upper(i: usize) -> u64 {
        if i < SUB {
            return i as u64;
        }
        let shift = (i / SUB - 1) as u32;
        let lower = ((SUB + i % SUB) as u64) << shift;
        lower + ((1u64 << shift) - 1)
    }

    /// Counts one value, ns. No allocation.
    #[inline]
    pub fn record(&mut self, ns: u64) {
        let b = &mut self.buckets[Self::index(ns)];
        *b = b.saturating_add(1);
        self.count += 1;
        self.max = self.max.max(ns);
    }

    /// Values recorded.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Largest value recorded, ns (`None` when empty).
    pub fn max(&self) -> Option<u64> {
        (self.count > 0).then_some(self.max)
    }

    /// The value at quantile `q` in `[0, 1]`, ns: the upper edge of the bucket that
    /// holds the `⌈q·n⌉`-th smallest value, capped at the maximum. `None` when empty.
    pub fn quantile(&self, q: f64) -> Option<u64> {
        if self.count == 0 {
            return None;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.count as f64).ceil() as u64).max(1);
        let mut seen = 0u64;
        for (i, &c) in self.buckets.iter().enumerate() {
            seen += u64::from(c);
            if seen >= rank {
                return Some(Self::upper(i).min(self.max));
            }
        }
        Some(self.max)
    }
}

/// Percentiles of a histogram of durations, µs: one table for every loop's
/// timing (`serve`, `demo`, `jitter`).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Percentiles {
    /// Samples.
    pub samples: u64,
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// 99.9th percentile.
    pub p999: f64,
    /// Maximum.
    pub max: f64,
}

impl Percentiles {
    /// Of a histogram in ns (`None` when empty).
    pub fn of(h: &Histogram) -> Option<Self> {
        let us = |ns: u64| ns as f64 / 1e3;
        Some(Percentiles {
            samples: h.count(),
            p50: us(h.quantile(0.5)?),
            p99: us(h.quantile(0.99)?),
            p999: us(h.quantile(0.999)?),
            max: us(h.max()?),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_tile_the_range() {
        assert_eq!(Histogram::index(0), 0);
        assert_eq!(Histogram::index(63), 63);
        assert_eq!(Histogram::index(64), 64);
        assert_eq!(Histogram::index(u64::MAX), BUCKETS - 1);
        for i in 0..BUCKETS - 1 {
            let hi = Histogram::upper(i);
            assert_eq!(Histogram::index(hi), i);
            assert_eq!(Histogram::index(hi + 1), i + 1);
        }
        assert_eq!(Histogram::upper(BUCKETS - 1), u64::MAX);
    }

    #[test]
    fn quantiles_are_close_and_never_below_the_truth() {
        let mut h = Histogram::new();
        assert_eq!(h.quantile(0.5), None);
        for v in 1..=10_000u64 {
            h.record(v * 100);
        }
        assert_eq!(h.count(), 10_000);
        assert_eq!(h.max(), Some(1_000_000));
        for (q, truth) in [(0.5, 500_000.0), (0.99, 990_000.0), (1.0, 1_000_000.0)] {
            let got = h.quantile(q).unwrap() as f64;
            assert!(
                got >= truth && got <= truth * (1.0 + 1.0 / 64.0),
                "{q}: {got}"
            );
        }
        // Small values are exact.
        let mut h = Histogram::new();
        for v in [3, 3, 7] {
            h.record(v);
        }
        assert_eq!(h.quantile(0.5), Some(3));
        assert_eq!(h.quantile(1.0), Some(7));
    }
}
