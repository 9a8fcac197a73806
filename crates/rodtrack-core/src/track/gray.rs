//! Step 4: the Gray bits, read against a threshold that follows the light along the code.

use super::state::{EnhancedState, GrayRead, Intermediate};
use super::tuning::{GRAY_SAMPLES, QUIET_REFERENCE_MIN_MM, QUIET_SAMPLES};
use crate::decode::decode_bits;
use crate::frame::FrameView;
use crate::marker::Marker;

impl EnhancedState {
    /// Step 4: the Gray bits at the centre of each bit space: the decoded step and each bit's
    /// margin.
    ///
    /// Each bit is read on the barcode's scale (its black 0, its white 1, with the print's
    /// shading across the rod) against a threshold that follows the light along the Gray
    /// code: the print may be lit unlike the barcode (a lamp's glare, a light gradient) by an
    /// offset that bit space 0's stripes measure (their mean is 0.5 when lit as the barcode:
    /// half black, half white) and the white quiet zone after the last bit space measures
    /// (1 when lit as the barcode); between them it is interpolated. `stripes_mean` is bit
    /// space 0's mean from the phase step.
    pub(super) fn gray_code(
        &self,
        m: &Marker,
        frame: &FrameView,
        inter: &Intermediate,
        stripes_mean: f64,
    ) -> GrayRead {
        let position = inter.edges.position_mm;
        let bits = m.bits() as usize;
        // The shading at the facing line (the middle of the phase samples).
        let mid = self.white.len() / 2;
        let centre = |v: &[f64]| {
            if v.len() % 2 == 0 {
                0.5 * (v[mid - 1] + v[mid])
            } else {
                v[mid]
            }
        };
        let (white, black) = if self.white.is_empty() {
            (inter.loc.white, inter.loc.black)
        } else {
            (centre(&self.white), centre(&self.black))
        };
        let span = (white - black).max(0.2 * (inter.loc.white - inter.loc.black));
        let read = |u: f64, along_mm: f64, at: &[(f64, f64)]| -> Option<f64> {
            let lp = self.knots.at(position + u);
            if !frame.contains(lp.x as f32, lp.y as f32, 2.0 + 0.5 * lp.radius_px as f32) {
                return None;
            }
            let mut acc = 0.0f32;
            for &(da, dc) in at {
                let (x, y) = lp.offset(da * along_mm * lp.px_per_mm, dc * lp.radius_px);
                acc += frame.luma_bilinear(x as f32, y as f32);
            }
            Some((acc as f64 / at.len() as f64 - black) / span)
        };
        // The light's offset on the barcode's scale: at bit space 0 and at the quiet zone.
        let u0 = m.bit_space_centre_mm(0);
        let off0 = (stripes_mean - 0.5).clamp(-1.0, 1.0);
        let gray_end = m.gray_start_mm() + bits as f64 * m.bit_space_mm();
        let quiet = m.length_mm() - gray_end;
        let uq = gray_end + 0.5 * quiet;
        let offq = if quiet >= QUIET_REFERENCE_MIN_MM {
            read(uq, quiet, &QUIET_SAMPLES).map(|w| (w - 1.0).clamp(-1.0, 1.0))
        } else {
            None
        };
        let mut samples = [0.0f32; 8];
        let mut margins = [0.0f64; 8];
        let mut offsets = [0.0f64; 8];
        for (kb, s) in samples.iter_mut().enumerate().take(bits) {
            let c = m.bit_space_centre_mm(kb as u32);
            let off = match offq {
                Some(oq) => off0 + (oq - off0) * (c - u0) / (uq - u0),
                None => off0,
            };
            offsets[kb] = off;
            // Outside the frame: read as the threshold, an ambiguous bit.
            let v = read(c, m.bit_space_mm(), &GRAY_SAMPLES).map_or(0.5, |v| v - off);
            *s = v as f32;
            margins[kb] = (v - 0.5).abs() / 0.5;
        }
        let (_, alpha) = decode_bits(&samples[..bits], 0.5);
        GrayRead {
            alpha,
            margins,
            offsets,
        }
    }
}
