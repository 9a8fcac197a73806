//! Step 6: the phase fused with the Gray code, their consistency, and the status and quality.

use super::agree::CodeCheck;
use super::quality::{quality, QualityInputs};
use super::result::RodResult;
use super::state::{EnhancedState, GrayRead, Intermediate, PhaseFit};
use super::tuning::{MAX_STRIPE_AMP_RATIO, MIN_STRIPE_SHARE};
use crate::angle::{wrap_2pi, wrap_step, wrap_steps, wrap_steps_centred};
use crate::calib::RodCalibration;
use crate::marker::Marker;
use crate::measurement::Status;
use std::f64::consts::TAU;

impl EnhancedState {
    /// Step 6: fuses the phase with the Gray code, checks their consistency, and gives the
    /// status and quality.
    pub(super) fn judge(
        &mut self,
        m: &Marker,
        calib: &RodCalibration,
        inter: &Intermediate,
        gray: &GrayRead,
        ph: &PhaseFit,
        check: &CodeCheck,
    ) -> RodResult {
        let (frac4, theta) = (check.frac4, check.theta);
        let alpha = gray.alpha;
        let amp_ratio = ph.amp_ratio;
        let (ncc, k) = (inter.loc.ncc, inter.loc.k);
        let edge_std = inter.edges.edge_std_mm;
        let cell = m.cell_mm();
        let steps = m.steps();
        let angle = wrap_2pi(theta * TAU / steps as f64 - calib.enhanced.angle_offset_rad);
        // 6. Consistency and status.
        let code_dist = {
            let d = wrap_steps(theta - (alpha as f64 + 0.5), steps as f64);
            d.min(steps as f64 - d)
        };
        let near_group_edge = !(0.75..=3.25).contains(&frac4);
        let mut status = Status::Ok;
        let mut reason = "";
        if amp_ratio < 0.25 {
            status = Status::Occluded;
            reason = "weak stripes over bit space 0";
        }
        // What lies over bit space 0 must look like its stripes: a wave between the print's
        // black and white, whose fundamental can be no stronger than a square wave's (ratio
        // 1) and explains most of the variation across the rod (8/pi^2 = 0.81 for sharp
        // stripes, more when blurred). A hand's edge, a glare spot or a shadow over part of it
        // can still give a phase, and one that may agree with the Gray code by chance.
        if amp_ratio > MAX_STRIPE_AMP_RATIO {
            status = Status::Occluded;
            reason = "stripes stronger than the print's over bit space 0";
        }
        if ph.share < MIN_STRIPE_SHARE {
            status = Status::Occluded;
            reason = "no stripe pattern over bit space 0";
        }
        if edge_std > 0.2 * cell {
            status = Status::Occluded;
            reason = "barcode edges inconsistent";
        }
        // Every high bit (those above the two the phase refines) must stand clear of the
        // threshold, but for the one that changes where the phase puts the angle at the edge
        // of a group of 4 steps: that one is legitimately half way there (the Gray code
        // changes one bit at a time, so either reading is one step off at most, which the
        // phase then settles). Glare or a shadow over the code leaves several high bits
        // ambiguous at once, and then no reading is trusted.
        let excused = if near_group_edge {
            group_edge_bit(theta, steps)
        } else {
            0
        };
        let min_high_margin = (2..m.bits() as usize)
            .filter(|&k| excused & (1 << k) == 0)
            .map(|k| gray.margins[k])
            .fold(f64::MAX, f64::min);
        if min_high_margin < 0.35 {
            status = Status::Occluded;
            reason = "a high Gray bit is ambiguous";
        }
        // The decoded angle against the whole visible print of every bit space (see
        // `agree`): a reading whose high bits were fooled disagrees with much of some bit
        // space, and the true reading (another group) agrees with the print better; a true
        // one disagrees only by noise, or where the rod's image is off its model (a radius
        // or centre read a little off), and then every other reading is worse still. A
        // reading that disagrees with most of a bit space is refused whatever the others do.
        if check.worst_share > 0.5 * self.code_wrong_share
            && (check.better_reading || check.worst_share > 0.5)
        {
            status = Status::Occluded;
            reason = "Gray code disagrees with the print across the rod";
        }
        if code_dist > 1.5 {
            status = Status::Occluded;
            reason = "Gray code and phase disagree";
        }
        // The evidence against the reading's high bits: this frame's check across the rod,
        // or, when the reading continues the last ok frame's slowly (the check is skipped,
        // see `agree`), that of the check that started it.
        //
        // Where this frame's print has ruled out every other reading of the high bits (each
        // would leave ink seen where its print is paper, see `agree`), the evidence of a
        // wrong code is what is present of the disagreement the likeliest of them would force
        // on the decoded reading, or the paper seen as ink if more: disagreement that light
        // explains (a glint on the print beside the facing line) no longer counts. The
        // geometric bound `code_wrong_share` is what any wrong reading must show; this
        // frame's comparison what each one would show here.
        let frame_share = match check.wrong_evidence {
            Some(e) => check.worst_share.min(e * self.code_wrong_share),
            None => check.worst_share,
        };
        let code_share = if self.continues_slowly(theta, steps as f64) {
            self.reading_code_share.max(frame_share)
        } else {
            frame_share
        };
        // A reading that disagrees with the print as much as the least wrong reading of the
        // high bits would (`code_wrong_share`, from the code's geometry alone) carries the
        // whole evidence of a wrong code: its quality's `q_code` is 0, and it is not `ok`
        // whether or not another reading agrees better.
        if self.code_wrong_share > 0.0 && code_share >= self.code_wrong_share {
            status = Status::Occluded;
            reason = "the print disagrees with the Gray code as much as a wrong reading would";
        }
        let quality = quality(&QualityInputs {
            stripe_share: ph.share,
            amp_ratio,
            edge_std_mm: edge_std,
            edges: inter.edges.edges_used,
            code_share,
            wrong_share: self.code_wrong_share,
            cycles: (steps / 4) as f64,
        });
        if status == Status::Ok {
            self.last_k = Some(k);
            let s = steps as f64;
            self.last_dtheta = match self.last_ok_theta {
                Some(p) => wrap_steps_centred(theta - p, s),
                None => s,
            };
            self.last_ok_theta = Some(theta);
            self.reading_code_share = code_share;
        } else {
            self.last_ok_theta = None;
        }
        RodResult {
            position_mm: inter.edges.position_out_mm,
            angle_rad: angle,
            quality: if status == Status::Ok {
                quality
            } else {
                quality.min(0.3)
            },
            status,
            gray_step: alpha,
            theta_steps: theta,
            ncc,
            reason,
            amp_ratio,
            stripe_share: ph.share,
            edge_std_mm: edge_std,
            code_disagreement: check.worst_share,
        }
    }
}

/// The phase's place inside a group of 4 steps, `[0, 4)`, and the angle fused with the Gray
/// code, `[0, steps)`, both in Gray steps.
pub(super) fn fused_steps(
    m: &Marker,
    calib: &RodCalibration,
    gray: &GrayRead,
    ph: &PhaseFit,
) -> (f64, f64) {
    let sigma = calib.enhanced.phase_sign as f64;
    let frac4 = wrap_steps(
        4.0 * wrap_steps((-sigma * ph.phi) / TAU, 1.0) + calib.enhanced.phase_offset_steps,
        4.0,
    );
    (frac4, fuse_steps(frac4, gray.alpha, m.steps()))
}

/// The Gray code's bit (as a mask) that changes at the edge between groups of 4 steps nearest
/// to `theta` (in steps, `[0, steps)`): the one bit in which the codes of the steps either
/// side of that edge differ.
fn group_edge_bit(theta: f64, steps: u32) -> u32 {
    let group = wrap_step(i64::from((theta / 4.0).round() as u32 * 4), steps);
    let before = wrap_step(i64::from(group) - 1, steps);
    (group ^ (group >> 1)) ^ (before ^ (before >> 1))
}

/// Fuses a phase fraction `frac4` in `[0, 4)` (position inside a group of 4 Gray steps) with
/// the decoded step `alpha`, by the paper's steps 2-4. Returns `[0, steps)`.
pub fn fuse_steps(frac4: f64, alpha: u32, steps: u32) -> f64 {
    let alpha_p = (alpha & !3) as f64;
    let d = frac4 + alpha_p - alpha as f64;
    let j = (-d / 4.0).round();
    wrap_steps(frac4 + alpha_p + 4.0 * j, steps as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::marker::gray_decode;

    /// At every edge between groups of 4 steps, from either side, the excused bit is a single
    /// high bit (the two low bits are the phase's), and reading it the other way decodes the
    /// step on the other side of the edge: one step off, never a group.
    #[test]
    fn the_group_edge_bit_is_the_one_high_bit_that_changes_there() {
        for bits in [3u32, 5, 6] {
            let steps = 1u32 << bits;
            for g in 0..steps / 4 {
                let edge = 4 * g;
                for theta in [
                    edge as f64 + 0.3,
                    (edge as f64 - 0.3).rem_euclid(steps as f64),
                ] {
                    let mask = group_edge_bit(theta, steps);
                    assert_eq!(mask.count_ones(), 1, "bits {bits} edge {edge}");
                    assert!(mask >= 4, "a high bit: {mask:#b} at edge {edge}");
                    let code = edge ^ (edge >> 1);
                    assert_eq!(gray_decode(code ^ mask), (edge + steps - 1) % steps);
                }
            }
        }
    }
}
