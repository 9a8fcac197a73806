//! Capture time: one nanosecond timestamp type from the source to the sink.
//!
//! A source stamps each frame with a [`Timestamp`]; the tracker copies it into every
//! [`Measurement`](crate::Measurement) of that frame, and the filter, the fusion, the sinks and
//! the bindings read it from there. Time differences are taken in whole nanoseconds and
//! converted to seconds once ([`Timestamp::seconds_since`]); seconds as `f64`
//! ([`Timestamp::as_secs_f64`]) are for printing and for the physics that need a continuous
//! time.

use serde::{Deserialize, Serialize};

/// The latest time [`Timestamp::try_from_secs_f64`] accepts, s (about 317 years; `u64`
/// nanoseconds reach 584 years).
pub const MAX_TIMESTAMP_S: f64 = 1e10;

/// A capture time in nanoseconds (from the source's own epoch: camera clock, first frame, ...).
///
/// ```
/// use rodtrack_core::Timestamp;
/// let t = Timestamp::from_frame(3, 200.0);
/// assert_eq!(t.as_nanos(), 15_000_000);
/// assert_eq!(t.seconds_since(Timestamp::from_nanos(5_000_000)), 0.01);
/// ```
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Timestamp(pub u64);

impl Timestamp {
    /// From nanoseconds.
    pub const fn from_nanos(ns: u64) -> Self {
        Timestamp(ns)
    }
    /// From seconds, to the nearest nanosecond; negative and non-finite values give 0.
    pub fn from_secs_f64(s: f64) -> Self {
        if s.is_finite() && s > 0.0 {
            Timestamp((s * 1e9).round() as u64)
        } else {
            Timestamp(0)
        }
    }
    /// From seconds read from outside (a file, a packet, a binding), to the nearest
    /// nanosecond; `None` unless finite, not negative and at most [`MAX_TIMESTAMP_S`].
    pub fn try_from_secs_f64(s: f64) -> Option<Self> {
        (s.is_finite() && (0.0..=MAX_TIMESTAMP_S).contains(&s)).then(|| Timestamp::from_secs_f64(s))
    }
    /// Nanoseconds.
    pub const fn as_nanos(self) -> u64 {
        self.0
    }
    /// Seconds (`ns * 1e-9`).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }
    /// The time from `earlier` to `self`, seconds: the exact difference in nanoseconds,
    /// converted once (negative when `earlier` is later).
    pub fn seconds_since(self, earlier: Timestamp) -> f64 {
        (i128::from(self.0) - i128::from(earlier.0)) as f64 * 1e-9
    }
    /// The time of frame `frame_id` at a constant `fps` (frame 0 at time 0). Exact for whole
    /// frame rates; 0 for a rate that is not finite and positive.
    pub fn from_frame(frame_id: u64, fps: f64) -> Self {
        if !(fps > 0.0 && fps.is_finite()) {
            return Timestamp(0);
        }
        if fps.fract() == 0.0 && fps <= u64::MAX as f64 {
            let ns = u128::from(frame_id) * 1_000_000_000 / fps as u128;
            return Timestamp(u64::try_from(ns).unwrap_or(u64::MAX));
        }
        Timestamp((frame_id as f64 * 1e9 / fps).round() as u64)
    }
}

impl std::fmt::Display for Timestamp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.9} s", self.as_secs_f64())
    }
}

/// Serde for a [`Timestamp`] written as seconds (`f64`), the way the measurement files carry
/// it: `#[serde(with = "rodtrack_core::time::as_secs")]`.
pub mod as_secs {
    use super::Timestamp;
    use serde::{Deserialize, Deserializer, Serializer};

    /// Writes `t` as seconds.
    pub fn serialize<S: Serializer>(t: &Timestamp, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(t.as_secs_f64())
    }
    /// Reads seconds, to the nearest nanosecond.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Timestamp, D::Error> {
        f64::deserialize(d).map(Timestamp::from_secs_f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamps_convert() {
        assert_eq!(Timestamp::from_frame(3, 200.0).as_nanos(), 15_000_000);
        assert_eq!(Timestamp::from_secs_f64(1.5).as_nanos(), 1_500_000_000);
        assert_eq!(Timestamp::from_secs_f64(f64::NAN).as_nanos(), 0);
        assert_eq!(Timestamp::from_frame(3, 0.0).as_nanos(), 0);
        assert_eq!(Timestamp::from_frame(1, 3.0).as_nanos(), 333_333_333);
        assert_eq!(
            Timestamp::from_frame(10_000_000_019, 227.0).as_nanos(),
            44_052_863_519_823_788
        );
        assert_eq!(Timestamp::from_frame(2, 2.5).as_nanos(), 800_000_000);
        assert_eq!(
            Timestamp::try_from_secs_f64(0.055),
            Some(Timestamp(55_000_000))
        );
        assert_eq!(Timestamp::try_from_secs_f64(0.0), Some(Timestamp(0)));
        for bad in [-1e-9, f64::NAN, f64::INFINITY, 1.1e10] {
            assert_eq!(Timestamp::try_from_secs_f64(bad), None, "{bad}");
        }
    }

    #[test]
    fn differences_are_exact_before_the_conversion() {
        // Far from the epoch, seconds lose the nanoseconds; the integer difference keeps them.
        let a = Timestamp::from_nanos(1_000_000_000_000_000_000);
        let b = Timestamp::from_nanos(1_000_000_000_000_000_001);
        assert_eq!(b.seconds_since(a), 1e-9);
        assert_eq!(a.seconds_since(b), -1e-9);
        assert_eq!(b.as_secs_f64() - a.as_secs_f64(), 0.0);
        assert_eq!(
            Timestamp(u64::MAX).seconds_since(Timestamp(0)),
            u64::MAX as f64 * 1e-9
        );
    }
}
