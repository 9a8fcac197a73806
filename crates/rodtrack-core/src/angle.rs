//! Angle wraps, in one place: to `[0, 2 pi)` (an absolute angle, as measurements carry it), to
//! `(-pi, pi]` (an angle difference), and unwrapping near a reference (a continuous angle).
//!
//! Each function is the exact floating-point expression its callers used to write out, so
//! results are bit for bit what they were. Two flavours of the `(-pi, pi]` wrap exist, and
//! differ in the last bits:
//! - [`wrap_pi`] shifts by pi, wraps and shifts back (what the filter and the fusion use). The
//!   shift rounds: a difference smaller than about `1e-16` comes back as 0.
//! - [`wrap_pi_fold`] wraps to `[0, 2 pi)` and folds the upper half down (what the multi-turn
//!   count and the scores use). Small differences come back unchanged.

use std::f32::consts::TAU as TAU_F32;
use std::f64::consts::{PI, TAU};

/// `a` wrapped to `[0, 2 pi)`: `a.rem_euclid(2 pi)`.
///
/// Like [`f64::rem_euclid`], a negative `a` closer to 0 than half an ulp of `2 pi` (about
/// `4.4e-16`) comes back as exactly `2 pi`: the sum `2 pi + a` rounds there.
#[inline]
pub fn wrap_2pi(a: f64) -> f64 {
    a.rem_euclid(TAU)
}

/// [`wrap_2pi`] in `f32` (the paper mode's phase arithmetic).
#[inline]
pub fn wrap_2pi_f32(a: f32) -> f32 {
    a.rem_euclid(TAU_F32)
}

/// An angle difference wrapped to `(-pi, pi]`, by shifting it by pi, wrapping to `[0, 2 pi)`
/// and shifting back. The shift rounds `a + pi`, so the result carries an absolute error of
/// up to half an ulp of pi (about `2.2e-16`) (see [`wrap_pi_fold`] for the flavour without).
#[inline]
pub fn wrap_pi(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w <= -PI {
        w + TAU
    } else {
        w
    }
}

/// An angle difference wrapped to `(-pi, pi]`, by wrapping it to `[0, 2 pi)` ([`wrap_2pi`])
/// and taking `2 pi` off what lies above pi. A difference in `[0, pi]` comes back unchanged.
#[inline]
pub fn wrap_pi_fold(a: f64) -> f64 {
    let w = wrap_2pi(a);
    if w > PI {
        w - TAU
    } else {
        w
    }
}

/// The angle equal to `a` modulo `2 pi` nearest to `reference` (within pi of it):
/// `reference + wrap_pi(a - reference)` (see [`wrap_pi`]). Unwraps a wrapped angle against
/// the last unwrapped one.
#[inline]
pub fn unwrap_near(a: f64, reference: f64) -> f64 {
    reference + wrap_pi(a - reference)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// How far `x` is from the nearest whole multiple of `2 pi`.
    fn off_turn(x: f64) -> f64 {
        let k = (x / TAU).round();
        (x - k * TAU).abs()
    }

    #[test]
    fn edges() {
        assert_eq!(wrap_2pi(0.0), 0.0);
        assert_eq!(wrap_2pi(TAU), 0.0);
        assert_eq!(wrap_2pi(-TAU), 0.0);
        assert_eq!(wrap_2pi(-1e-20), TAU);
        assert_eq!(wrap_pi(PI), PI);
        assert_eq!(wrap_pi(-PI), PI);
        assert_eq!(wrap_pi(1e-20), 0.0);
        assert_eq!(wrap_pi_fold(PI), PI);
        assert_eq!(wrap_pi_fold(-PI), PI);
        assert_eq!(wrap_pi_fold(1e-20), 1e-20);
        assert_eq!(wrap_pi_fold(-1e-20), 0.0);
        assert_eq!(
            unwrap_near(0.1, 10.0 * TAU),
            10.0 * TAU + wrap_pi(0.1 - 10.0 * TAU)
        );
    }

    proptest! {
        #[test]
        fn wrap_2pi_lands_in_range_and_keeps_the_angle(a in -1e4f64..1e4) {
            let w = wrap_2pi(a);
            prop_assert!((0.0..=TAU).contains(&w), "{a} -> {w}");
            prop_assert!(w < TAU || a > -1e-15, "{a} -> {w}");
            prop_assert!(off_turn(w - a) < 1e-11, "{a} -> {w}");
            // Idempotent inside the range.
            if w < TAU {
                prop_assert_eq!(wrap_2pi(w), w);
            }
        }

        #[test]
        fn wrap_2pi_f32_lands_in_range(a in -1e3f32..1e3) {
            let w = wrap_2pi_f32(a);
            prop_assert!((0.0..=TAU_F32).contains(&w), "{a} -> {w}");
            prop_assert_eq!(w.to_bits(), a.rem_euclid(TAU_F32).to_bits());
        }

        #[test]
        fn both_pi_wraps_land_in_range_and_keep_the_angle(a in -1e4f64..1e4) {
            for w in [wrap_pi(a), wrap_pi_fold(a)] {
                prop_assert!(w > -PI && w <= PI, "{a} -> {w}");
                prop_assert!(off_turn(w - a) < 1e-11, "{a} -> {w}");
            }
            // The flavours agree but for rounding.
            let (s, f) = (wrap_pi(a), wrap_pi_fold(a));
            prop_assert!(off_turn(s - f) < 1e-11, "{a}: {s} vs {f}");
        }

        #[test]
        fn pi_wraps_leave_small_differences_alone(a in -3.0f64..3.0) {
            prop_assert!((wrap_pi(a) - a).abs() < 1e-15);
            if a >= 0.0 {
                prop_assert_eq!(wrap_pi_fold(a), a);
            } else {
                prop_assert!((wrap_pi_fold(a) - a).abs() < 1e-15);
            }
        }

        #[test]
        fn pi_wraps_are_the_expressions_they_replaced(a in -1e4f64..1e4) {
            // The filter's wrap, as it was written there.
            let w = (a + PI).rem_euclid(TAU) - PI;
            let filter = if w <= -PI { w + TAU } else { w };
            prop_assert_eq!(wrap_pi(a).to_bits(), filter.to_bits());
            // The multi-turn count's, as it was written in the pipeline.
            let mut d = a.rem_euclid(TAU);
            if d > PI {
                d -= TAU;
            }
            prop_assert_eq!(wrap_pi_fold(a).to_bits(), d.to_bits());
            prop_assert_eq!(wrap_2pi(a).to_bits(), a.rem_euclid(TAU).to_bits());
        }

        #[test]
        fn unwrap_near_is_within_pi_of_the_reference(a in 0.0f64..TAU, r in -1e3f64..1e3) {
            let u = unwrap_near(a, r);
            prop_assert!((u - r).abs() <= PI + 1e-9, "{a} near {r} -> {u}");
            prop_assert!(off_turn(u - a) < 1e-9, "{a} near {r} -> {u}");
            // An angle already near the reference stays.
            prop_assert!((unwrap_near(r + 0.5, r) - (r + 0.5)).abs() < 1e-9);
        }
    }
}
