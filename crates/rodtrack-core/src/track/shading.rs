//! The shading stage: the print's shading across the rod, from the barcode's white and black
//! runs, measured again only when the marker has moved or enough frames have passed.

use super::state::{EnhancedState, Intermediate};
use super::tuning::{SHADING_REUSE_FRAMES, SHADING_REUSE_MM};
use crate::frame::FrameView;
use crate::marker::Marker;

impl EnhancedState {
    /// Whether the print's shading must be measured with the marker at `position_mm`, or the
    /// last measurement still serves (see [`EnhancedState::shading`]).
    pub(super) fn shading_due(&self, position_mm: f64) -> bool {
        let near = (position_mm - self.shading_at_mm).abs() <= SHADING_REUSE_MM;
        !(near && self.shading_age < SHADING_REUSE_FRAMES)
    }

    /// The shading of white and black print across the rod, from the barcode's runs (into
    /// `white` and `black`, per phase sample). The light is fixed, so while the marker stays
    /// within [`SHADING_REUSE_MM`] of where the shading was last measured (and for at most
    /// [`SHADING_REUSE_FRAMES`] frames), the last measurement is reused, rescaled to this
    /// frame's barcode levels (which follow exposure changes and flicker); `force` measures.
    pub(super) fn shading(
        &mut self,
        m: &Marker,
        reference_position_mm: f64,
        frame: &FrameView,
        inter: &Intermediate,
        force: bool,
    ) {
        let position = inter.edges.position_mm;
        let (lo, span) = (inter.loc.black, inter.loc.white - inter.loc.black);
        if !force && !self.shading_due(position) {
            self.shading_age += 1;
            for (o, r) in self.white.iter_mut().zip(&self.white_rel) {
                *o = lo + r * span;
            }
            for (o, r) in self.black.iter_mut().zip(&self.black_rel) {
                *o = lo + r * span;
            }
            return;
        }
        let ca = self.centre_at(m, reference_position_mm, position);
        for (rows_u, out) in [
            (&self.white_u, &mut self.white),
            (&self.black_u, &mut self.black),
        ] {
            out.iter_mut().for_each(|v| *v = 0.0);
            for &u in rows_u.iter() {
                let lp = self.knots.at(position + u);
                let (e, r) = (ca.offset_px, lp.radius_px * ca.radius_ratio);
                for (o, &(_, _, sin_d)) in out.iter_mut().zip(&self.phase_delta) {
                    let (x, y) = lp.offset(0.0, e + r * sin_d);
                    *o += frame.luma_bilinear(x as f32, y as f32) as f64;
                }
            }
            let inv = 1.0 / rows_u.len().max(1) as f64;
            // Scale, then a 3-tap smoothing (the shading is smooth; this halves its noise).
            let mut prev = out[0] * inv;
            let n = out.len();
            for j in 0..n {
                let cur = out[j] * inv;
                let next = if j + 1 < n { out[j + 1] * inv } else { cur };
                out[j] = (prev + 2.0 * cur + next) * 0.25;
                prev = cur;
            }
        }
        for (r, o) in self.white_rel.iter_mut().zip(&self.white) {
            *r = (o - lo) / span;
        }
        for (r, o) in self.black_rel.iter_mut().zip(&self.black) {
            *r = (o - lo) / span;
        }
        self.shading_at_mm = position;
        self.shading_age = 0;
    }
}
