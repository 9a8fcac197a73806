//! Angle decoding: the paper's coarse Gray code (2.4), single-bin DFT phase (eq. 6) and the four
//! fusion steps of 2.5.

use crate::angle::{wrap_2pi_f32, wrap_steps_f32};
use crate::marker::gray_decode;
use std::f32::consts::TAU;

/// The paper's adaptive threshold: `(min(30, min B) + max(100, max B)) / 2`.
pub fn paper_threshold(samples: &[f32]) -> f32 {
    let lo = samples.iter().cloned().fold(30.0f32, f32::min);
    let hi = samples.iter().cloned().fold(100.0f32, f32::max);
    0.5 * (lo + hi)
}

/// Binarises bit-space samples (bit space `k` at index `k`; dark = 1) and Gray-decodes them.
pub fn decode_bits(samples: &[f32], threshold: f32) -> (u32, u32) {
    let mut code = 0u32;
    for (k, &v) in samples.iter().enumerate() {
        if v < threshold {
            code |= 1 << k;
        }
    }
    (code, gray_decode(code))
}

/// Eq. (6): the phase of one DFT bin of period `period` (samples) over `d`, whose middle
/// element is `i = 0`.
pub fn paper_phase(d: &[f32], period: f32) -> f32 {
    let np = (d.len() / 2) as isize;
    let mut s = 0.0f32;
    let mut c = 0.0f32;
    for (idx, &v) in d.iter().enumerate() {
        let i = idx as isize - np;
        let a = TAU * i as f32 / period;
        s += v * a.sin();
        c += v * a.cos();
    }
    s.atan2(c)
}

/// The four fusion steps of 2.5. `phi` is the phase, `phi_offset` its calibrated offset,
/// `alpha` the decoded Gray step, `steps` the number of Gray steps (32). Returns `theta` in
/// `[0, steps)`, in Gray steps.
pub fn paper_fuse(phi: f32, phi_offset: f32, alpha: u32, steps: u32) -> f32 {
    // 1. Offset and rescale to a period of 4.
    let phi_p = 4.0 * wrap_2pi_f32(phi - phi_offset) / TAU;
    // 2. Strip the two low bits.
    let alpha_p = (alpha & !3) as f32;
    // 3. Wrap the difference to [-2, 2] with j.
    let d = phi_p + alpha_p - alpha as f32;
    let j = (-d / 4.0).round();
    // 4. Combine.
    wrap_steps_f32(phi_p + alpha_p + 4.0 * j, steps as f32)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn threshold_rule() {
        assert_eq!(paper_threshold(&[50.0, 60.0, 70.0]), 65.0);
        assert_eq!(paper_threshold(&[10.0, 200.0]), 105.0);
    }

    #[test]
    fn decode_bits_reads_dark_as_one() {
        // code 00011 (bit 4 first) = gray(2): bits 0 and 1 dark.
        let (code, alpha) = decode_bits(&[20.0, 25.0, 200.0, 210.0, 190.0], 100.0);
        assert_eq!(code, 0b00011);
        assert_eq!(alpha, 2);
    }

    /// Over a window that is not a whole number of periods the bright mean leaks into eq. 6:
    /// the paper's phase is biased, which rodtrack's enhanced phase avoids by removing the mean.
    #[test]
    fn paper_phase_leaks_dc_off_whole_periods() {
        let period = 6.0f32;
        let shift = 1.5f32;
        let v: Vec<f32> = (-10..=10)
            .map(|i| 100.0 + 80.0 * (TAU * (i as f32 - shift) / period).cos())
            .collect();
        let expect = TAU * shift / period;
        let err = |p: f32| (p - expect).abs();
        assert!(err(paper_phase(&v, period)) > 0.2);
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        let z: Vec<f32> = v.iter().map(|x| x - mean).collect();
        assert!(err(paper_phase(&z, period)) < 0.5 * err(paper_phase(&v, period)));
    }

    proptest! {
        /// A stripe pattern shifted by `shift` samples has its eq.-6 phase shifted by
        /// `2 pi shift / T`.
        #[test]
        fn phase_of_shifted_stripes(shift in -3.0f32..3.0, periods in 2usize..5) {
            // A window of a whole number of periods: eq. 6 is then exact.
            let period = 21.0 / periods as f32;
            let make = |sh: f32| -> Vec<f32> {
                (-10..=10).map(|i| 100.0 + 80.0 * (TAU * (i as f32 - sh) / period).cos()).collect()
            };
            let p0 = paper_phase(&make(0.0), period);
            let p1 = paper_phase(&make(shift), period);
            let expect = TAU * shift / period;
            let diff = (p1 - p0 - expect + 3.0 * TAU).rem_euclid(TAU);
            let diff = if diff > TAU / 2.0 { diff - TAU } else { diff };
            prop_assert!(diff.abs() < 1e-3, "diff {}", diff);
        }

        /// With a consistent phase, fusion returns the true angle whatever the Gray step's
        /// low bits, and a Gray value off by one step does not change it.
        #[test]
        fn fusion_recovers_theta(theta in 0.0f32..32.0, off in -0.9f32..0.9) {
            let phi = TAU * (theta % 4.0) / 4.0;
            let alpha = (theta.floor() as i32 + if off.abs() > 0.6 { off.signum() as i32 } else { 0 })
                .rem_euclid(32) as u32;
            let t = paper_fuse(phi, 0.0, alpha, 32);
            let err = (t - theta + 48.0).rem_euclid(32.0) - 16.0;
            prop_assert!(err.abs() < 1e-3, "theta {} alpha {} got {}", theta, alpha, t);
        }
    }
}
