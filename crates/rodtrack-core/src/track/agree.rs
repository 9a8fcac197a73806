//! The decoded angle held against the whole visible print of the Gray code: a cross-check of
//! step 4 (which reads each bit at one place, the facing line) over every bit space.
//!
//! Around the rod, bit space `k` is a pattern of ink and paper fixed by the code: at print
//! coordinate `x` (in Gray steps) it is ink where bit `k` of `gray(floor(x))` is 1. The
//! camera sees about +/-70 degrees of it across the rod. Once the angle is decoded (the Gray
//! code's high bits with the phase's fine position), every sample across every bit space has
//! an expected colour. A true reading agrees with the print everywhere but at the pattern's
//! edges (blur). A reading whose high bits were fooled (a lamp's reflection on the code, a
//! shadow, a finger) gives an angle whose expected pattern is the print shifted by at least one
//! group of 4 steps, and that disagrees with what the camera sees over a large share of the
//! samples of some bit space: see [`min_wrong_share`], which bounds that share from the code's
//! geometry alone. What lies over the code and is not print (glare brighter than the paper,
//! or a blob that turns ink to paper) disagrees too. Either way the reading is not trusted.

use super::judge::fused_steps;
use super::state::{EnhancedState, GrayRead, Intermediate, PhaseFit};
use super::tuning::{
    CODE_CHECK_EDGE_STEPS, CODE_CHECK_EVERY, CODE_CHECK_MAX_DELTA_DEG, CODE_CHECK_SLOW_STEPS,
};
use crate::angle::{step_index, wrap_steps_centred};
use crate::calib::RodCalibration;
use crate::frame::FrameView;
use crate::marker::{gray, Marker};
use std::f64::consts::TAU;

/// The angle decoded (the phase fused with the Gray code) and how the print across the rod
/// agrees with it.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct CodeCheck {
    /// The phase's place inside a group of 4 steps, `[0, 4)`.
    pub(super) frac4: f64,
    /// The fused angle at the facing line, Gray steps, `[0, steps)`.
    pub(super) theta: f64,
    /// Over the bit spaces, the largest share of checked samples whose colour is not the one
    /// the decoded angle expects (0 when none could be checked).
    pub(super) worst_share: f64,
    /// Whether another reading of the high bits (the angle shifted by whole groups of 4
    /// steps) agrees with the print across the rod better than the decoded one.
    pub(super) better_reading: bool,
    /// Set when this frame's print rules out every other reading of the high bits (see
    /// [`EnhancedState::code_check`]): the evidence left against the decoded reading, as a
    /// share of the whole (`code_wrong_share`): the larger of the share present of the
    /// disagreement the likeliest other reading would force on it (each reading taken in the
    /// bit space where least of it is present), and the paper seen as ink, which no light
    /// explains. `None` when the other readings were not compared or one of them is not
    /// ruled out.
    pub(super) wrong_evidence: Option<f64>,
}

/// The most groups of 4 Gray steps a code is checked over (a 8-bit code).
const MAX_GROUPS: usize = 64;

/// The check's counts across the rod, for the decoded reading and, when compared, every
/// reading of the high bits (see [`EnhancedState::code_check`]).
struct Tally {
    /// The decoded reading's share of disagreeing samples, worst bit space.
    worst: f64,
    /// The decoded reading's share of samples where it expects paper and ink is seen (what
    /// no light explains), worst bit space.
    dark: f64,
    /// Per reading (group shift): checked samples and disagreeing ones, over all bit spaces.
    group_n: [u32; MAX_GROUPS],
    group_wrong: [u32; MAX_GROUPS],
    /// Per other reading: the least share, over its bit spaces, of the disagreement it would
    /// force on the decoded reading were it the true one that is present.
    evidence: [f64; MAX_GROUPS],
    /// Per other reading: whether some bit space shows ink where its print is paper on at
    /// least `code_wrong_share` of its samples.
    ruled_out: [bool; MAX_GROUPS],
}

impl EnhancedState {
    /// Whether the angle `theta` (Gray steps of a `steps`-step code) continues the last ok
    /// frame's slowly: the rod turned less than [`CODE_CHECK_SLOW_STEPS`] since then, and
    /// did so at the frame before too.
    pub(super) fn continues_slowly(&self, theta: f64, steps: f64) -> bool {
        self.last_ok_theta.is_some_and(|prev| {
            wrap_steps_centred(theta - prev, steps).abs() < CODE_CHECK_SLOW_STEPS
                && self.last_dtheta.abs() < CODE_CHECK_SLOW_STEPS
        })
    }

    /// Fuses the phase with the Gray code and checks the angle against the print across the
    /// rod over every bit space.
    pub(super) fn code_check(
        &self,
        m: &Marker,
        calib: &RodCalibration,
        frame: &FrameView,
        inter: &Intermediate,
        gray_read: &GrayRead,
        ph: &PhaseFit,
    ) -> CodeCheck {
        let (frac4, theta) = fused_steps(m, calib, gray_read, ph);
        // Temporal consistency: a rod measured ok at the last frame, turning slowly then and
        // now, cannot have had its high bits fooled (that jumps a group of 4 steps at once,
        // which only an acceleration beyond any rod's would hide): nothing to check.
        if self.continues_slowly(theta, m.steps() as f64) {
            return CodeCheck {
                frac4,
                theta,
                worst_share: 0.0,
                better_reading: false,
                wrong_evidence: None,
            };
        }
        // The print coordinate grows with the sample angle across the rod as the phase does.
        let sign = calib.enhanced.phase_sign as f64;
        let reference_position_mm = calib.reference_position_mm;
        let position = inter.edges.position_mm;
        let ca = self.centre_at(m, reference_position_mm, position);
        let steps = m.steps();
        let steps_f = steps as f64;
        let to_steps = sign * steps_f / TAU;
        let min_span = 0.2 * (inter.loc.white - inter.loc.black);
        let surface = &self.eps_angles[self.eps_best];
        let ink = |k: u32, x: f64| (gray(step_index(x, steps)) >> k) & 1 == 1;
        // Every reading of the high bits that keeps the phase's place in its group: the
        // decoded one (group shift 0) and the others, each shifted by whole groups of 4 steps.
        // Over all bit spaces, the share of checked samples each disagrees with.
        // `groups` readings counted: the decoded one alone, or every one.
        //
        // When every reading is counted, also the evidence for and against each other
        // reading `g` being the true one. Where the decoded reading expects ink and `g`'s
        // print is paper, the camera must see paper (or glare: light cannot turn paper into
        // ink) if `g` is true, and the decoded reading then disagrees there: `forced`. Of
        // those samples, the ones where the decoded reading's ink is not seen are `present`;
        // the others show ink where `g` has paper, which no light explains. A bit space where
        // those are at least `code_wrong_share` of its samples (the least share of evidence
        // the code's geometry guarantees against any wrong reading) rules `g` out, as that
        // share of evidence rules out the decoded reading.
        let tally = |groups: usize| {
            let mut t = Tally {
                worst: 0.0,
                dark: 0.0,
                group_n: [0; MAX_GROUPS],
                group_wrong: [0; MAX_GROUPS],
                evidence: [1.0; MAX_GROUPS],
                ruled_out: [false; MAX_GROUPS],
            };
            // Bit space 0 repeats every group of 4 steps: it tells no group from another (and the
            // phase's fit already holds it to the stripes).
            for k in 1..m.bits() {
                let lp = self.knots.at(position + m.bit_space_centre_mm(k));
                let (e, rad) = (ca.offset_px, lp.radius_px * ca.radius_ratio);
                let off = gray_read.offsets[k as usize];
                let (mut n, mut wrong, mut dark) = (0u32, 0u32, 0u32);
                // Per other reading: the decoded reading's checked samples where it expects
                // ink and that reading's print is paper.
                let mut forced = [0u32; MAX_GROUPS];
                // Of those, the ones where the decoded reading's ink is not seen.
                let mut present = [0u32; MAX_GROUPS];
                for j in (0..self.phase_delta.len()).step_by(CODE_CHECK_EVERY) {
                    if self.phase_delta[j].0.abs() > CODE_CHECK_MAX_DELTA_DEG.to_radians() {
                        continue;
                    }
                    let (px, py) = lp.offset(0.0, e + rad * self.phase_delta[j].2);
                    if !frame.contains(px as f32, py as f32, 1.0) {
                        continue;
                    }
                    let v = frame.luma_bilinear(px as f32, py as f32) as f64;
                    let span = (self.white[j] - self.black[j]).max(min_span);
                    let r = (v - self.black[j]) / span - off;
                    // The decoded reading's ink here, clear of an edge, and whether it is not
                    // seen (needed only when the other readings are compared).
                    let (decoded_ink, decoded_wrong) = if groups > 1 {
                        let x0 = theta + to_steps * surface[j];
                        let i = ink(k, x0)
                            && ink(k, x0 - CODE_CHECK_EDGE_STEPS)
                            && ink(k, x0 + CODE_CHECK_EDGE_STEPS);
                        (i, i && r >= 0.5)
                    } else {
                        (false, false)
                    };
                    for (g, (gn, gw)) in t
                        .group_n
                        .iter_mut()
                        .zip(t.group_wrong.iter_mut())
                        .take(groups)
                        .enumerate()
                    {
                        // The print coordinate this sample sees under this reading, and the
                        // expected colour there: skip samples near an edge of the pattern (blur,
                        // the angle's own error).
                        let x = theta + 4.0 * g as f64 + to_steps * surface[j];
                        let expect = ink(k, x);
                        if ink(k, x - CODE_CHECK_EDGE_STEPS) != expect
                            || ink(k, x + CODE_CHECK_EDGE_STEPS) != expect
                        {
                            continue;
                        }
                        // Ink reads below the middle between the print's black and white, paper
                        // above it and not brighter than paper by half the contrast.
                        let agrees = if expect {
                            r < 0.5
                        } else {
                            (0.5..1.5).contains(&r)
                        };
                        *gn += 1;
                        *gw += (!agrees) as u32;
                        if g > 0 && decoded_ink && !expect {
                            forced[g] += 1;
                            present[g] += decoded_wrong as u32;
                        }
                        if g == 0 {
                            n += 1;
                            wrong += (!agrees) as u32;
                            dark += (!expect && r < 0.5) as u32;
                        }
                    }
                }
                if n > 0 {
                    t.worst = t.worst.max(wrong as f64 / n as f64);
                    t.dark = t.dark.max(dark as f64 / n as f64);
                    for g in 1..groups {
                        let (f, p) = (forced[g], present[g]);
                        if f > 0 {
                            t.evidence[g] = t.evidence[g].min(p as f64 / f as f64);
                            t.ruled_out[g] |= (f - p) as f64 >= self.code_wrong_share * n as f64;
                        }
                    }
                }
            }
            t
        };
        // The decoded reading first; the others only when it disagrees with the print beyond
        // what noise makes of a true reading (and not with most of it, refused anyway).
        let mut t = tally(1);
        let mut groups = 1;
        let mut wrong_evidence = None;
        if t.worst > 0.5 * self.code_wrong_share && t.worst <= 0.5 {
            groups = ((steps / 4) as usize).clamp(1, MAX_GROUPS);
            t = tally(groups);
            if groups > 1 && t.ruled_out[1..groups].iter().all(|&r| r) {
                let likeliest = t.evidence[1..groups].iter().copied().fold(0.0, f64::max);
                // What no light explains stays evidence against the reading: paper seen as
                // ink (a hand, a shadow), as a share of the bound.
                wrong_evidence = Some(likeliest.max(t.dark / self.code_wrong_share));
            }
        }
        let share = |g: usize| t.group_wrong[g] as f64 / t.group_n[g].max(1) as f64;
        let decoded = share(0);
        let better_reading = (1..groups).any(|g| t.group_n[g] > 0 && share(g) < decoded);
        CodeCheck {
            frac4,
            theta,
            worst_share: t.worst,
            better_reading,
            wrong_evidence,
        }
    }
}

/// Over every angle and every wrong reading of the high bits (the angle shifted by a whole
/// number of groups of 4 steps, as when the high bits are misread and the phase keeps the
/// position inside the group), the least share of the checked samples of the worst bit space
/// where the reading expects ink and the print is paper (what no added light can hide: glare
/// turns ink into paper, never paper into ink), for a code of `bits` bits whose samples see
/// the surface at `angles_rad` from the facing line, skipping those within `edge_steps` of an
/// edge of the pattern. The judge refuses a reading whose worst
/// share exceeds half of this.
pub fn min_wrong_share(bits: u32, angles_rad: &[f64], edge_steps: f64) -> f64 {
    let steps = 1u32 << bits;
    let steps_f = steps as f64;
    let ink = |k: u32, x: f64| (gray(step_index(x, steps)) >> k) & 1 == 1;
    let mut least = 1.0f64;
    for a in 0..(steps * 16) {
        let theta = a as f64 / 16.0;
        for g in 1..steps / 4 {
            let wrong_theta = theta + 4.0 * g as f64;
            let mut worst = 0.0f64;
            for k in 0..bits {
                let (mut n, mut wrong) = (0u32, 0u32);
                for &d in angles_rad {
                    let x = wrong_theta + d * steps_f / TAU;
                    let expect = ink(k, x);
                    if ink(k, x - edge_steps) != expect || ink(k, x + edge_steps) != expect {
                        continue;
                    }
                    n += 1;
                    // Expected ink where the print is paper: added light (glare) cannot hide
                    // that (it can make ink read as paper, never paper as ink).
                    wrong += (expect && !ink(k, theta + d * steps_f / TAU)) as u32;
                }
                if n > 0 {
                    worst = worst.max(wrong as f64 / n as f64);
                }
            }
            least = least.min(worst);
        }
    }
    least
}

/// [`min_wrong_share`] remembered per code layout (bits, sample angles, edge margin): it
/// depends on nothing else, and calibration and every new tracker ask for the same few
/// layouts again and again (a few ms each).
pub(super) fn min_wrong_share_cached(bits: u32, angles_rad: &[f64], edge_steps: f64) -> f64 {
    type Key = (u32, Vec<u64>, u64);
    static CACHE: std::sync::Mutex<Vec<(Key, f64)>> = std::sync::Mutex::new(Vec::new());
    let key: Key = (
        bits,
        angles_rad.iter().map(|a| a.to_bits()).collect(),
        edge_steps.to_bits(),
    );
    if let Ok(cache) = CACHE.lock() {
        if let Some((_, v)) = cache.iter().find(|(k, _)| *k == key) {
            return *v;
        }
    }
    let v = min_wrong_share(bits, angles_rad, edge_steps);
    if let Ok(mut cache) = CACHE.lock() {
        // A handful of layouts in practice; bounded all the same.
        if cache.len() >= 64 {
            cache.remove(0);
        }
        cache.push((key, v));
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Marker v1 seen over +/-67.5 degrees with 24 samples: a reading a group or more off
    /// disagrees with the print over a large share of some bit space even under glare, far
    /// above what noise makes of a true one.
    #[test]
    fn the_cached_share_is_the_computed_one() {
        for n in [16usize, 24] {
            let angles: Vec<f64> = (0..n)
                .map(|j| (-60.0 + 120.0 * (j as f64 + 0.5) / n as f64).to_radians())
                .collect();
            let direct = min_wrong_share(5, &angles, 0.5);
            assert_eq!(min_wrong_share_cached(5, &angles, 0.5), direct);
            assert_eq!(min_wrong_share_cached(5, &angles, 0.5), direct);
            assert_eq!(
                min_wrong_share_cached(4, &angles, 0.5),
                min_wrong_share(4, &angles, 0.5)
            );
        }
    }

    #[test]
    fn a_wrong_group_disagrees_with_much_of_some_bit_space() {
        let angles: Vec<f64> = (0..24)
            .map(|j| (-67.5 + 135.0 * (j as f64 + 0.5) / 24.0).to_radians())
            .collect();
        let share = min_wrong_share(5, &angles, 0.5);
        assert!(share >= 0.12, "least share {share}");
        eprintln!("marker v1: least share {share:.3}");
    }
}
