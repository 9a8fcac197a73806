//! Reading the frame for a fit: the colour's position between the field's and the ball's at
//! any point (bilinear between quads, through the detector's memo), the memo's blocks and
//! discs that are surely the ball's colour, and the field's colour at a point.

use super::BallDetector;
use crate::ball::memo::{bilinear, Block, SURE_INSIDE};
use crate::FrameView;

impl BallDetector {
    /// The colour's position between field (0) and ball (1), bilinear between quad centres.
    pub(super) fn alpha_at(&mut self, view: &FrameView, x_q: f64, y_q: f64) -> Option<f32> {
        let (ix, iy) = self.base_quad(x_q, y_q)?;
        let (fx, fy) = ((x_q - ix as f64) as f32, (y_q - iy as f64) as f32);
        let [a00, a10, a01, a11] = match self.alpha.block(ix, iy) {
            Some(c) => {
                let w = self.alpha.w;
                [
                    self.memo_alpha(view, c),
                    self.memo_alpha(view, c + 1),
                    self.memo_alpha(view, c + w),
                    self.memo_alpha(view, c + w + 1),
                ]
            }
            None => {
                let mut a = |x: usize, y: usize| match self.alpha.cell(x, y) {
                    Some(c) => self.memo_alpha(view, c),
                    None => self.colours.alpha(self.layout.rgb(view, x, y)),
                };
                [a(ix, iy), a(ix + 1, iy), a(ix, iy + 1), a(ix + 1, iy + 1)]
            }
        };
        Some(bilinear([a00, a10, a01, a11], fx, fy))
    }

    /// The quad `(floor x_q, floor y_q)` of a bilinear sample at `(x_q, y_q)`, when the sample's
    /// four quads are in the image.
    #[inline(always)]
    pub(super) fn base_quad(&self, x_q: f64, y_q: f64) -> Option<(usize, usize)> {
        if x_q < 0.0 || y_q < 0.0 {
            return None;
        }
        // Not negative: the integer part is the floor.
        let (ix, iy) = (x_q as i64 as usize, y_q as i64 as usize);
        (ix < self.qw.saturating_sub(1) && iy < self.qh.saturating_sub(1)).then_some((ix, iy))
    }

    /// The block of quads from `(floor x_q, floor y_q)` to the next ones, `[x0, y0, x1, y1)`
    /// in quads, when the memo covers it, with its four quads' colour positions (`[x0 y0, x1
    /// y0, x0 y1, x1 y1]`, those [`BallDetector::alpha_at`] interpolates between for a sample
    /// in the block) and whether they are all surely the ball's colour (each at least
    /// [`SURE_INSIDE`]: every bilinear sample in it is then at least 0.5, and none off the
    /// colours' axis). `None` where [`BallDetector::alpha_at`] gives `None` or the memo does
    /// not reach.
    #[inline]
    pub(super) fn sure_block(&mut self, view: &FrameView, x_q: f64, y_q: f64) -> Option<Block> {
        let (ix, iy) = self.base_quad(x_q, y_q)?;
        let c = self.alpha.block(ix, iy)?;
        let w = self.alpha.w;
        // Four calls, not an array's `map`: that one is not inlined.
        let corners = [
            self.memo_alpha(view, c),
            self.memo_alpha(view, c + 1),
            self.memo_alpha(view, c + w),
            self.memo_alpha(view, c + w + 1),
        ];
        let (x0, y0) = (ix as f64, iy as f64);
        Some(Block {
            quads: [x0, y0, x0 + 1.0, y0 + 1.0],
            sure: corners[0] >= SURE_INSIDE
                && corners[1] >= SURE_INSIDE
                && corners[2] >= SURE_INSIDE
                && corners[3] >= SURE_INSIDE,
            corners,
        })
    }

    /// The memo's colour position of cell `c`, computed on first use.
    #[inline(always)]
    pub(super) fn memo_alpha(&mut self, view: &FrameView, c: usize) -> f32 {
        let v = self.alpha.cells[c];
        if !v.is_nan() {
            return v;
        }
        let (x, y) = self.alpha.quad(c);
        let v = self.colours.alpha(self.layout.rgb(view, x, y));
        self.alpha.cells[c] = v;
        v
    }

    /// Every memo cell within `radius_q` quads of `(cx_q, cy_q)` holds a colour position of
    /// at least [`SURE_INSIDE`] (surely the ball's colour; a cell not computed yet, or the
    /// disc not wholly in the memo: false). Checks a little more than the disc, never less:
    /// each row as wide as the disc is a quad nearer the centre, rounded outwards.
    pub(super) fn sure_disc(&self, cx_q: f64, cy_q: f64, radius_q: f64) -> bool {
        let m = &self.alpha;
        let y_lo = (cy_q - radius_q).floor() as isize;
        let y_hi = (cy_q + radius_q).ceil() as isize;
        if y_lo < m.y0 || y_hi >= m.y0 + m.h as isize {
            return false;
        }
        (y_lo..=y_hi).all(|y| {
            let dy = (y as f64 - cy_q).abs();
            let half = (radius_q * radius_q - (dy - 1.0).max(0.0).powi(2))
                .max(0.0)
                .sqrt();
            let (x_lo, x_hi) = (
                (cx_q - half).floor() as isize,
                (cx_q + half).ceil() as isize,
            );
            if x_lo < m.x0 || x_hi >= m.x0 + m.w as isize {
                return false;
            }
            let row = (y - m.y0) as usize * m.w;
            let (a, b) = (row + (x_lo - m.x0) as usize, row + (x_hi - m.x0) as usize);
            // NaN (not computed) compares false.
            m.cells[a..=b].iter().all(|&v| v >= SURE_INSIDE)
        })
    }

    /// Fills the memo's cells within `radius_q` quads of `(cx_q, cy_q)` row by row (the quads
    /// nearly every ray reads; the rest stay computed on first use).
    pub(super) fn prefill_alpha(&mut self, view: &FrameView, cx_q: f64, cy_q: f64, radius_q: f64) {
        let m = &mut self.alpha;
        let (qw, qh) = (self.qw as isize, self.qh as isize);
        let y_lo = ((cy_q - radius_q).ceil() as isize).max(m.y0).max(0);
        let y_hi = ((cy_q + radius_q).floor() as isize)
            .min(m.y0 + m.h as isize - 1)
            .min(qh - 1);
        for y in y_lo..=y_hi {
            let dy = y as f64 - cy_q;
            let half = (radius_q * radius_q - dy * dy).max(0.0).sqrt();
            let x_lo = ((cx_q - half).ceil() as isize).max(m.x0).max(0);
            let x_hi = ((cx_q + half).floor() as isize)
                .min(m.x0 + m.w as isize - 1)
                .min(qw - 1);
            if x_hi < x_lo {
                continue;
            }
            let row = (y - m.y0) as usize * m.w;
            let first = row + (x_lo - m.x0) as usize;
            let n = (x_hi - x_lo + 1) as usize;
            let cells = &mut m.cells[first..first + n];
            let colours = &self.colours;
            self.layout
                .for_row(view, y as usize, x_lo as usize, 1, n, |k, rgb| {
                    cells[k] = colours.alpha(rgb);
                });
        }
    }

    pub(super) fn is_field_at(&self, view: &FrameView, x_q: f64, y_q: f64) -> bool {
        let (x, y) = (x_q.round(), y_q.round());
        if x < 0.0 || y < 0.0 || x as usize >= self.qw || y as usize >= self.qh {
            return false;
        }
        self.colours
            .is_field(self.layout.rgb(view, x as usize, y as usize))
    }
}
