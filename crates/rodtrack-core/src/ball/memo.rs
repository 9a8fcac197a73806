//! The fit's samples of the ball's colour: the quads' colour positions computed once per fit
//! ([`AlphaMemo`]), and the blocks of quads a ray crosses without a sample's value
//! ([`leaves_block`], [`SURE_INSIDE`]).

use super::colour::OFF_AXIS;

/// The quads' colour positions around a blob, each computed at most once per fit.
#[derive(Debug, Clone)]
pub(super) struct AlphaMemo {
    /// Quad of cell 0.
    pub(super) x0: isize,
    pub(super) y0: isize,
    /// Cells per row and rows in use.
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) cells: Vec<f32>,
    /// The largest square's side, cells: the buffer is allocated for it.
    max_side: usize,
}

impl AlphaMemo {
    /// A memo for squares of up to `max_side` cells a side.
    pub(super) fn new(max_side: usize) -> AlphaMemo {
        AlphaMemo {
            x0: 0,
            y0: 0,
            w: 0,
            h: 0,
            cells: Vec::with_capacity(max_side * max_side),
            max_side,
        }
    }

    /// Starts a fit over the square of half size `half_q` quads around `(cx_q, cy_q)`; false
    /// when it is larger than the memo's largest square (then the rays compute every sample).
    /// The buffer's size is the memo's own, not its capacity: a clone of the detector (whose
    /// buffer has only the length it had) grows it once and keeps the fast path.
    pub(super) fn start(&mut self, cx_q: f64, cy_q: f64, half_q: f64) -> bool {
        let n = (2.0 * half_q).ceil() as usize + 3;
        if !(half_q.is_finite() && n <= self.max_side) {
            self.w = 0;
            self.h = 0;
            return false;
        }
        self.x0 = (cx_q - half_q).floor() as isize - 1;
        self.y0 = (cy_q - half_q).floor() as isize - 1;
        self.w = n;
        self.h = n;
        self.cells.clear();
        self.cells.resize(n * n, f32::NAN);
        true
    }

    /// The memo's cell of quad `(x, y)` when it covers the 2 x 2 block from `(x, y)` to
    /// `(x + 1, y + 1)` (cells `c`, `c + 1`, `c + w`, `c + w + 1`).
    #[inline]
    pub(super) fn block(&self, x: usize, y: usize) -> Option<usize> {
        let (dx, dy) = (x as isize - self.x0, y as isize - self.y0);
        (dx >= 0 && dy >= 0 && (dx as usize) + 1 < self.w && (dy as usize) + 1 < self.h)
            .then(|| dy as usize * self.w + dx as usize)
    }

    /// The quad of cell `c`.
    #[inline]
    pub(super) fn quad(&self, c: usize) -> (usize, usize) {
        (
            (self.x0 + (c % self.w) as isize) as usize,
            (self.y0 + (c / self.w) as isize) as usize,
        )
    }

    /// The memo's cell of quad `(x, y)`, if it covers it.
    #[inline]
    pub(super) fn cell(&self, x: usize, y: usize) -> Option<usize> {
        let (dx, dy) = (x as isize - self.x0, y as isize - self.y0);
        (dx >= 0 && dy >= 0 && (dx as usize) < self.w && (dy as usize) < self.h)
            .then(|| dy as usize * self.w + dx as usize)
    }
}

/// The ray parameter beyond which the ray from `o` along `d` may have left `block`
/// (`[x0, y0, x1, y1)`, quads): before it, its points are inside by more than a billionth of a
/// quad on both axes, beyond any rounding of `o + t d`.
pub(super) fn leaves_block(block: [f64; 4], o: [f64; 2], d: [f64; 2]) -> f64 {
    const MARGIN: f64 = 1e-9;
    let mut t = f64::INFINITY;
    for k in 0..2 {
        let (lo, hi) = (block[k] + MARGIN, block[k + 2] - MARGIN);
        if d[k] > 0.0 {
            t = t.min((hi - o[k]) / d[k]);
        } else if d[k] < 0.0 {
            t = t.min((lo - o[k]) / d[k]);
        } else if !(lo..=hi).contains(&o[k]) {
            t = f64::NEG_INFINITY;
        }
    }
    t
}

/// A quad's colour position at which it is surely the ball's: above 0.5 by more than a
/// bilinear sample's rounding.
pub(super) const SURE_INSIDE: f32 = 0.5 + 1e-3;

/// A block of quads a ray's samples fall in: see `BallDetector::sure_block`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Block {
    /// `[x0, y0, x1, y1)`, quads.
    pub(super) quads: [f64; 4],
    /// The four quads' colour positions, `[x0 y0, x1 y0, x0 y1, x1 y1]`.
    pub(super) corners: [f32; 4],
    /// All four surely the ball's colour.
    pub(super) sure: bool,
}

/// The bilinear value at `(fx, fy)` (each in `[0, 1)`) between the colour positions `[a00,
/// a10, a01, a11]` of four neighbouring quads; [`OFF_AXIS`] when any of them is.
#[inline(always)]
pub(super) fn bilinear([a00, a10, a01, a11]: [f32; 4], fx: f32, fy: f32) -> f32 {
    if [a00, a10, a01, a11].contains(&OFF_AXIS) {
        return OFF_AXIS;
    }
    let top = a00 * (1.0 - fx) + a10 * fx;
    let bot = a01 * (1.0 - fx) + a11 * fx;
    top * (1.0 - fy) + bot * fy
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A clone of a memo (a cloned detector) takes the same squares as the memo: a `Vec`'s
    /// clone has the length, not the capacity, of the original.
    #[test]
    fn a_cloned_memo_takes_the_squares_the_memo_takes() {
        let mut memo = AlphaMemo::new(13);
        assert!(memo.start(50.0, 50.0, 5.0));
        for mut m in [memo.clone(), AlphaMemo::new(13).clone()] {
            assert!(m.start(50.0, 50.0, 5.0));
            assert_eq!((m.w, m.h, m.cells.len()), (13, 13, 169));
            assert!(!m.start(50.0, 50.0, 5.5));
        }
    }

    proptest! {
        /// Every point of a ray before [`leaves_block`] floors to the block's quad, on both
        /// axes: the samples the fit skips are in the block it checked.
        #[test]
        fn a_ray_stays_in_the_block_until_it_leaves(
            (bx, by) in (0usize..200, 0usize..200),
            (fx, fy) in (0.0f64..1.0, 0.0f64..1.0),
            angle in 0.0f64..std::f64::consts::TAU,
            t0 in 0.0f64..30.0,
        ) {
            let block = [bx as f64, by as f64, bx as f64 + 1.0, by as f64 + 1.0];
            let d = [angle.cos(), angle.sin()];
            // A ray through the point `(bx + fx, by + fy)` at parameter `t0`.
            let o = [bx as f64 + fx - t0 * d[0], by as f64 + fy - t0 * d[1]];
            let end = leaves_block(block, o, d);
            for k in 0..=64 {
                let t = t0 + (end - t0) * k as f64 / 64.0;
                if t < t0 || t > end {
                    continue;
                }
                let (x, y) = (o[0] + t * d[0], o[1] + t * d[1]);
                prop_assert!(x >= 0.0 && y >= 0.0);
                prop_assert_eq!((x as i64 as usize, y as i64 as usize), (bx, by), "t {} of {}", t, end);
            }
        }
    }
}
