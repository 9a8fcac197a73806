//! One rod, one frame: the measurement (SPEC section 4, steps 1-5), in the paper's mode and in
//! rodtrack's enhanced mode.
//!
//! A [`RodTracker`] is built once from a rod's calibration: it precomputes the line tables and
//! owns its scratch buffers, so that [`RodTracker::process`] allocates nothing.

use crate::calib::RodCalibration;
use crate::decode::{decode_bits, paper_fuse, paper_phase, paper_threshold};
use crate::frame::FrameView;
use crate::line::{Knots, LinePoint, PaperLine};
use crate::marker::Marker;
use crate::measurement::Status;
use crate::signal::{
    argmax, argmax_sq, hysteresis, ncc_cells_prefix, ncc_direct, paper_bandpass, parabolic_offset,
    prefix_sums, PAPER_HYSTERESIS,
};
use crate::CoreError;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// Which algorithm measures a rod.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// The paper's algorithm, exactly (the baseline).
    Paper,
    /// rodtrack's algorithm.
    #[default]
    Enhanced,
}

impl Mode {
    /// Parses `paper` or `enhanced`.
    pub fn from_name(s: &str) -> Option<Mode> {
        match s {
            "paper" => Some(Mode::Paper),
            "enhanced" => Some(Mode::Enhanced),
            _ => None,
        }
    }
}

/// What one rod's processing found in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RodResult {
    /// Position along `u`, mm.
    pub position_mm: f64,
    /// Angle in `[0, 2 pi)`.
    pub angle_rad: f64,
    /// Confidence in `[0, 1]`.
    pub quality: f64,
    /// Trust.
    pub status: Status,
    /// Diagnostics: the decoded Gray step.
    pub gray_step: u32,
    /// Diagnostics: the angle in Gray steps before the offset, `[0, steps)`.
    pub theta_steps: f64,
    /// Diagnostics: the correlation peak.
    pub ncc: f64,
    /// Diagnostics: why the status is not `ok` (empty when it is).
    pub reason: &'static str,
    /// Diagnostics: phase amplitude over the expected one.
    pub amp_ratio: f64,
    /// Diagnostics: spread of the barcode's edges around their fit, mm.
    pub edge_std_mm: f64,
}

/// Candidate search margin beyond the travel, mm.
const SEARCH_MARGIN_MM: f64 = 10.0;
/// Fine-profile half length around an edge, in cells.
const EDGE_HALF_CELLS: f64 = 0.5;
/// Fine-profile samples per cell.
const EDGE_SAMPLES_PER_CELL: usize = 16;
/// Phase samples per stripe period.
const PHASE_SAMPLES_PER_PERIOD: usize = 8;

#[derive(Debug, Clone)]
struct PaperState {
    line: PaperLine,
    kernel_px: Vec<f32>,
    raw: Vec<f32>,
    filtered: Vec<f32>,
    binary: Vec<f32>,
    corr: Vec<f32>,
    d: Vec<f32>,
}

#[derive(Debug, Clone)]
struct EnhancedState {
    knots: Knots,
    /// Axis coordinate of coarse sample 0, mm.
    coarse_s0: f64,
    coarse_step: f64,
    /// Nearest luma node per coarse sample; `None` outside the frame.
    coarse_nodes: Vec<Option<(isize, isize)>>,
    coarse: Vec<f32>,
    prefix: Vec<f64>,
    prefix2: Vec<f64>,
    corr: Vec<f32>,
    /// Candidate is usable (its whole window is inside the frame).
    valid: Vec<bool>,
    cells: Vec<f32>,
    cell_len: usize,
    edges: Vec<(f64, bool)>,
    edge_offsets: Vec<f64>,
    profile: Vec<f32>,
    /// Phase sample angles (rad from the facing line) and their sin/cos of `f delta`.
    phase_delta: Vec<(f64, f64, f64, f64)>,
    /// Marker `u` of the rows across white and black rings used to measure the shading.
    white_u: Vec<f64>,
    black_u: Vec<f64>,
    /// Shading of white and black print at each phase sample angle (scratch).
    white: Vec<f64>,
    black: Vec<f64>,
}

/// Measures one rod in frames of one camera.
#[derive(Debug, Clone)]
pub struct RodTracker {
    calib: RodCalibration,
    marker: Marker,
    width: usize,
    height: usize,
    mode: Mode,
    paper: Option<PaperState>,
    enhanced: EnhancedState,
}

impl RodTracker {
    /// Builds the tracker: validates the calibration and precomputes the tables.
    pub fn new(
        calib: &RodCalibration,
        width: usize,
        height: usize,
        mode: Mode,
    ) -> Result<RodTracker, CoreError> {
        let marker = calib.validate(width, height)?;
        if mode == Mode::Paper && calib.paper.is_none() {
            return Err(CoreError::Calibration {
                rod: calib.rod,
                field: "paper".into(),
                reason: "paper mode needs the paper parameters (the rod must run along image rows)"
                    .into(),
            });
        }
        let paper = calib.paper.as_ref().map(|p| {
            let line = PaperLine::new(p.trajectory_abc, p.view_angle_deg.to_radians(), height);
            let n = (marker.kernel().len() as f64 * p.cell_px).round().max(4.0) as usize;
            let n = n.min(line.pixels.len().saturating_sub(1)).max(1);
            let kernel_px: Vec<f32> = (0..n)
                .map(|i| {
                    let c = ((i as f64 + 0.5) / p.cell_px) as usize;
                    let c = c.min(marker.kernel().len() - 1);
                    let c = if p.direction > 0 {
                        c
                    } else {
                        marker.kernel().len() - 1 - c
                    };
                    if marker.kernel()[c] {
                        1.0
                    } else {
                        0.0
                    }
                })
                .collect();
            let len = line.pixels.len();
            PaperState {
                kernel_px,
                raw: vec![0.0; len],
                filtered: vec![0.0; len],
                binary: vec![0.0; len],
                corr: vec![0.0; len.saturating_sub(n) + 1],
                d: vec![0.0; 2 * p.half_width_px as usize + 1],
                line,
            }
        });
        let enhanced = Self::build_enhanced(calib, &marker, width, height);
        Ok(RodTracker {
            calib: calib.clone(),
            marker,
            width,
            height,
            mode,
            paper,
            enhanced,
        })
    }

    fn build_enhanced(
        calib: &RodCalibration,
        marker: &Marker,
        width: usize,
        height: usize,
    ) -> EnhancedState {
        let knots = calib.knots.clone();
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
        let phase_delta = (0..count)
            .map(|j| {
                let d = -half + (j as f64 + 0.5) * (2.0 * half / count as f64);
                let w = d.cos();
                (d, w, (cycles * d).sin(), (cycles * d).cos())
            })
            .collect();
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
        EnhancedState {
            white_u: run_rows(false),
            black_u: run_rows(true),
            white: vec![0.0; n_phase],
            black: vec![0.0; n_phase],
            knots,
            coarse_s0: first,
            coarse_step: step,
            coarse: vec![0.0; n],
            prefix: vec![0.0; n + 1],
            prefix2: vec![0.0; n + 1],
            corr: vec![0.0; n_cand],
            valid,
            coarse_nodes,
            cells,
            cell_len,
            edges: marker.barcode_edges_mm(),
            edge_offsets: Vec::with_capacity(64),
            profile: vec![0.0; (2.0 * EDGE_HALF_CELLS * EDGE_SAMPLES_PER_CELL as f64) as usize + 1],
            phase_delta,
        }
    }

    /// The rod id.
    pub fn rod(&self) -> u32 {
        self.calib.rod
    }
    /// The calibration this tracker was built from.
    pub fn calibration(&self) -> &RodCalibration {
        &self.calib
    }
    /// The mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }
    /// The marker.
    pub fn marker(&self) -> &Marker {
        &self.marker
    }
    /// The enhanced line.
    pub fn knots(&self) -> &Knots {
        &self.enhanced.knots
    }

    /// Measures the rod in one frame. Allocates nothing.
    pub fn process(&mut self, frame: &FrameView) -> Result<RodResult, CoreError> {
        if frame.width() != self.width || frame.height() != self.height {
            return Err(CoreError::FrameMismatch {
                field: "size",
                expected: format!("{}x{}", self.width, self.height),
                got: format!("{}x{}", frame.width(), frame.height()),
            });
        }
        Ok(match self.mode {
            Mode::Paper => self.process_paper(frame),
            Mode::Enhanced => self.process_enhanced(frame),
        })
    }

    // ---------------------------------------------------------------- paper mode

    fn process_paper(&mut self, frame: &FrameView) -> RodResult {
        let (Some(st), Some(p)) = (self.paper.as_mut(), self.calib.paper.as_ref()) else {
            return RodResult {
                status: Status::NotFound,
                ..Default::default()
            };
        };
        // 1. Line extraction, nearest pixel.
        for (v, &(x, y)) in st.raw.iter_mut().zip(&st.line.pixels) {
            *v = frame.luma_nearest(x as f32, y as f32);
        }
        // 2. Band-pass and hysteresis.
        paper_bandpass(&st.raw, &mut st.filtered);
        hysteresis(
            &st.filtered,
            -PAPER_HYSTERESIS,
            PAPER_HYSTERESIS,
            &mut st.binary,
        );
        // 3. NCC, argmax C^2.
        ncc_direct(&st.kernel_px, &st.binary, &mut st.corr);
        let Some(pk) = argmax_sq(&st.corr) else {
            return RodResult {
                status: Status::NotFound,
                ..Default::default()
            };
        };
        let c = st.corr[pk] as f64;
        let pm = pk as f64;
        // 4. Coarse angle.
        let len = st.raw.len() as f64;
        let mut samples = [0.0f32; 8];
        let bits = self.marker.bits() as usize;
        for (k, s) in samples.iter_mut().enumerate().take(bits) {
            let j = (pm + p.offset_px + (k as f64 + 1.5) * p.spacing_px).round();
            if j < 0.0 || j >= len {
                return RodResult {
                    status: Status::OutOfView,
                    ncc: c,
                    ..Default::default()
                };
            }
            *s = st.raw[j as usize];
        }
        let thr = paper_threshold(&samples[..bits]);
        let (_, alpha) = decode_bits(&samples[..bits], thr);
        // 5. Fine angle: pixels across the rod at bit space 0's centre row.
        let j0 = (pm + p.offset_px + 1.5 * p.spacing_px).round() as usize;
        let (x0, y0) = st.line.pixels[j0.min(st.line.pixels.len() - 1)];
        let np = p.half_width_px as i32;
        for (i, d) in st.d.iter_mut().enumerate() {
            *d = frame.luma_nearest((x0 + i as i32 - np) as f32, y0 as f32);
        }
        let phi = p.phase_sign as f32 * paper_phase(&st.d, p.period_px as f32);
        let steps = self.marker.steps();
        let theta = paper_fuse(phi, p.phase_offset_rad as f32, alpha, steps) as f64;
        let angle = (theta * TAU / steps as f64 - p.angle_offset_rad).rem_euclid(TAU);
        let position =
            p.direction as f64 * (pm - p.zero_px) * p.mm_per_px + self.calib.reference_position_mm;
        RodResult {
            position_mm: position,
            angle_rad: angle,
            quality: c.abs().min(1.0),
            status: Status::Ok,
            gray_step: alpha,
            theta_steps: theta,
            ncc: c,
            ..Default::default()
        }
    }

    // ------------------------------------------------------------- enhanced mode

    fn process_enhanced(&mut self, frame: &FrameView) -> RodResult {
        let m = &self.marker;
        let st = &mut self.enhanced;
        let node_off = frame.node_offset() as f64;
        // 1. Coarse line at 1/4 cell, nearest luma node.
        for (v, n) in st.coarse.iter_mut().zip(&st.coarse_nodes) {
            *v = match n {
                Some((i, j)) => {
                    let i = (*i as f64 - node_off).round() as isize;
                    let j = (*j as f64 - node_off).round() as isize;
                    frame.luma_node(i, j)
                }
                None => 0.0,
            };
        }
        // 2. NCC with the cell kernel in O(samples x cells).
        prefix_sums(&st.coarse, &mut st.prefix, &mut st.prefix2);
        ncc_cells_prefix(
            &st.cells,
            st.cell_len,
            &st.prefix,
            &st.prefix2,
            &mut st.corr,
        );
        for (c, ok) in st.corr.iter_mut().zip(&st.valid) {
            if !ok {
                *c = -1.0;
            }
        }
        let Some(k) = argmax(&st.corr) else {
            return RodResult {
                status: Status::OutOfView,
                ..Default::default()
            };
        };
        let ncc = st.corr[k] as f64;
        if !st.valid[k] {
            return RodResult {
                status: Status::OutOfView,
                ..Default::default()
            };
        }
        if ncc < 0.5 {
            return RodResult {
                status: Status::NotFound,
                quality: ncc.max(0.0) * 0.5,
                ncc,
                reason: "weak barcode correlation",
                ..Default::default()
            };
        }
        let sub = parabolic_offset(&st.corr, k) as f64;
        let pos0 = st.coarse_s0 + (k as f64 + sub) * st.coarse_step - m.barcode_start_mm();
        // Black and white levels from the cells' middle samples.
        let (mut w_sum, mut w_n, mut b_sum, mut b_n) = (0.0f64, 0usize, 0.0f64, 0usize);
        for (c, &cell) in st.cells.iter().enumerate() {
            let base = k + c * st.cell_len;
            let v = 0.5 * (st.coarse[base + 1] + st.coarse[base + 2]) as f64;
            if cell > 0.5 {
                w_sum += v;
                w_n += 1;
            } else {
                b_sum += v;
                b_n += 1;
            }
        }
        let white = w_sum / w_n.max(1) as f64;
        let black = b_sum / b_n.max(1) as f64;
        let contrast = white - black;
        if contrast < 8.0 {
            return RodResult {
                status: Status::NotFound,
                ncc,
                reason: "no contrast",
                ..Default::default()
            };
        }
        // 3. Sub-pixel position from the barcode's edges.
        let cell = m.cell_mm();
        let n_prof = st.profile.len();
        let half = EDGE_HALF_CELLS * cell;
        let dstep = 2.0 * half / (n_prof - 1) as f64;
        st.edge_offsets.clear();
        for &(u_e, rising) in &st.edges {
            let s_e = pos0 + u_e;
            for (i, v) in st.profile.iter_mut().enumerate() {
                let p = st.knots.at(s_e - half + i as f64 * dstep);
                *v = frame.luma_bilinear(p.x as f32, p.y as f32);
            }
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
                st.edge_offsets.push(o);
            }
        }
        let n_edges = st.edge_offsets.len();
        if n_edges < st.edges.len() / 2 {
            return RodResult {
                status: Status::Occluded,
                ncc,
                quality: 0.2,
                reason: "too few barcode edges",
                ..Default::default()
            };
        }
        st.edge_offsets.sort_unstable_by(|a, b| a.total_cmp(b));
        let median = st.edge_offsets[n_edges / 2];
        let (mut s1, mut sn, mut s2) = (0.0, 0usize, 0.0);
        for &o in &st.edge_offsets {
            if (o - median).abs() < 0.25 * cell {
                s1 += o;
                s2 += o * o;
                sn += 1;
            }
        }
        let mean_off = if sn > 0 { s1 / sn as f64 } else { median };
        let edge_std = if sn > 1 {
            (s2 / sn as f64 - mean_off * mean_off).max(0.0).sqrt()
        } else {
            cell
        };
        let position = pos0 + mean_off;
        // 4. Gray bits at the centre of each bit space.
        let bits = m.bits() as usize;
        let mut samples = [0.0f32; 8];
        let threshold = (0.5 * (white + black)) as f32;
        let mut min_high_margin = f64::MAX;
        for (kb, s) in samples.iter_mut().enumerate().take(bits) {
            let c = m.bit_space_centre_mm(kb as u32);
            let lp = st.knots.at(position + c);
            let mut acc = 0.0f32;
            for da in [-0.2, 0.0, 0.2] {
                for dc in [-0.15, 0.0, 0.15] {
                    let (x, y) = lp.offset(da * m.bit_space_mm() * lp.px_per_mm, dc * lp.radius_px);
                    acc += frame.luma_bilinear(x as f32, y as f32);
                }
            }
            *s = acc / 9.0;
            if kb >= 2 {
                let margin = ((*s - threshold).abs() as f64) / (0.5 * contrast);
                min_high_margin = min_high_margin.min(margin);
            }
        }
        let (_, alpha) = decode_bits(&samples[..bits], threshold);
        // 5. Phase across the rod over bit space 0, with the cylinder's projection.
        let c0 = m.bit_space_centre_mm(0);
        // The shading of white and black print across the rod, from the barcode's rings.
        for (rows_u, out) in [(&st.white_u, &mut st.white), (&st.black_u, &mut st.black)] {
            out.iter_mut().for_each(|v| *v = 0.0);
            for &u in rows_u.iter() {
                let lp = st.knots.at(position + u);
                for (o, &(d, ..)) in out.iter_mut().zip(&st.phase_delta) {
                    let (x, y) = lp.offset(0.0, lp.radius_px * d.sin());
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
        let min_span = 0.2 * contrast;
        let (mut ss, mut cc, mut sw, mut sv) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let sigma = self.calib.enhanced.phase_sign as f64;
        // First pass: weighted mean; second: DFT of the mean-free signal. Both from the same
        // samples, stored on the stack in two passes over rows.
        let rows = [-0.25, 0.0, 0.25];
        let mut sum_ws = 0.0f64;
        let mut sum_wc = 0.0f64;
        for r in rows {
            let lp: LinePoint = st.knots.at(position + c0 + r * m.bit_space_mm());
            for (j, &(d, w, sd, cd)) in st.phase_delta.iter().enumerate() {
                let (x, y) = lp.offset(0.0, lp.radius_px * d.sin());
                let raw = frame.luma_bilinear(x as f32, y as f32) as f64;
                // Normalised to the print's own white (1) and black (0) at this angle.
                let v = (raw - st.black[j]) / (st.white[j] - st.black[j]).max(min_span);
                sv += w * v;
                sw += w;
                ss += w * v * sd;
                cc += w * v * cd;
                sum_ws += w * sd;
                sum_wc += w * cd;
            }
        }
        let mean = sv / sw.max(1e-9);
        let ss = ss - mean * sum_ws;
        let cc = cc - mean * sum_wc;
        let phi = ss.atan2(cc);
        let amplitude = 2.0 * (ss * ss + cc * cc).sqrt() / sw.max(1e-9);
        // A square wave between 0 and 1 has a fundamental of amplitude 2/pi.
        let amp_ratio = amplitude / (2.0 / std::f64::consts::PI);
        let frac4 = (4.0 * ((-sigma * phi) / TAU).rem_euclid(1.0)
            + self.calib.enhanced.phase_offset_steps)
            .rem_euclid(4.0);
        let steps = m.steps();
        let theta = fuse_steps(frac4, alpha, steps);
        let angle =
            (theta * TAU / steps as f64 - self.calib.enhanced.angle_offset_rad).rem_euclid(TAU);
        // 6. Consistency and status.
        let code_dist = {
            let d = (theta - (alpha as f64 + 0.5)).rem_euclid(steps as f64);
            d.min(steps as f64 - d)
        };
        let near_group_edge = !(0.75..=3.25).contains(&frac4);
        let mut status = Status::Ok;
        let mut reason = "";
        if amp_ratio < 0.25 {
            status = Status::Occluded;
            reason = "weak stripes over bit space 0";
        }
        if edge_std > 0.2 * cell {
            status = Status::Occluded;
            reason = "barcode edges inconsistent";
        }
        if min_high_margin < 0.35 && !near_group_edge {
            status = Status::Occluded;
            reason = "a high Gray bit is ambiguous";
        }
        if code_dist > 1.5 {
            status = Status::Occluded;
            reason = "Gray code and phase disagree";
        }
        let q_ncc = ((ncc - 0.5) / 0.45).clamp(0.0, 1.0);
        let q_amp = amp_ratio.clamp(0.0, 1.0);
        let q_edge = (1.0 - edge_std / (0.2 * cell)).clamp(0.0, 1.0);
        let q_code = (1.0 - (code_dist - 0.5).max(0.0)).clamp(0.0, 1.0);
        let quality = (q_ncc * q_amp * q_edge * q_code).powf(0.25);
        RodResult {
            position_mm: position,
            angle_rad: angle,
            quality: if status == Status::Ok {
                quality
            } else {
                quality.min(0.3)
            },
            status,
            gray_step: alpha,
            theta_steps: theta,
            ncc,
            reason,
            amp_ratio,
            edge_std_mm: edge_std,
        }
    }
}

/// Fuses a phase fraction `frac4` in `[0, 4)` (position inside a group of 4 Gray steps) with
/// the decoded step `alpha`, by the paper's steps 2-4. Returns `[0, steps)`.
pub fn fuse_steps(frac4: f64, alpha: u32, steps: u32) -> f64 {
    let alpha_p = (alpha & !3) as f64;
    let d = frac4 + alpha_p - alpha as f64;
    let j = (-d / 4.0).round();
    (frac4 + alpha_p + 4.0 * j).rem_euclid(steps as f64)
}
