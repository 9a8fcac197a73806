//! Where the coarse scan looks when the window around the prediction finds no ball: the whole
//! field, one of its bands, or the part of it a ball last seen at a known place can have
//! reached since. Every region lies on the whole scan's grid of quads, so that a ball it holds
//! whole leaves the same blob as in the whole scan.

use super::BallDetector;
use crate::ball::tuning::EXTENT_RATIO_MAX;

/// A disc of the ball's plane the ball is known to be in: where it was last seen and how far
/// it can have gone since (the fastest ball over the time since), table mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reach {
    /// The ball's centre when last seen, table mm.
    pub centre_mm: [f64; 2],
    /// How far from it the ball's centre can be now, mm.
    pub radius_mm: f64,
}

/// Points on the reach's circle projected to bound its image.
const REACH_OUTLINE_POINTS: usize = 32;

impl BallDetector {
    /// Quads `[x0, y0, x1, y1)` of the field in band `k` of `n`: the field's rows cut in `n`
    /// bands, each widened by a ball's extent and a step on both sides so that a ball on a
    /// border lies whole in a band. `None`: the band is not one of `n > 1`.
    pub(super) fn band_region(&self, (k, n): (usize, usize)) -> Option<[usize; 4]> {
        if n <= 1 || k >= n {
            return None;
        }
        let mut region = self.field_q;
        let [_, y0, _, y1] = self.field_q;
        let h = (y1 - y0).div_ceil(n);
        let step = self.coarse_step;
        region[1] = y0 + (k * h).saturating_sub(self.extent_margin_q()) / step * step;
        region[3] = (y0 + (k + 1) * h + self.extent_margin_q()).min(y1);
        Some(region)
    }

    /// Quads `[x0, y0, x1, y1)` of the field that hold every ball whose centre lies in
    /// `reach`: the bounding box of the reach's outline projected at the ball's centre height,
    /// widened by a ball's extent and a step. `None` when a point of the outline does not
    /// project (behind the camera) or the reach is not finite.
    pub(super) fn reach_region(&self, reach: Reach) -> Option<[usize; 4]> {
        let Reach {
            centre_mm: [cx, cy],
            radius_mm,
        } = reach;
        if !(cx.is_finite() && cy.is_finite() && radius_mm.is_finite() && radius_mm >= 0.0) {
            return None;
        }
        let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        // The outline's points on a circumscribed polygon (its chords bowed out to the circle):
        // it holds the whole disc.
        let r = radius_mm / (std::f64::consts::PI / REACH_OUTLINE_POINTS as f64).cos();
        for i in 0..REACH_OUTLINE_POINTS {
            let a = std::f64::consts::TAU * i as f64 / REACH_OUTLINE_POINTS as f64;
            let p = [cx + r * a.cos(), cy + r * a.sin(), self.radius_mm];
            let (u, v) = self.cam.project(p)?;
            u0 = u0.min(u);
            v0 = v0.min(v);
            u1 = u1.max(u);
            v1 = v1.max(v);
        }
        // Pixels to quads, widened by a ball's extent and a step.
        let m = self.extent_margin_q() as f64;
        let to_q = |px: f64| (px - 0.5) / 2.0;
        let [fx0, fy0, fx1, fy1] = self.field_q;
        let lo = |q: f64, f0: usize, f1: usize| {
            let q = (q - m).floor().clamp(f0 as f64, f1 as f64) as usize;
            // On the whole scan's grid.
            f0 + (q - f0) / self.coarse_step * self.coarse_step
        };
        let hi = |q: f64, f0: usize, f1: usize| (q + m).ceil().clamp(f0 as f64, f1 as f64) as usize;
        let region = [
            lo(to_q(u0), fx0, fx1),
            lo(to_q(v0), fy0, fy1),
            hi(to_q(u1), fx0, fx1),
            hi(to_q(v1), fy0, fy1),
        ];
        Some(region)
    }

    /// Quads in a field's region, its area.
    pub(super) fn region_quads(region: [usize; 4]) -> usize {
        region[2].saturating_sub(region[0]) * region[3].saturating_sub(region[1])
    }

    /// A ball's largest extent anywhere in the image and a coarse step, quads.
    fn extent_margin_q(&self) -> usize {
        (EXTENT_RATIO_MAX * 2.0 * self.rq_high).ceil() as usize + self.coarse_step
    }
}
