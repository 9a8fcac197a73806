//! Prefetching: the frame's cache lines that measuring a rod will read, asked for before any
//! rod of the frame is measured.

use super::state::EnhancedState;
use super::tuning::{GRAY_SAMPLES, PHASE_ROWS, QUIET_SAMPLES, SEARCH_WINDOWS_MM};
use crate::frame::FrameView;
use crate::marker::Marker;

impl EnhancedState {
    /// [`super::RodTracker::prefetch`] in the enhanced mode: nothing when the last frame did
    /// not find the marker.
    pub(super) fn prefetch(&self, m: &Marker, frame: &FrameView) -> u8 {
        let st = self;
        let Some(p) = st.predicted_mm else {
            return 0;
        };
        // The Gray and quiet-zone samples' reach across the line (the widest of the strip's
        // reads), and every read's bilinear footprint.
        let gray_across = GRAY_SAMPLES
            .iter()
            .chain(&QUIET_SAMPLES)
            .fold(0.0f64, |a, s| a.max(s.1.abs()));
        let footprint_px = 2.0;
        let mut acc = 0u8;
        let mut touch = |a_mm: f64, b_mm: f64, radii: f64| {
            acc ^= st.touch_strip(frame, p + a_mm, p + b_mm, radii, footprint_px);
        };
        let search_mm = SEARCH_WINDOWS_MM[0] + 1.0;
        touch(
            m.barcode_start_mm() - search_mm,
            m.length_mm() + 1.0,
            gray_across,
        );
        let half0 = PHASE_ROWS.iter().fold(0.0f64, |a, r| a.max(r.abs())) * m.bit_space_mm() + 1.0;
        // The phase's rows over bit space 0, and the refinement's over the others, across the
        // whole rod (the learnt centre and radius move the samples by a fraction of a radius).
        for k in 0..m.bits() {
            let c = m.bit_space_centre_mm(k);
            touch(c - half0, c + half0, 1.1);
        }
        if st.shading_due(p) {
            for &u in st.white_u.iter().chain(&st.black_u) {
                touch(u - 1.0, u + 1.0, 1.1);
            }
        }
        if st.learns_centre(p, st.frames_seen.wrapping_add(1)) {
            for &(u, _) in st.ring_u.iter().filter(|r| st.centre.scans(r.1)) {
                touch(u - 1.0, u + 1.0, 1.5);
            }
        }
        acc
    }

    /// Asks for the frame's cache lines over the stretch `a_mm..b_mm` of the line, `radii`
    /// radii to either side and `footprint_px` beyond all round, in pieces short enough that
    /// each one's bounding box stays close to the strip however the line runs in the image.
    pub(super) fn touch_strip(
        &self,
        frame: &FrameView,
        a_mm: f64,
        b_mm: f64,
        radii: f64,
        footprint_px: f64,
    ) -> u8 {
        let (pa, pb) = (self.knots.at(a_mm), self.knots.at(b_mm));
        // A piece's box holds at most about 8 px of the line's run across the image's minor
        // direction (a line along a row or a column is one piece).
        let minor = (pb.x - pa.x).abs().min((pb.y - pa.y).abs());
        let n = (minor / 8.0).ceil().clamp(1.0, 64.0) as usize;
        let mut acc = 0u8;
        let mut prev = pa;
        for i in 1..=n {
            let next = if i == n {
                pb
            } else {
                self.knots.at(a_mm + (b_mm - a_mm) * i as f64 / n as f64)
            };
            let mid = self
                .knots
                .at(a_mm + (b_mm - a_mm) * (i as f64 - 0.5) / n as f64);
            let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
            for lp in [&prev, &mid, &next] {
                let r = radii * lp.radius_px;
                for side in [-r, r] {
                    let (x, y) = lp.offset(0.0, side);
                    x0 = x0.min(x);
                    x1 = x1.max(x);
                    y0 = y0.min(y);
                    y1 = y1.max(y);
                }
            }
            let f = footprint_px;
            acc ^= frame.touch_rect(x0 - f, y0 - f, x1 + f, y1 + f);
            prev = next;
        }
        acc
    }
}
