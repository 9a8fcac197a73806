//! Step 5: the phase of the stripes across the rod over bit space 0, with the cylinder's
//! projection and the learnt radius correction `eps`.

use super::linalg::invert3;
use super::state::{EnhancedState, Intermediate, PhaseFit};
use super::tuning::{
    CONTRAST_WEIGHT_POWER, EPS_FORGET, EPS_LEARN_FRAMES, EPS_RESCORE_EVERY, PHASE_ROWS,
};
use crate::calib::angle_bias_at;
use crate::frame::FrameView;
use crate::line::LinePoint;
use crate::marker::Marker;

impl EnhancedState {
    /// Step 5: the phase across the rod over bit space 0, with the cylinder's projection.
    pub(super) fn phase(
        &mut self,
        m: &Marker,
        reference_position_mm: f64,
        frame: &FrameView,
        inter: &Intermediate,
    ) -> PhaseFit {
        let st = self;
        let position = inter.edges.position_mm;
        let ca = st.centre_at(m, reference_position_mm, position);
        let c0 = m.bit_space_centre_mm(0);
        let min_span = 0.2 * (inter.loc.white - inter.loc.black);
        // The samples sit at x = R sin(delta) across the rod. If the true apparent radius
        // differs by a factor (1 + eps), sample j really sees the surface angle
        // asin(sin(delta_j) / (1 + eps)); a wrong eps stretches the pattern symmetrically and
        // leaks the fundamental into its conjugate (an error at twice the stripe frequency).
        // The radius is static, so eps is learnt over frames: every frame scores a grid of eps
        // by the matched filter's energy, and the phase uses the best one so far. With a
        // camera model the knots' radius is the lens' projection of the cylinder and the
        // samples already sit where the surface angles `delta` are seen (the rod's own
        // perspective included): the grid is then `eps = 0` alone. The silhouettes' radius
        // misses there by up to a fifth where the light falls off towards a limb, and the
        // energy's best `eps` is not the unbiased one (10 tables as built: angle std per
        // camera, worst / median, 2.31 / 2.04 mrad learnt, 2.64 / 1.78 lens).
        let rows = PHASE_ROWS;
        let n_eps = st.eps_tables.len();
        // The rows' raw samples summed per angle, then normalised to the print's own white (1)
        // and black (0) at that angle.
        st.phase_v.fill(0.0);
        for r in rows {
            let u = c0 + r * m.bit_space_mm();
            let lp: LinePoint = st.knots.at(position + u);
            let (e, rad) = (ca.offset_px, lp.radius_px * ca.radius_ratio);
            let (xb, yb) = lp.offset(0.0, e);
            let (xb, yb) = (xb as f32, yb as f32);
            let (sx, sy) = ((-lp.ty * rad) as f32, (lp.tx * rad) as f32);
            for (acc, &(_, _, sin_d)) in st.phase_v.iter_mut().zip(&st.phase_delta) {
                let sd = sin_d as f32;
                *acc += frame.luma_bilinear(xb + sx * sd, yb + sy * sd) as f64;
            }
        }
        let n_rows = rows.len() as f64;
        for (j, (pv, c)) in st.phase_v.iter_mut().zip(st.phase_c.iter_mut()).enumerate() {
            let span = (st.white[j] - st.black[j]).max(min_span);
            *pv = (*pv - n_rows * st.black[j]) / span;
            *c = span;
        }
        // Weighted least squares of `v = m + a cos + b sin` (the stripes' fundamental): its
        // energy scores eps, its phase is the measurement.
        let fit = |table: &[(f64, f64, f64)], gi: &[[f64; 3]; 3], phase_v: &[f64]| {
            let mut r = [0.0f64; 3];
            let mut sw = 0.0f64;
            for (&(w, c, s_), &pv) in table.iter().zip(phase_v) {
                let wv = w * pv;
                sw += w;
                r[0] += wv;
                r[1] += wv * c;
                r[2] += wv * s_;
            }
            let x: [f64; 3] =
                std::array::from_fn(|i| gi[i][0] * r[0] + gi[i][1] * r[1] + gi[i][2] * r[2]);
            // Energy explained by the fundamental beyond the constant.
            let energy = x[0] * r[0] + x[1] * r[1] + x[2] * r[2] - r[0] * r[0] / sw.max(1e-12);
            (x[0], x[1], x[2], energy)
        };
        // Learn: score the whole grid (while learning, then every 8th frame), accumulate the
        // normalised energies (slowly forgetting), keep the best eps.
        if st.frames_seen < EPS_LEARN_FRAMES || st.frames_seen % EPS_RESCORE_EVERY == 0 {
            for ((z, table), gi) in st.eps_z.iter_mut().zip(&st.eps_tables).zip(&st.eps_ginv) {
                let (_, _, _, e) = fit(table, gi, &st.phase_v);
                *z = (e.max(0.0).sqrt(), 0.0);
            }
            let e_max = st
                .eps_z
                .iter()
                .map(|z| z.0 * z.0 + z.1 * z.1)
                .fold(0.0, f64::max);
            if e_max > 0.0 {
                let keep = if st.frames_seen < EPS_LEARN_FRAMES {
                    EPS_FORGET
                } else {
                    EPS_FORGET.powi(EPS_RESCORE_EVERY as i32)
                };
                for (acc, z) in st.eps_acc.iter_mut().zip(&st.eps_z) {
                    *acc = keep * *acc + (z.0 * z.0 + z.1 * z.1) / e_max;
                }
                st.eps_best = (0..n_eps)
                    .max_by(|&a, &b| st.eps_acc[a].total_cmp(&st.eps_acc[b]))
                    .unwrap_or(n_eps / 2);
            }
        }
        let table = &st.eps_tables[st.eps_best];
        let (mean, a, b, energy) = fit_by_contrast(table, &st.phase_v, &st.phase_c);
        // The variation beyond the constant, weighted as in the fit.
        let (mut sw, mut swv, mut swvv) = (0.0f64, 0.0f64, 0.0f64);
        for ((&(w, _, _), &pv), &c) in table.iter().zip(&st.phase_v).zip(&st.phase_c) {
            let w = w * contrast_weight(c);
            sw += w;
            swv += w * pv;
            swvv += w * pv * pv;
        }
        let variation = swvv - swv * swv / sw.max(1e-12);
        // The angle's bias measured by calibration at this position, removed from the phase
        // (the angle is -phase_sign * phi / cycles plus constants, see the judge).
        let cycles = (m.steps() / 4) as f64;
        let bias = angle_bias_at(&st.angle_bias, position);
        let phi = b.atan2(a) + st.phase_sign * cycles * bias;
        // Per row (phase_v sums the rows).
        let amplitude = (a * a + b * b).sqrt() / rows.len() as f64;
        PhaseFit {
            phi,
            // A square wave between 0 and 1 has a fundamental of amplitude 2/pi.
            amp_ratio: amplitude / (2.0 / std::f64::consts::PI),
            mean: mean / rows.len() as f64,
            share: if variation > 1e-12 {
                (energy / variation).clamp(0.0, 1.0)
            } else {
                0.0
            },
        }
    }
}

/// A sample's weight for the print's contrast `c` (white minus black) there: the normalised
/// sample's noise goes as `1 / c`, so `c^2` is its inverse variance (a dim limb, in the
/// rod's own shade or far from the light, counts for little; see
/// [`CONTRAST_WEIGHT_POWER`]).
fn contrast_weight(c: f64) -> f64 {
    c.powi(CONTRAST_WEIGHT_POWER)
}

/// Weighted least squares of `v = m + a cos + b sin` over a phase table whose weights are
/// multiplied per sample by [`contrast_weight`] of the print's contrast there: returns `(m, a,
/// b, energy explained by the fundamental beyond the constant)`.
fn fit_by_contrast(
    table: &[(f64, f64, f64)],
    phase_v: &[f64],
    contrast: &[f64],
) -> (f64, f64, f64, f64) {
    let mut g = [[0.0f64; 3]; 3];
    let mut r = [0.0f64; 3];
    let mut sw = 0.0f64;
    for ((&(w, c, s_), &v), &k) in table.iter().zip(phase_v).zip(contrast) {
        let w = w * contrast_weight(k);
        let x = [1.0, c, s_];
        for i in 0..3 {
            r[i] += w * v * x[i];
            for j in 0..3 {
                g[i][j] += w * x[i] * x[j];
            }
        }
        sw += w;
    }
    let gi = invert3(&g);
    let x: [f64; 3] = std::array::from_fn(|i| gi[i][0] * r[0] + gi[i][1] * r[1] + gi[i][2] * r[2]);
    let energy = x[0] * r[0] + x[1] * r[1] + x[2] * r[2] - r[0] * r[0] / sw.max(1e-12);
    (x[0], x[1], x[2], energy)
}
