//! A fixed-size log-linear latency histogram (about 3 % relative resolution, no allocation per
//! sample).

use std::time::Duration;

const LINEAR: u64 = 64;
const SUB: usize = 32;
const BUCKETS: usize = LINEAR as usize + 58 * SUB;

/// Latency histogram in nanoseconds.
#[derive(Clone)]
pub struct LatencyHistogram {
    counts: Box<[u64; BUCKETS]>,
    count: u64,
    sum_ns: u128,
    min_ns: u64,
    max_ns: u64,
}

impl std::fmt::Debug for LatencyHistogram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LatencyHistogram")
            .field("summary", &self.summary())
            .finish()
    }
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        LatencyHistogram {
            counts: Box::new([0; BUCKETS]),
            count: 0,
            sum_ns: 0,
            min_ns: u64::MAX,
            max_ns: 0,
        }
    }
}

fn bucket(v: u64) -> usize {
    if v < LINEAR {
        return v as usize;
    }
    let e = 63 - v.leading_zeros() as usize; // >= 6
    let m = (v >> (e - 5)) as usize; // 32..63
    LINEAR as usize + (e - 6) * SUB + (m - SUB)
}

/// Lower and upper bound of a bucket.
fn bounds(b: usize) -> (u64, u64) {
    if b < LINEAR as usize {
        return (b as u64, b as u64 + 1);
    }
    let k = b - LINEAR as usize;
    let e = k / SUB + 6;
    let m = (k % SUB + SUB) as u64;
    let shift = e - 5;
    let hi = ((u128::from(m) + 1) << shift).min(u128::from(u64::MAX)) as u64;
    (m << shift, hi)
}

/// Percentiles of a histogram.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LatencySummary {
    /// Number of samples.
    pub count: u64,
    /// Smallest sample.
    pub min: Duration,
    /// Mean.
    pub mean: Duration,
    /// Median (bucket midpoint, clamped to min..max).
    pub p50: Duration,
    /// 90th percentile.
    pub p90: Duration,
    /// 99th percentile.
    pub p99: Duration,
    /// Largest sample (exact).
    pub max: Duration,
}

impl std::fmt::Display for LatencySummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        write!(
            f,
            "{} samples, p50 {:.3} ms, p90 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
            self.count,
            ms(self.p50),
            ms(self.p90),
            ms(self.p99),
            ms(self.max)
        )
    }
}

/// Where a frame's latency goes: the five consecutive stages from "frame available" to "rows
/// written", each a distribution over frames (their sum, frame by frame, is the latency).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LatencyStages {
    /// Frame available -> its processing starts: the queue and the processing thread's wake-up
    /// ([`super::Handoff::Queue`]); zero with [`super::Handoff::Inline`].
    pub pickup: LatencySummary,
    /// The processing stage (the tracker) and the camera's filter.
    pub process: LatencySummary,
    /// Processing done -> the output stage has the rows: the hand-off to the calling thread
    /// ([`super::Pipeline::run`]) or the wait for the output lock ([`super::Pipeline::run_direct`]).
    pub handoff: LatencySummary,
    /// Waiting for the other cameras of the frame set ([`super::WriteMode::Set`]); zero with
    /// [`super::WriteMode::PerCamera`].
    pub wait_set: LatencySummary,
    /// The write: the set's rows gathered, the fusion and the sink's `write` call
    /// ([`super::WriteMode::Set`]), or the camera's rows passed to the sink's `write`
    /// ([`super::WriteMode::PerCamera`]).
    pub write: LatencySummary,
}

impl std::fmt::Display for LatencyStages {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let us = |d: Duration| d.as_secs_f64() * 1e6;
        write!(f, "stages p50/p99 (us):")?;
        for (i, (name, s)) in [
            ("pickup", &self.pickup),
            ("process", &self.process),
            ("hand-off", &self.handoff),
            ("wait for set", &self.wait_set),
            ("write", &self.write),
        ]
        .into_iter()
        .enumerate()
        {
            let sep = if i == 0 { "" } else { "," };
            write!(f, "{sep} {name} {:.0}/{:.0}", us(s.p50), us(s.p99))?;
        }
        Ok(())
    }
}

/// The histograms behind [`LatencyStages`].
#[derive(Debug, Clone, Default)]
pub(crate) struct StageHistograms {
    pub(crate) pickup: LatencyHistogram,
    pub(crate) process: LatencyHistogram,
    pub(crate) handoff: LatencyHistogram,
    pub(crate) wait_set: LatencyHistogram,
    pub(crate) write: LatencyHistogram,
}

impl StageHistograms {
    pub(crate) fn summary(&self) -> LatencyStages {
        LatencyStages {
            pickup: self.pickup.summary(),
            process: self.process.summary(),
            handoff: self.handoff.summary(),
            wait_set: self.wait_set.summary(),
            write: self.write.summary(),
        }
    }
}

impl LatencyHistogram {
    /// An empty histogram.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one sample.
    pub fn record(&mut self, d: Duration) {
        let ns = u64::try_from(d.as_nanos()).unwrap_or(u64::MAX);
        self.counts[bucket(ns)] += 1;
        self.count += 1;
        self.sum_ns += u128::from(ns);
        self.min_ns = self.min_ns.min(ns);
        self.max_ns = self.max_ns.max(ns);
    }

    /// Adds all samples of another histogram.
    pub fn merge(&mut self, other: &LatencyHistogram) {
        for (a, b) in self.counts.iter_mut().zip(other.counts.iter()) {
            *a += b;
        }
        self.count += other.count;
        self.sum_ns += other.sum_ns;
        self.min_ns = self.min_ns.min(other.min_ns);
        self.max_ns = self.max_ns.max(other.max_ns);
    }

    /// Number of samples.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// The value below which a fraction `q` (0..=1) of the samples lie.
    pub fn quantile(&self, q: f64) -> Duration {
        if self.count == 0 {
            return Duration::ZERO;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.count as f64).ceil() as u64).max(1);
        let mut seen = 0u64;
        for (b, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                let (lo, hi) = bounds(b);
                let mid = lo + (hi - lo) / 2;
                return Duration::from_nanos(mid.clamp(self.min_ns, self.max_ns));
            }
        }
        Duration::from_nanos(self.max_ns)
    }

    /// Count, min, mean, p50, p90, p99, max.
    pub fn summary(&self) -> LatencySummary {
        if self.count == 0 {
            return LatencySummary::default();
        }
        LatencySummary {
            count: self.count,
            min: Duration::from_nanos(self.min_ns),
            mean: Duration::from_nanos((self.sum_ns / u128::from(self.count)) as u64),
            p50: self.quantile(0.5),
            p90: self.quantile(0.9),
            p99: self.quantile(0.99),
            max: Duration::from_nanos(self.max_ns),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_are_contiguous() {
        let mut prev_hi = 0;
        for b in 0..BUCKETS {
            let (lo, hi) = bounds(b);
            assert_eq!(lo, prev_hi, "bucket {b}");
            assert!(hi > lo);
            prev_hi = hi;
        }
        for v in [0u64, 1, 63, 64, 65, 1000, 123_456_789, u64::MAX / 3] {
            let (lo, hi) = bounds(bucket(v));
            assert!(lo <= v && v < hi, "{v}");
        }
    }

    #[test]
    fn percentiles_within_resolution() {
        let mut h = LatencyHistogram::new();
        for us in 1..=1000u64 {
            h.record(Duration::from_micros(us));
        }
        let s = h.summary();
        let near = |d: Duration, us: f64| (d.as_secs_f64() * 1e6 - us).abs() / us < 0.04;
        assert!(near(s.p50, 500.0), "{s}");
        assert!(near(s.p99, 990.0), "{s}");
        assert_eq!(s.max, Duration::from_micros(1000));
        assert_eq!(s.min, Duration::from_micros(1));
        assert_eq!(s.count, 1000);
    }
}
