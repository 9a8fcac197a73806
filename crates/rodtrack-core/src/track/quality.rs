//! A row's `quality`: how far this frame's measurement is from the best the marker allows,
//! from what the stages measured. See `docs/quality.md` for the derivation and the measured
//! relation to the error.
//!
//! The temporal filter and the fusion weigh a row by a variance `sigma^2 / quality^2`, `sigma`
//! being a camera's noise at quality 1. So quality is defined as a ratio of standard deviations
//! (the one the marker gives at best over the one this frame's evidence predicts), times the
//! share of the evidence against a wrong absolute code that is absent:
//!
//! `quality = min(q_phase, q_amplitude, q_position) * q_code`
//!
//! - `q_phase = min(1, sqrt(r_print / r), sigma_angle / sigma_bias)`, with `r = (1 - share) /
//!   share` the power the phase fit leaves unexplained over the power of the stripes'
//!   fundamental (`share`: the share of the variation across the rod the fundamental
//!   explains). The print alone leaves the power of a square wave's harmonics, `r_print =
//!   pi^2 / 8 - 1` (less when blurred), which does not bias the phase. More than that is
//!   noise or something over the stripes that is not print (a finger's edge, a shadow,
//!   glare). As noise, spread over the samples, it grows the phase's std by `sqrt(r /
//!   r_print)` (a least-squares sinusoid's phase variance is residual power over fundamental
//!   power over samples). As an object over part of the stripes it does not average out: a
//!   perturbation of power `P_e` shifts the fitted phase by up to `sqrt(P_e / P_1)` rad
//!   (`P_1` the fundamental's power; the worst case is a perturbation in quadrature with
//!   it), so the angle may be off by `sigma_bias = sqrt(r - r_print) / cycles` (`cycles`:
//!   stripe periods per turn), against a camera's angle noise at quality 1, `sigma_angle`
//!   ([`ANGLE_NOISE_RAD`]).
//! - `q_amplitude = min(1, 1 / amp_ratio)`: the fundamental over a square wave's between the
//!   print's black and white. Only added light makes it stronger than the print's; of a
//!   fundamental `amp_ratio` times the print's, at most the share `1 / amp_ratio` is print.
//! - `q_position = min(1, sigma_ref / sigma_position)`, `sigma_position = edge_std /
//!   sqrt(edges - 2)` the std of the mean of the barcode's edges around their line (two
//!   parameters fitted), and `sigma_ref` a camera's position noise at quality 1 (the filter's
//!   default, [`POSITION_NOISE_MM`]).
//! - `q_code = 1 - code_share / wrong_share`: a reading whose high Gray bits were fooled by a
//!   group of 4 steps or more disagrees with at least `wrong_share` of some bit space's
//!   samples across the rod (the code's geometry alone gives that bound, see
//!   [`super::min_wrong_share`]); a true one only where noise, blur or the image's departure
//!   from its model flip a sample. `code_share / wrong_share` is the share of the evidence of
//!   a wrong reading that is present. A reading that continues the last frame's (slow motion:
//!   the check is skipped) carries the evidence of the check that started it.

/// A camera's position noise std at quality 1, mm (the temporal filter's and the fusion's
/// default, `FilterConfig::position_noise_mm`).
pub(super) const POSITION_NOISE_MM: f64 = 0.1;

/// A camera's angle noise std at quality 1, rad (the temporal filter's and the fusion's
/// default, `FilterConfig::angle_noise_rad`).
pub(super) const ANGLE_NOISE_RAD: f64 = 0.004;

/// The unexplained power of a sharp square wave's fit by its fundamental, over the
/// fundamental's: `sum over odd k >= 3 of 1 / k^2 = pi^2 / 8 - 1`.
pub(super) fn print_residual_ratio() -> f64 {
    std::f64::consts::PI * std::f64::consts::PI / 8.0 - 1.0
}

/// What the quality is computed from (see the module's documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct QualityInputs {
    /// The share of the variation across the rod over bit space 0 that the stripes'
    /// fundamental explains, `[0, 1]`.
    pub(super) stripe_share: f64,
    /// The stripes' fundamental over a square wave's between the print's black and white.
    pub(super) amp_ratio: f64,
    /// Spread of the barcode's edges around their line, mm.
    pub(super) edge_std_mm: f64,
    /// Barcode edges the position is fitted to.
    pub(super) edges: usize,
    /// The share of some bit space's samples across the rod that disagree with the reading
    /// (the worst bit space), `[0, 1]`.
    pub(super) code_share: f64,
    /// The least such share a reading fooled by a group or more gives.
    pub(super) wrong_share: f64,
    /// Stripe periods of bit space 0 per turn.
    pub(super) cycles: f64,
}

/// The quality factors: `(q_phase, q_amplitude, q_position, q_code)`, each in `[0, 1]`.
pub(super) fn factors(q: &QualityInputs) -> (f64, f64, f64, f64) {
    let share = q.stripe_share;
    let q_phase = if share.is_nan() || share <= 0.0 {
        0.0
    } else if share >= 1.0 {
        1.0
    } else {
        let r = (1.0 - share) / share;
        let r0 = print_residual_ratio();
        let sigma_bias = (r - r0).max(0.0).sqrt() / q.cycles.max(1.0);
        let q_bias = if sigma_bias > 0.0 {
            ANGLE_NOISE_RAD / sigma_bias
        } else {
            1.0
        };
        (r0 / r).sqrt().min(q_bias).min(1.0)
    };
    let q_amp = if q.amp_ratio > 1.0 {
        1.0 / q.amp_ratio
    } else if q.amp_ratio >= 0.0 {
        1.0
    } else {
        0.0
    };
    let dof = (q.edges as f64 - 2.0).max(1.0);
    let sigma_pos = q.edge_std_mm / dof.sqrt();
    let q_pos = if sigma_pos > 0.0 {
        (POSITION_NOISE_MM / sigma_pos).min(1.0)
    } else if sigma_pos == 0.0 {
        1.0
    } else {
        0.0
    };
    let q_code = if q.wrong_share > 0.0 {
        (1.0 - q.code_share / q.wrong_share).clamp(0.0, 1.0)
    } else {
        1.0
    };
    (q_phase, q_amp, q_pos, q_code)
}

/// The row's quality, `[0, 1]` (never NaN).
pub(super) fn quality(q: &QualityInputs) -> f64 {
    let (p, a, s, c) = factors(q);
    let v = p.min(a).min(s) * c;
    if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn base() -> QualityInputs {
        QualityInputs {
            stripe_share: 8.0 / (std::f64::consts::PI * std::f64::consts::PI),
            amp_ratio: 1.0,
            edge_std_mm: 0.01,
            edges: 12,
            code_share: 0.0,
            wrong_share: 0.4,
            cycles: 8.0,
        }
    }

    /// The print itself, sharp, read without noise and agreeing with its code, is quality 1.
    #[test]
    fn a_sharp_clean_print_is_quality_one() {
        assert!((quality(&base()) - 1.0).abs() < 1e-12);
    }

    /// Each piece of evidence lowers the quality as its derivation says.
    #[test]
    fn each_factor_follows_its_derivation() {
        // Unexplained power beyond the print's: as noise, the phase's std grows by
        // sqrt(r / r_print); as an object over part of the stripes, the angle may be off by
        // sqrt(r - r_print) / cycles. The worse of the two.
        let r0 = print_residual_ratio();
        for excess in [1e-4, 1e-3, 0.01, 0.1, 1.0] {
            let r = r0 + excess;
            let q = quality(&QualityInputs {
                stripe_share: 1.0 / (1.0 + r),
                ..base()
            });
            let noise = (r0 / r).sqrt();
            let bias = ANGLE_NOISE_RAD * 8.0 / excess.sqrt();
            assert!((q - noise.min(bias).min(1.0)).abs() < 1e-9, "{excess}: {q}");
        }
        // A hand over a third of the stripes (the share measured on such rows: 0.63): the
        // angle may be 0.07 rad off, and the quality says so.
        let q = quality(&QualityInputs {
            stripe_share: 0.63,
            ..base()
        });
        assert!(q < 0.1, "{q}");
        // Blurred stripes explain more than a square wave's fundamental: nothing lost.
        let q = quality(&QualityInputs {
            stripe_share: 0.97,
            ..base()
        });
        assert!((q - 1.0).abs() < 1e-12, "{q}");
        // A fundamental 1.25 times the print's: at most 0.8 of it is print.
        let q = quality(&QualityInputs {
            amp_ratio: 1.25,
            ..base()
        });
        assert!((q - 0.8).abs() < 1e-12, "{q}");
        // Edges spread 0.5 mm over 12: 0.158 mm, the reference 0.1 mm.
        let q = quality(&QualityInputs {
            edge_std_mm: 0.5,
            ..base()
        });
        assert!((q - 0.1 / (0.5 / 10f64.sqrt())).abs() < 1e-9, "{q}");
        // Half the disagreement a wrong reading must give.
        let q = quality(&QualityInputs {
            code_share: 0.2,
            ..base()
        });
        assert!((q - 0.5).abs() < 1e-12, "{q}");
    }

    /// Degenerate inputs give a quality in [0, 1], never NaN.
    #[test]
    fn degenerate_inputs_stay_in_range() {
        for share in [f64::NAN, -1.0, 0.0, 1.0, 2.0] {
            for amp in [f64::NAN, -1.0, 0.0, 5.0] {
                for wrong in [0.0, 0.4] {
                    let q = quality(&QualityInputs {
                        stripe_share: share,
                        amp_ratio: amp,
                        edge_std_mm: f64::NAN,
                        edges: 0,
                        code_share: f64::NAN,
                        wrong_share: wrong,
                        cycles: 8.0,
                    });
                    assert!((0.0..=1.0).contains(&q), "{q}");
                }
            }
        }
    }
}
