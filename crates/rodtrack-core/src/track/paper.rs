//! The paper's mode (the baseline), exactly as published: nearest-pixel line, band-pass and
//! hysteresis, NCC, the Gray bits at fixed offsets and the phase across one row.

use super::result::RodResult;
use crate::angle::wrap_2pi;
use crate::calib::PaperParams;
use crate::decode::{decode_bits, paper_fuse, paper_phase, paper_threshold};
use crate::frame::FrameView;
use crate::line::PaperLine;
use crate::marker::Marker;
use crate::measurement::Status;
use crate::signal::{argmax_sq, hysteresis, ncc_direct, paper_bandpass, PAPER_HYSTERESIS};
use std::f64::consts::TAU;

/// The paper mode's line table and scratch buffers.
#[derive(Debug, Clone)]
pub(super) struct PaperState {
    line: PaperLine,
    kernel_px: Vec<f32>,
    raw: Vec<f32>,
    filtered: Vec<f32>,
    binary: Vec<f32>,
    corr: Vec<f32>,
    d: Vec<f32>,
}

impl PaperState {
    /// The line table and the pixel kernel of a rod with the paper parameters `p`, in frames
    /// `height` rows high.
    pub(super) fn new(p: &PaperParams, marker: &Marker, height: usize) -> PaperState {
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
    }
}

impl PaperState {
    /// Measures the rod in one frame by the paper's steps 1-5, with its paper parameters `p`
    /// and the calibrated position of the reference pose.
    pub(super) fn process(
        &mut self,
        p: &PaperParams,
        marker: &Marker,
        reference_position_mm: f64,
        frame: &FrameView,
    ) -> RodResult {
        let st = self;
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
        let bits = marker.bits() as usize;
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
        let steps = marker.steps();
        let theta = paper_fuse(phi, p.phase_offset_rad as f32, alpha, steps) as f64;
        let angle = wrap_2pi(theta * TAU / steps as f64 - p.angle_offset_rad);
        let position = p.direction as f64 * (pm - p.zero_px) * p.mm_per_px + reference_position_mm;
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
}
