//! Step 3: the sub-pixel position from the barcode's edges, and the learnt mm scale.

use super::result::RodResult;
use super::state::{EdgeFit, EnhancedState, Located};
use super::tuning::EDGE_HALF_CELLS;
use crate::frame::FrameView;
use crate::marker::Marker;
use crate::measurement::Status;

impl EnhancedState {
    /// Step 3: sub-pixel position from the barcode's edges, and the learnt mm scale.
    pub(super) fn fit_edges(
        &mut self,
        m: &Marker,
        reference_position_mm: f64,
        frame: &FrameView,
        loc: &Located,
    ) -> Result<EdgeFit, RodResult> {
        let st = self;
        let (pos0, contrast, ncc) = (loc.pos0_mm, loc.white - loc.black, loc.ncc);
        let cell = m.cell_mm();
        let n_prof = st.profile.len();
        let half = EDGE_HALF_CELLS * cell;
        let dstep = 2.0 * half / (n_prof - 1) as f64;
        st.edge_offsets.clear();
        for &(u_e, rising) in &st.edges {
            // The profile is centred where the edge is expected (the coarse peak plus its usual
            // offset from the edges) and read lazily: its two ends, then outward from the
            // middle until the crossing, which is then usually one of the first two pairs.
            let bias = st.edge_bias_mm;
            let s_e = pos0 + bias + u_e;
            // Along the tangent at the edge: the line's knots are straight segments, and the
            // profile spans one cell, so this is the line itself to far below a pixel.
            let lp = st.knots.at(s_e);
            let (dx, dy) = (
                (lp.tx * lp.px_per_mm * dstep) as f32,
                (lp.ty * lp.px_per_mm * dstep) as f32,
            );
            let (x0, y0) = (
                (lp.x - lp.tx * lp.px_per_mm * half) as f32,
                (lp.y - lp.ty * lp.px_per_mm * half) as f32,
            );
            let sample = |i: usize| {
                let t = i as f32;
                frame.luma_bilinear(x0 + t * dx, y0 + t * dy)
            };
            st.profile.fill(f32::NAN);
            st.profile[0] = sample(0);
            st.profile[n_prof - 1] = sample(n_prof - 1);
            let level = 0.5 * (st.profile[0] + st.profile[n_prof - 1]);
            let local = (st.profile[0] - st.profile[n_prof - 1]).abs() as f64;
            if local < 0.35 * contrast {
                continue;
            }
            // White-to-black in +s means the profile falls through the level.
            let sign = if rising { 1.0f32 } else { -1.0 };
            let mid = n_prof / 2;
            let mut found = None;
            for r in 0..mid {
                for i in [mid + r, mid - r - 1] {
                    if i + 1 >= n_prof {
                        continue;
                    }
                    for q in [i, i + 1] {
                        if st.profile[q].is_nan() {
                            st.profile[q] = sample(q);
                        }
                    }
                    let a = (level - st.profile[i]) * sign;
                    let b = (level - st.profile[i + 1]) * sign;
                    if a <= 0.0 && b > 0.0 {
                        let f = a / (a - b);
                        found = Some((i as f64 + f as f64) * dstep - half);
                        break;
                    }
                }
                if found.is_some() {
                    break;
                }
            }
            if let Some(o) = found {
                st.edge_offsets.push((u_e, o + bias));
            }
        }
        let n_edges = st.edge_offsets.len();
        if n_edges < st.edges.len() / 2 {
            return Err(RodResult {
                status: Status::Occluded,
                ncc,
                quality: 0.2,
                reason: "too few barcode edges",
                ..Default::default()
            });
        }
        st.edge_offsets.sort_unstable_by(|a, b| a.1.total_cmp(&b.1));
        let median = st.edge_offsets[n_edges / 2].1;
        // Inliers: offset and local scale by least squares, o = a + b (u - mean u).
        let (mut n_in, mut su, mut so, mut suu, mut suo, mut soo) =
            (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
        for &(u, o) in &st.edge_offsets {
            if (o - median).abs() < 0.25 * cell {
                n_in += 1.0;
                su += u;
                so += o;
                suu += u * u;
                suo += u * o;
                soo += o * o;
            }
        }
        let (mean_off, edge_std, u_mean, slope) = if n_in >= 2.0 {
            let mu = su / n_in;
            let mo = so / n_in;
            let vu = suu / n_in - mu * mu;
            let b = if vu > 1e-9 {
                (suo / n_in - mu * mo) / vu
            } else {
                0.0
            };
            let resid = (soo / n_in - mo * mo - b * b * vu).max(0.0).sqrt();
            (mo, resid, mu, b)
        } else {
            (
                median,
                cell,
                m.barcode_start_mm() + 0.5 * m.barcode_len_mm(),
                0.0,
            )
        };
        // The edges' centroid on the calibrated line, and the local scale error there.
        let s_centroid = pos0 + u_mean + mean_off;
        if n_in >= 8.0 {
            st.scale.add(s_centroid, slope);
            st.edge_bias_mm += 0.1 * (mean_off - st.edge_bias_mm);
            st.edge_bias_mm = st.edge_bias_mm.clamp(-0.25 * cell, 0.25 * cell);
        }
        let s_ref_c = reference_position_mm + u_mean;
        let position_out = st.scale.to_true(s_centroid, s_ref_c) - u_mean;
        let position = s_centroid - u_mean;
        // The rod's centre and apparent radius where the marker is: this frame's silhouettes of
        Ok(EdgeFit {
            position_mm: position,
            position_out_mm: position_out,
            edge_std_mm: edge_std,
            edges_used: n_in as usize,
        })
    }
}
