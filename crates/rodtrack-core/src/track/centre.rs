//! The centre stage: the rings' silhouettes that feed the learnt centre line, and when a
//! frame adds to it.

use super::learners::Silhouette;
use super::silhouette::{ring_silhouette_measure, BLACK_RING_SCAN, WHITE_RING_SCAN};
use super::state::EnhancedState;
use super::tuning::MAX_RINGS;
use crate::frame::FrameView;

impl EnhancedState {
    /// Whether frame number `frame_no` (counted from 1) with the marker at `position_mm`
    /// adds its rings' silhouettes to the centre line. Once the line is learnt, every 4th
    /// frame, then every 16th, is enough to follow slow changes; but where the marker has not
    /// been yet, the line is extrapolated and every frame adds to it until it is learnt there
    /// too.
    pub(super) fn learns_centre(&self, position_mm: f64, frame_no: u64) -> bool {
        let every = match self.centre.samples() {
            _ if !self.centre.covers(position_mm + self.ring_u_mid) => 1,
            n if n < 60.0 => 1,
            n if n < 600.0 => 4,
            _ => 16,
        };
        frame_no % every == 0
    }

    /// The rod's centre and apparent radius where the marker is: this frame's silhouettes of
    /// the marker's white rings feed the centre line learnt over all frames.
    pub(super) fn learn_centre(&mut self, frame: &FrameView, position_mm: f64) {
        let mut rings = [Silhouette::default(); MAX_RINGS];
        let mut n = 0;
        for (ring, &(u, white)) in self.ring_u.iter().take(MAX_RINGS).enumerate() {
            if !self.centre.scans(white) {
                continue;
            }
            let lp = self.knots.at(position_mm + u);
            let scan = if white {
                &WHITE_RING_SCAN
            } else {
                &BLACK_RING_SCAN
            };
            if let Some(sil) = ring_silhouette_measure(frame, &lp, scan) {
                let (c, hw) = (sil.centre_px, sil.half_width_px);
                rings[n] = Silhouette {
                    ring,
                    white,
                    contrast_dn: sil.contrast_dn,
                    s_mm: position_mm + u,
                    offset_px: c,
                    ratio: hw / lp.radius_px,
                    radius_px: lp.radius_px,
                };
                n += 1;
            }
        }
        self.centre.add_frame(&rings[..n]);
    }
}
