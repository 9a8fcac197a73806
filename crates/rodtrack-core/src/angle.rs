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
//!
//! The same wraps exist for a period other than a turn, for angles counted in Gray steps
//! (`steps` per turn) or in groups of 4 steps: [`wrap_steps`], [`wrap_steps_centred`],
//! [`step_index`], and for whole step numbers [`wrap_step`] and [`wrap_step_diff`]. And
//! [`whole_turns`] is the multiple of `2 pi` nearest to an angle (aligning two unwrapped
//! angles).

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

/// `x` wrapped to `[0, period)` (for example an angle in Gray steps, `period` = the number
/// of steps per turn): `x.rem_euclid(period)`. Like [`wrap_2pi`], a negative `x` within half
/// an ulp of 0 comes back as `period`: see [`step_index`] for the whole step.
#[inline]
pub fn wrap_steps(x: f64, period: f64) -> f64 {
    x.rem_euclid(period)
}

/// [`wrap_steps`] in `f32` (the paper mode's step arithmetic).
#[inline]
pub fn wrap_steps_f32(x: f32, period: f32) -> f32 {
    x.rem_euclid(period)
}

/// A difference `d` wrapped to `[-period / 2, period / 2)`, by shifting it by half a period,
/// wrapping ([`wrap_steps`]) and shifting back (the step difference between two angles in
/// Gray steps). The shift rounds, as in [`wrap_pi`].
#[inline]
pub fn wrap_steps_centred(d: f64, period: f64) -> f64 {
    (d + 0.5 * period).rem_euclid(period) - 0.5 * period
}

/// The whole step, `[0, steps)`, that an angle `x` in steps lies in: `x` wrapped to
/// `[0, steps)` and truncated (an `x` that wraps to exactly `steps` by rounding is step 0).
#[inline]
pub fn step_index(x: f64, steps: u32) -> u32 {
    x.rem_euclid(steps as f64) as u32 % steps
}

/// A whole step number wrapped to `[0, steps)` (`steps` > 0).
#[inline]
pub fn wrap_step(step: i64, steps: u32) -> u32 {
    step.rem_euclid(i64::from(steps)) as u32
}

/// A difference of whole steps wrapped to `(-steps / 2, steps / 2]` (for an even `steps`):
/// wrapped to `[0, steps)` ([`wrap_step`]) and with `steps` taken off what lies above half.
/// The integer counterpart of [`wrap_pi_fold`].
#[inline]
pub fn wrap_step_diff(d: i64, steps: i64) -> i64 {
    let w = d.rem_euclid(steps);
    if w > steps / 2 {
        w - steps
    } else {
        w
    }
}

/// The whole number of turns nearest to `a`, as an angle: `round(a / 2 pi) * 2 pi` (the
/// offset that aligns one unwrapped angle with another).
#[inline]
pub fn whole_turns(a: f64) -> f64 {
    (a / TAU).round() * TAU
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
        fn step_wraps_are_the_expressions_they_replaced(x in -1e3f64..1e3, p in 1u32..64) {
            let pf = p as f64;
            prop_assert_eq!(wrap_steps(x, pf).to_bits(), x.rem_euclid(pf).to_bits());
            prop_assert_eq!(
                wrap_steps_centred(x, pf).to_bits(),
                ((x + 0.5 * pf).rem_euclid(pf) - 0.5 * pf).to_bits()
            );
            let c = wrap_steps_centred(x, pf);
            prop_assert!(c >= -0.5 * pf - 1e-9 && c <= 0.5 * pf, "{x} -> {c}");
            let i = step_index(x, p);
            prop_assert!(i < p);
            prop_assert_eq!(i, x.rem_euclid(pf) as u32 % p);
            let (xf, xs) = (x as f32, p as f32);
            prop_assert_eq!(wrap_steps_f32(xf, xs).to_bits(), xf.rem_euclid(xs).to_bits());
            prop_assert_eq!(whole_turns(x).to_bits(), ((x / TAU).round() * TAU).to_bits());
            prop_assert!((x - whole_turns(x)).abs() <= PI + 1e-9);
        }

        #[test]
        fn integer_step_wraps(d in -10_000i64..10_000, half in 1i64..64) {
            let steps = 2 * half;
            let w = wrap_step(d, steps as u32);
            prop_assert!(i64::from(w) < steps && (i64::from(w) - d) % steps == 0);
            let f = wrap_step_diff(d, steps);
            prop_assert!(f > -half && f <= half && (f - d) % steps == 0, "{d} -> {f}");
            // What the calibration's direction vote wrote out.
            let mut old = d.rem_euclid(steps);
            if old > steps / 2 {
                old -= steps;
            }
            prop_assert_eq!(f, old);
            // What the judge's edge bit wrote out for a step in range.
            if (0..steps).contains(&d) {
                let s = steps as u32;
                prop_assert_eq!(wrap_step(d - 1, s), (d as u32 + s - 1) % s);
            }
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
