//! Step 5b: the fused angle refined by the edges of the Gray code's other bit spaces.
//!
//! The phase reads the angle from bit space 0's stripes alone: about 6 edges of the print
//! across the visible half of the rod. Each edge's image position carries an error that
//! depends on where it falls on the pixel grid (a sensor samples the image, it does not see
//! it whole: aliasing, a fill factor below 1, a renderer's few rays per pixel); 6 edges
//! average it little, and then the angle errs by a few mrad from pose to pose, the same at
//! every frame of a pose. Bit spaces 1 and up hold as many edges again (3, 1.5, 0.75, 0.75 in
//! the same window for marker v1), each as sensitive to the angle as one of bit space 0 (an
//! edge at surface angle `d` moves by `R cos d` per radian whatever its bit), at other places
//! on the pixel grid. Once the angle is decoded, where each of them must be is known: each
//! is located in a short profile across it (its crossing of the middle between the print's
//! black and white, as the shading measured them), and the angle moves by the weighted mean
//! of how far they sit from where the decoded angle puts them, weighed against bit space 0's
//! own edges. On the independent validation table the angle's scatter from pose to pose goes
//! down by a fifth (see `docs/accuracy.md`).

use super::agree::CodeCheck;
use super::state::{EnhancedState, GrayRead, Intermediate};
use super::tuning::{PHASE_ROWS, REFINE_MAX_STEPS, REFINE_PROFILE};
use crate::angle::wrap_steps;
use crate::calib::RodCalibration;
use crate::frame::FrameView;
use crate::line::LinePoint;
use crate::marker::{gray, Marker};
use std::f64::consts::TAU;

impl EnhancedState {
    /// Where across the rod (in knot radii) the surface line at angle `t` from the facing one
    /// is seen, from `t`'s sine and cosine: through the rod's own perspective with the lens'
    /// radius, else on the learnt radius correction's scale (the inverse of the phase's sample
    /// tables).
    fn across_of_surface(&self, sin_t: f64, cos_t: f64) -> f64 {
        match self.lens_rho {
            Some((rho, scale)) => scale * sin_t / (1.0 - rho * cos_t),
            None => (1.0 + self.eps_values[self.eps_best]) * sin_t,
        }
    }

    /// The shading's white and black at surface angle `d` (linear between the phase samples'
    /// angles; clamped to their range).
    #[inline]
    fn shading_at(&self, d: f64) -> (f64, f64) {
        let n = self.white.len();
        if n == 0 {
            return (1.0, 0.0);
        }
        let f = ((d + self.phase_half_rad) * self.phase_per_rad - 0.5).clamp(0.0, (n - 1) as f64);
        let j = (f as usize).min(n.saturating_sub(2));
        let t = (f - j as f64).clamp(0.0, 1.0);
        let j1 = (j + 1).min(n - 1);
        (
            self.white[j] + t * (self.white[j1] - self.white[j]),
            self.black[j] + t * (self.black[j1] - self.black[j]),
        )
    }

    /// Step 5b: `check.theta` moved by the edges of bit spaces 1 and up (see the module's
    /// documentation); unchanged when none is found where the decoded angle puts one.
    pub(super) fn refine(
        &self,
        m: &Marker,
        calib: &RodCalibration,
        frame: &FrameView,
        inter: &Intermediate,
        gray_read: &GrayRead,
        check: CodeCheck,
    ) -> CodeCheck {
        let steps = m.steps();
        let steps_f = steps as f64;
        let theta = check.theta;
        let to_steps = calib.enhanced.phase_sign as f64 * steps_f / TAU;
        let step_rad = TAU / steps_f;
        let position = inter.edges.position_mm;
        let ca = self.centre_at(m, calib.reference_position_mm, position);
        let min_span = 0.2 * (inter.loc.white - inter.loc.black);
        // Whether bit space `k` is ink over Gray step `n` (wrapped): before edge `e` is step
        // `e - 1`, after it step `e`.
        let ink = |k: u32, n: i64| (gray(n.rem_euclid(i64::from(steps)) as u32) >> k) & 1 == 1;
        // An edge's weight: its position's inverse variance (noise over the print's contrast
        // times the edge's foreshortening).
        let weight = |d: f64| {
            let (w, b) = self.shading_at(d);
            let c = (w - b).max(min_span) * d.cos();
            c * c
        };
        // The print coordinates (steps) of the edges whose profile stays inside the shading's
        // range, from the decoded angle.
        let d_max = self.phase_half_rad - REFINE_PROFILE.0 * step_rad;
        let (x_a, x_b) = (theta - to_steps * d_max, theta + to_steps * d_max);
        let (x_lo, x_hi) = (x_a.min(x_b).ceil() as i64, x_a.max(x_b).floor() as i64);
        // Bit space 0's edges in the phase's window: what the phase is worth against them.
        let mut w0 = 0.0f64;
        let (y_a, y_b) = (
            theta - to_steps * self.phase_half_rad,
            theta + to_steps * self.phase_half_rad,
        );
        for e in y_a.min(y_b).ceil() as i64..=y_a.max(y_b).floor() as i64 {
            if ink(0, e - 1) != ink(0, e) {
                w0 += weight((e as f64 - theta) / to_steps);
            }
        }
        let (half_o, n_prof) = (REFINE_PROFILE.0, REFINE_PROFILE.1);
        let o_step = 2.0 * half_o / (n_prof - 1) as f64;
        let d_step = o_step / to_steps;
        let (sin_step, cos_step) = d_step.sin_cos();
        let (e_px, ratio) = (ca.offset_px, ca.radius_ratio);
        let mut prof = [0.0f64; 16];
        let inv_rows = 1.0 / PHASE_ROWS.len() as f64;
        let n_prof = n_prof.min(prof.len());
        let (mut sw, mut swd) = (0.0f64, 0.0f64);
        for k in 1..m.bits() {
            let lps: [LinePoint; PHASE_ROWS.len()] = std::array::from_fn(|i| {
                self.knots
                    .at(position + m.bit_space_centre_mm(k) + PHASE_ROWS[i] * m.bit_space_mm())
            });
            let off = gray_read.offsets[k as usize];
            for e in x_lo..=x_hi {
                let x_e = e as f64;
                let ink_before = ink(k, e - 1);
                if ink_before == ink(k, e) {
                    continue;
                }
                // The profile across the edge against the middle between the print's black
                // and white there (the light's offset at this bit space included): negative
                // on ink, positive on paper. The samples' surface angles step by `o_step`
                // steps, their sines and cosines by the angle-addition rule (no trigonometry
                // per sample); a profile whose ends are in the frame is in it.
                let d0 = (x_e - half_o - theta) / to_steps;
                let (mut sin_d, mut cos_d) = d0.sin_cos();
                let mut inside = true;
                for (i, p) in prof.iter_mut().enumerate().take(n_prof) {
                    let a = self.across_of_surface(sin_d, cos_d);
                    let end = i == 0 || i + 1 == n_prof;
                    let mut acc = 0.0f32;
                    for lp in &lps {
                        let (px, py) = lp.offset(0.0, e_px + lp.radius_px * ratio * a);
                        let (px, py) = (px as f32, py as f32);
                        if end {
                            inside &= frame.contains(px, py, 1.0);
                        }
                        acc += frame.luma_bilinear(px, py);
                    }
                    let (w, b) = self.shading_at(d0 + i as f64 * d_step);
                    *p = acc as f64 * inv_rows - b - (0.5 + off) * (w - b).max(min_span);
                    (sin_d, cos_d) = (
                        sin_d * cos_step + cos_d * sin_step,
                        cos_d * cos_step - sin_d * sin_step,
                    );
                }
                if !inside {
                    continue;
                }
                // The crossing of the middle nearest the expected edge, in the print's
                // direction (from ink to paper if ink comes first).
                let mut best: Option<f64> = None;
                for i in 0..n_prof - 1 {
                    let (a, b) = (prof[i], prof[i + 1]);
                    let crosses = if ink_before {
                        a < 0.0 && b >= 0.0
                    } else {
                        a >= 0.0 && b < 0.0
                    };
                    if !crosses {
                        continue;
                    }
                    let o = -half_o + (i as f64 + a / (a - b)) * o_step;
                    if best.is_none_or(|bo| o.abs() < bo.abs()) {
                        best = Some(o);
                    }
                }
                let Some(o) = best else { continue };
                // The edge sits at print coordinate `x_e`, seen where the decoded angle puts
                // `x_e + o`: the angle is `o` steps too far.
                if o.abs() > REFINE_MAX_STEPS {
                    continue;
                }
                let w = weight((x_e + o - theta) / to_steps);
                sw += w;
                swd -= w * o;
            }
        }
        if sw <= 0.0 || !(swd / sw).is_finite() {
            return check;
        }
        let shift = swd / (sw + w0);
        CodeCheck {
            theta: wrap_steps(theta + shift, steps_f),
            ..check
        }
    }
}
