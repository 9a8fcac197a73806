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
//! down by a quarter (see `docs/accuracy.md`).

use super::agree::CodeCheck;
use super::state::{EnhancedState, GrayRead, Intermediate};
use super::tuning::{PHASE_ROWS, REFINE_MAX_STEPS, REFINE_PROFILE};
use crate::angle::wrap_steps;
use crate::calib::RodCalibration;
use crate::frame::FrameView;
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
        let steps_f = m.steps() as f64;
        let theta = check.theta;
        let to_steps = calib.enhanced.phase_sign as f64 * steps_f / TAU;
        let position = inter.edges.position_mm;
        let ca = self.centre_at(m, calib.reference_position_mm, position);
        let min_span = 0.2 * (inter.loc.white - inter.loc.black);
        // The surface angle (from the facing line) where the decoded angle puts the print's
        // edge at coordinate `x` (steps), the instance of it nearest the facing line.
        let angle_of = |x: f64| {
            let near = x + steps_f * ((theta - x) / steps_f).round();
            (near - theta) / to_steps
        };
        // An edge's weight: its position's inverse variance (noise over the print's contrast
        // times the edge's foreshortening).
        let weight = |d: f64| {
            let (w, b) = self.shading_at(d);
            let c = (w - b).max(min_span) * d.cos();
            c * c
        };
        // Bit space 0's edges in the phase's window: what the phase is worth against them.
        let mut w0 = 0.0f64;
        for &(x, k, _) in &self.print_edges {
            if k == 0 {
                let d = angle_of(x);
                if d.abs() <= self.phase_half_rad {
                    w0 += weight(d);
                }
            }
        }
        // The edges whose profile stays inside the shading's range.
        let (half_o, n_prof) = (REFINE_PROFILE.0, REFINE_PROFILE.1.min(MAX_PROFILE));
        let d_max = self.phase_half_rad - half_o * TAU / steps_f;
        let o_step = 2.0 * half_o / (n_prof - 1) as f64;
        let d_step = o_step / to_steps;
        let (sin_step, cos_step) = d_step.sin_cos();
        let inv_rows = 1.0 / PHASE_ROWS.len() as f64;
        let mut prof = [0.0f64; MAX_PROFILE];
        let (mut sw, mut swd) = (0.0f64, 0.0f64);
        let mut rows_of = u32::MAX;
        // Per row over the bit space: the line's point (the learnt offset applied) and the step
        // across per knot radius, px.
        let mut rows = [(0.0f32, 0.0f32, 0.0f32, 0.0f32); PHASE_ROWS.len()];
        let mut off = 0.0f64;
        for &(x_e, k, ink_before) in &self.print_edges {
            if k == 0 {
                continue;
            }
            let d_e = angle_of(x_e);
            if d_e.abs() > d_max {
                continue;
            }
            if rows_of != k {
                rows_of = k;
                off = gray_read.offsets[k as usize];
                for (row, r) in rows.iter_mut().zip(PHASE_ROWS) {
                    let lp = self
                        .knots
                        .at(position + m.bit_space_centre_mm(k) + r * m.bit_space_mm());
                    let (x0, y0) = lp.offset(0.0, ca.offset_px);
                    let rad = lp.radius_px * ca.radius_ratio;
                    *row = (
                        x0 as f32,
                        y0 as f32,
                        (-lp.ty * rad) as f32,
                        (lp.tx * rad) as f32,
                    );
                }
            }
            // The profile across the edge against the middle between the print's black and
            // white there (the light's offset at this bit space included): negative on ink,
            // positive on paper. The samples' surface angles step by `o_step` steps, their
            // sines and cosines by the angle-addition rule (no trigonometry per sample); a
            // profile whose ends are in the frame is in it.
            let d0 = d_e - half_o / to_steps;
            let (mut sin_d, mut cos_d) = d0.sin_cos();
            let mut inside = true;
            for (i, p) in prof.iter_mut().enumerate().take(n_prof) {
                let a = self.across_of_surface(sin_d, cos_d) as f32;
                let end = i == 0 || i + 1 == n_prof;
                let mut acc = 0.0f32;
                for &(x0, y0, sx, sy) in &rows {
                    let (px, py) = (x0 + sx * a, y0 + sy * a);
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
            // The crossing of the middle nearest the expected edge, in the print's direction
            // (from ink to paper if ink comes first).
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
            let w = weight(d_e + o / to_steps);
            sw += w;
            swd -= w * o;
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

/// The most samples of a profile across an edge.
const MAX_PROFILE: usize = 8;

/// The edges of a code's print around the rod: `(print coordinate in Gray steps, bit space,
/// ink before the edge)`, by bit space then coordinate (an edge of bit space `k` at `x` is
/// where bit `k` of `gray(x - 1)` and of `gray(x)` differ).
pub(super) fn print_edges(bits: u32) -> Vec<(f64, u32, bool)> {
    let steps = 1u32 << bits;
    let mut out = Vec::new();
    for k in 0..bits {
        for x in 0..steps {
            let before = (gray((x + steps - 1) % steps) >> k) & 1 == 1;
            let after = (gray(x) >> k) & 1 == 1;
            if before != after {
                out.push((x as f64, k, before));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::print_edges;

    /// Marker v1: bit space 0 holds 8 black and 8 white stripes (16 edges), each next one half
    /// as many, bit spaces 3 and 4 one black and one white half each.
    #[test]
    fn the_print_has_the_specs_edges() {
        let e = print_edges(5);
        let count = |k: u32| e.iter().filter(|x| x.1 == k).count();
        assert_eq!((0..5).map(count).collect::<Vec<_>>(), vec![16, 8, 4, 2, 2]);
        // Every Gray step boundary is an edge of exactly one bit space.
        let mut xs: Vec<f64> = e.iter().map(|x| x.0).collect();
        xs.sort_by(f64::total_cmp);
        xs.dedup();
        assert_eq!(xs.len(), 32);
        // Edges alternate ink -> paper and paper -> ink within a bit space.
        for k in 0..5 {
            let inks: Vec<bool> = e.iter().filter(|x| x.1 == k).map(|x| x.2).collect();
            assert!(inks.windows(2).all(|w| w[0] != w[1]), "bit space {k}");
        }
    }
}
