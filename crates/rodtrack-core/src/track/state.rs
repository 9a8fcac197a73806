//! The enhanced mode's per-rod state: the precomputed tables, the scratch buffers, what the
//! learners hold, and the records one frame's stages hand on to the next.

use super::agree::min_wrong_share_cached;
use super::fresh::Learnt;
use super::learners::{CentreFit, ScaleFit};
use super::linalg::normal_inverse;
use super::silhouette::silhouette_rings;
use super::tuning::{
    eps_of, CODE_CHECK_EDGE_STEPS, CODE_CHECK_EVERY, CODE_CHECK_MAX_DELTA_DEG, EDGE_HALF_CELLS,
    EDGE_SAMPLES_PER_CELL, EPS_GRID, PHASE_SAMPLES_PER_PERIOD, SEARCH_MARGIN_MM,
};
use crate::calib::RodCalibration;
use crate::line::PreparedKnots;
use crate::marker::Marker;
use std::f64::consts::TAU;

/// The enhanced mode's state for one rod: line tables, scratch buffers, what is learnt over
/// frames, and the last frame's results between stages.
#[derive(Debug, Clone)]
pub(super) struct EnhancedState {
    pub(super) knots: PreparedKnots,
    /// Coarse candidate of the last frame that was measured `ok` (search window centre).
    pub(super) last_k: Option<usize>,
    /// Axis coordinate of coarse sample 0, mm.
    pub(super) coarse_s0: f64,
    pub(super) coarse_step: f64,
    /// Nearest luma node per coarse sample; `None` outside the frame.
    pub(super) coarse_nodes: Vec<Option<(isize, isize)>>,
    /// `coarse_nodes` on the luma grid of frames whose node offset is `coarse_grid_offset`
    /// (converted on the first frame, again only if the pixel format changes).
    pub(super) coarse_grid: Vec<Option<(isize, isize)>>,
    pub(super) coarse_grid_offset: f64,
    pub(super) coarse: Vec<f32>,
    pub(super) prefix: Vec<f64>,
    pub(super) prefix2: Vec<f64>,
    pub(super) corr: Vec<f32>,
    /// Candidate is usable (its whole window is inside the frame).
    pub(super) valid: Vec<bool>,
    pub(super) cells: Vec<f32>,
    pub(super) cell_len: usize,
    pub(super) edges: Vec<(f64, bool)>,
    pub(super) edge_offsets: Vec<(f64, f64)>,
    /// Usual offset of the edges from the coarse peak, mm (learnt; centres the profiles).
    pub(super) edge_bias_mm: f64,
    /// The mm scale along the rod learnt from the barcode's length over all frames.
    pub(super) scale: ScaleFit,
    pub(super) profile: Vec<f32>,
    /// Phase sample angles `delta` (rad from the facing line): (delta, weight cos delta,
    /// where the sample sits across the rod in knot radii: `sin delta`, or through the rod's
    /// own perspective with the lens' radius).
    pub(super) phase_delta: Vec<(f64, f64, f64)>,
    /// Half the phase samples' span of surface angles, rad, and their spacing's inverse, per
    /// rad.
    pub(super) phase_half_rad: f64,
    pub(super) phase_per_rad: f64,
    /// The print's edges around the rod (see [`super::refine::print_edges`]).
    pub(super) print_edges: Vec<(f64, u32, bool)>,
    /// The rod's own perspective `rho = r / D` with the lens' radius (calibration's
    /// `lens_perspective`), and `sqrt(1 - rho^2)`.
    pub(super) lens_rho: Option<(f64, f64)>,
    /// The radius corrections `eps` scored (one, 0, with the lens' radius).
    pub(super) eps_values: Vec<f64>,
    /// Per radius correction `eps`: (weight, cos, sin) of `cycles * asin(sin(delta) / (1 + eps))`.
    pub(super) eps_tables: Vec<Vec<(f64, f64, f64)>>,
    /// Per `eps`: the inverse of the weighted normal matrix of the fit `v = m + a cos + b sin`
    /// over the samples (the samples need not hold whole periods, nor be evenly spread in the
    /// print's angle, for the fit to keep the phase unbiased).
    pub(super) eps_ginv: Vec<[[f64; 3]; 3]>,
    /// Per `eps`: the surface angle each phase sample sees, `asin(sin(delta) / (1 + eps))`.
    pub(super) eps_angles: Vec<Vec<f64>>,
    /// The least share of a bit space's checked samples that a reading fooled by a group or
    /// more disagrees with (see [`super::min_wrong_share`], computed once per layout).
    pub(super) code_wrong_share: f64,
    /// Matched-filter energy per `eps`, accumulated over frames.
    pub(super) eps_acc: Vec<f64>,
    /// This frame's DFT per `eps` (scratch).
    pub(super) eps_z: Vec<(f64, f64)>,
    /// The best `eps` so far (index into `eps_tables`).
    pub(super) eps_best: usize,
    /// Phase samples summed over the rows (scratch).
    pub(super) phase_v: Vec<f64>,
    /// The print's contrast (white minus black) at each phase sample (scratch).
    pub(super) phase_c: Vec<f64>,
    /// Marker `u` of the rows across white and black rings used to measure the shading.
    pub(super) white_u: Vec<f64>,
    pub(super) black_u: Vec<f64>,
    /// Shading of white and black print at each phase sample angle (scratch).
    pub(super) white: Vec<f64>,
    pub(super) black: Vec<f64>,
    /// The last measured shading, relative to that frame's barcode levels (0 black, 1 white),
    /// where it was measured, and how many frames ago.
    pub(super) white_rel: Vec<f64>,
    pub(super) black_rel: Vec<f64>,
    pub(super) shading_at_mm: f64,
    pub(super) shading_age: u32,
    /// Marker `u` of the full rings whose silhouettes give the rod's centre and radius, white
    /// (`true`) or black, and their mean `u`.
    pub(super) ring_u: Vec<(f64, bool)>,
    pub(super) ring_u_mid: f64,
    /// The rod's centre line learnt from the rings' silhouettes over all frames so far.
    pub(super) centre: CentreFit,
    /// Whether the learnt centre line moves the phase's lateral reference along the travel
    /// (calibration's `learn_centre_slope`).
    pub(super) centre_slope: bool,
    /// Whether the knots' radius is the lens' projection of the cylinder (calibration's
    /// `lens_perspective`): the silhouettes' radius ratio is then not applied.
    pub(super) lens_radius: bool,
    /// The angle's bias along the travel measured by calibration (see
    /// [`EnhancedParams::angle_bias_rad`](crate::calib::EnhancedParams::angle_bias_rad)), and
    /// the print's direction around the rod (`phase_sign`).
    pub(super) angle_bias: Vec<[f64; 2]>,
    pub(super) phase_sign: f64,
    /// Frames processed (for decimating the learning).
    pub(super) frames_seen: u64,
    /// Frames in which the whole travel was searched (diagnostics).
    pub(super) full_searches: u64,
    /// The fused angle (Gray steps) of the last frame, when it was measured ok, and how far
    /// it had moved from the frame before (see `agree`).
    pub(super) last_ok_theta: Option<f64>,
    pub(super) last_dtheta: f64,
    /// The code's disagreement with the print across the rod (see `agree`) of the check that
    /// started the reading the last ok frame continued (the quality's evidence, see
    /// `quality`).
    pub(super) reading_code_share: f64,
    /// Frames in a row not measured `ok` (see `fresh`).
    pub(super) not_ok_run: u64,
    /// Fresh searches from the calibration alone, and those that reset the learnt state.
    pub(super) fresh_searches: u64,
    pub(super) learnt_resets: u64,
    /// The learnt state set aside during a fresh search.
    pub(super) backup: Learnt,
    /// The last frame's results between stages, when it got past the edges.
    pub(super) inter: Option<Intermediate>,
    /// Where the marker is expected in the next frame (last position plus last motion), mm on
    /// the calibrated line; `None` when the last frame did not find it.
    pub(super) predicted_mm: Option<f64>,
}

/// Where the coarse search found the barcode.
#[derive(Debug, Clone, Copy)]
pub(super) struct Located {
    /// Coarse candidate.
    pub(super) k: usize,
    /// Its correlation.
    pub(super) ncc: f64,
    /// Marker position on the calibrated line from the coarse peak, mm.
    pub(super) pos0_mm: f64,
    /// Print levels from the barcode's cells.
    pub(super) white: f64,
    pub(super) black: f64,
}

/// The position from the barcode's edges.
#[derive(Debug, Clone, Copy)]
pub(super) struct EdgeFit {
    /// Marker position on the calibrated line, mm.
    pub(super) position_mm: f64,
    /// The same in true mm (the learnt scale applied).
    pub(super) position_out_mm: f64,
    /// Spread of the edges around their fit, mm.
    pub(super) edge_std_mm: f64,
    /// Edges the fit used.
    pub(super) edges_used: usize,
}

/// One frame's results between stages.
#[derive(Debug, Clone, Copy)]
pub(super) struct Intermediate {
    pub(super) loc: Located,
    pub(super) edges: EdgeFit,
}
/// The Gray code step's result.
#[derive(Debug, Clone, Copy)]
pub(super) struct GrayRead {
    /// The decoded step.
    pub(super) alpha: u32,
    /// Each bit's distance from the threshold, in half contrasts (bit space `k` at `k`).
    pub(super) margins: [f64; 8],
    /// The light's offset on the barcode's scale at each bit space (see
    /// [`EnhancedState::gray_code`]).
    pub(super) offsets: [f64; 8],
}

/// The phase step's result.
#[derive(Debug, Clone, Copy)]
pub(super) struct PhaseFit {
    /// Phase of the stripes' fundamental, rad.
    pub(super) phi: f64,
    /// Its amplitude over a full-contrast square wave's.
    pub(super) amp_ratio: f64,
    /// The stripes' mean level over bit space 0, on the barcode's scale (its black 0, its
    /// white 1 at each point across the rod): 0.5 when bit space 0 is lit as the barcode is.
    pub(super) mean: f64,
    /// The share of the samples' variation (beyond their mean) that the fundamental explains:
    /// 8/pi^2 = 0.81 for sharp stripes, more when blurred.
    pub(super) share: f64,
}
/// The learnt centre line, seen from one frame's marker position (worked out once per frame).
pub(super) struct CentreAt {
    /// The offset across the calibrated line relative to the reference pose, px. The learnt
    /// centre is a line in `s`, so this is its slope times the marker's distance from the
    /// reference: the same at every row of the marker.
    pub(super) offset_px: f64,
    /// The learnt half width over the calibrated radius at bit space 0.
    pub(super) radius_ratio: f64,
}

impl EnhancedState {
    /// Precomputes the tables and allocates the buffers for a rod of `calib` in frames of
    /// `width` x `height`.
    pub(super) fn new(
        calib: &RodCalibration,
        marker: &Marker,
        width: usize,
        height: usize,
    ) -> EnhancedState {
        let knots = PreparedKnots::new(&calib.knots);
        let cell_len = 4usize;
        let step = marker.cell_mm() / cell_len as f64;
        let first = calib.travel_mm[0] - SEARCH_MARGIN_MM + marker.barcode_start_mm();
        let last = calib.travel_mm[1]
            + SEARCH_MARGIN_MM
            + marker.barcode_start_mm()
            + marker.barcode_len_mm();
        let n = ((last - first) / step).ceil() as usize + 1;
        let kernel_n = marker.kernel().len() * cell_len;
        let n = n.max(kernel_n + 1);
        let coarse_nodes: Vec<Option<(isize, isize)>> = (0..n)
            .map(|i| {
                let p = knots.at(first + i as f64 * step);
                // Nearest luma node; for Bayer the node offset is applied when reading.
                if p.x < 1.0 || p.y < 1.0 || p.x > width as f64 - 2.0 || p.y > height as f64 - 2.0 {
                    None
                } else {
                    Some((p.x.round() as isize, p.y.round() as isize))
                }
            })
            .collect();
        let n_cand = n - kernel_n + 1;
        let valid: Vec<bool> = (0..n_cand)
            .map(|k| coarse_nodes[k..k + kernel_n].iter().all(|c| c.is_some()))
            .collect();
        let cells: Vec<f32> = marker
            .kernel()
            .iter()
            .map(|&b| if b { 0.0 } else { 1.0 })
            .collect();
        let cycles = (marker.steps() / 4) as f64;
        // Whole periods inside +/- 70 deg of the facing line.
        let period = TAU / cycles;
        let periods = ((140f64.to_radians() / period).floor() as usize).max(1);
        let half = periods as f64 * period * 0.5;
        let count = periods * PHASE_SAMPLES_PER_PERIOD;
        // Where across the rod (in knot radii) the surface line at angle `d` from the facing
        // one is seen: `sin d` for a distant camera; with the lens' radius, through the rod's
        // own perspective `rho = r / D` (`sqrt(1 - rho^2)` turns the knots' silhouette radius
        // into the facing line's scale).
        let lens = calib.enhanced.lens_perspective;
        let across = |d: f64| match lens {
            Some(rho) => (1.0 - rho * rho).sqrt() * d.sin() / (1.0 - rho * d.cos()),
            None => d.sin(),
        };
        let phase_delta: Vec<(f64, f64, f64)> = (0..count)
            .map(|j| {
                let d = -half + (j as f64 + 0.5) * (2.0 * half / count as f64);
                (d, d.cos(), across(d))
            })
            .collect();
        // With the lens' radius nothing is learnt: one table, the surface angles themselves.
        let eps_values: Vec<f64> = if lens.is_some() {
            vec![0.0]
        } else {
            (0..EPS_GRID).map(eps_of).collect()
        };
        let eps_tables: Vec<Vec<(f64, f64, f64)>> = eps_values
            .iter()
            .map(|eps| {
                phase_delta
                    .iter()
                    .map(|&(d, w, _): &(f64, f64, f64)| {
                        let t = (d.sin() / (1.0 + eps)).clamp(-1.0, 1.0).asin();
                        (w, (cycles * t).cos(), (cycles * t).sin())
                    })
                    .collect()
            })
            .collect();
        let eps_angles: Vec<Vec<f64>> = eps_values
            .iter()
            .map(|eps| {
                phase_delta
                    .iter()
                    .map(|&(d, _, _)| (d.sin() / (1.0 + eps)).clamp(-1.0, 1.0).asin())
                    .collect()
            })
            .collect();
        let eps_ginv: Vec<[[f64; 3]; 3]> = eps_tables.iter().map(|t| normal_inverse(t)).collect();
        // Rows across the middle of the longest white and black runs of the barcode: the print's
        // shading across the rod (the light is fixed in the world, so it depends on the angle
        // from the facing line, not on the rod's angle) is measured there every frame.
        let run_rows = |black: bool| -> Vec<f64> {
            let k = marker.kernel();
            let mut best = (0usize, 0usize);
            let mut i = 0;
            while i < k.len() {
                if k[i] == black {
                    let j = (i..k.len()).find(|&j| k[j] != black).unwrap_or(k.len());
                    if j - i > best.1 - best.0 {
                        best = (i, j);
                    }
                    i = j;
                } else {
                    i += 1;
                }
            }
            let centre =
                marker.barcode_start_mm() + 0.5 * (best.0 + best.1) as f64 * marker.cell_mm();
            let half = 0.5 * (best.1 - best.0) as f64 * marker.cell_mm();
            if half >= marker.cell_mm() {
                vec![centre - 0.4 * half, centre + 0.4 * half]
            } else {
                vec![centre]
            }
        };
        let n_phase = count;
        let checked: Vec<f64> = phase_delta
            .iter()
            .step_by(CODE_CHECK_EVERY)
            .map(|p| p.0)
            .filter(|d| d.abs() <= CODE_CHECK_MAX_DELTA_DEG.to_radians())
            .collect();
        let code_wrong_share =
            min_wrong_share_cached(marker.bits(), &checked, CODE_CHECK_EDGE_STEPS);
        let ring_u = silhouette_rings(marker);
        EnhancedState {
            last_k: None,
            ring_u_mid: ring_u.iter().map(|r| r.0).sum::<f64>() / ring_u.len().max(1) as f64,
            ring_u,
            centre: CentreFit::default(),
            centre_slope: calib.enhanced.learn_centre_slope,
            lens_radius: lens.is_some(),
            print_edges: super::refine::print_edges(marker.bits()),
            lens_rho: lens.map(|rho| (rho, (1.0 - rho * rho).sqrt())),
            phase_half_rad: half,
            phase_per_rad: count as f64 / (2.0 * half),
            angle_bias: calib.enhanced.angle_bias_rad.clone(),
            phase_sign: calib.enhanced.phase_sign as f64,
            frames_seen: 0,
            full_searches: 0,
            not_ok_run: 0,
            last_ok_theta: None,
            last_dtheta: 0.0,
            reading_code_share: 0.0,
            fresh_searches: 0,
            learnt_resets: 0,
            backup: Learnt::with_sizes(eps_values.len(), n_phase),
            inter: None,
            predicted_mm: None,
            white_u: run_rows(false),
            black_u: run_rows(true),
            white: vec![0.0; n_phase],
            black: vec![0.0; n_phase],
            white_rel: vec![0.0; n_phase],
            black_rel: vec![0.0; n_phase],
            shading_at_mm: f64::NAN,
            shading_age: 0,
            knots,
            coarse_s0: first,
            coarse_step: step,
            coarse: vec![0.0; n],
            prefix: vec![0.0; n + 1],
            prefix2: vec![0.0; n + 1],
            corr: vec![0.0; n_cand],
            valid,
            coarse_grid: coarse_nodes.clone(),
            coarse_grid_offset: f64::NAN,
            coarse_nodes,
            cells,
            cell_len,
            edges: marker.barcode_edges_mm(),
            edge_offsets: Vec::with_capacity(64),
            edge_bias_mm: 0.0,
            scale: ScaleFit::default(),
            profile: vec![0.0; (2.0 * EDGE_HALF_CELLS * EDGE_SAMPLES_PER_CELL as f64) as usize + 1],
            eps_tables,
            eps_ginv,
            eps_angles,
            code_wrong_share,
            eps_acc: vec![0.0; eps_values.len()],
            eps_z: vec![(0.0, 0.0); eps_values.len()],
            eps_best: eps_values.len() / 2,
            eps_values,
            phase_v: vec![0.0; count],
            phase_c: vec![0.0; count],
            phase_delta,
        }
    }

    /// The learnt centre's offset at marker `u` relative to the reference pose (calibration
    /// fixed the absolute centre, and with it the angle offset, there; what is learnt is how
    /// the centre runs away from it), and the learnt radius ratio at bit space 0.
    pub(super) fn centre_at(
        &self,
        m: &Marker,
        reference_position_mm: f64,
        position_mm: f64,
    ) -> CentreAt {
        let c0 = m.bit_space_centre_mm(0);
        let (run_px, radius_ratio) = self
            .centre
            .run_between(reference_position_mm + c0, position_mm + c0);
        let offset_px = if self.centre_slope { run_px } else { 0.0 };
        let radius_ratio = if self.lens_radius { 1.0 } else { radius_ratio };
        CentreAt {
            offset_px,
            radius_ratio,
        }
    }
}
