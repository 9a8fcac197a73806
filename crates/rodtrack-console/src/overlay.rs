//! What the live view draws over a frame for one rod, computed from the tracker's line (knots)
//! and the frame's result. Coordinates are full-resolution pixels.

use rodtrack_core::{gray, RodResult, RodTracker, Status};
use serde::Serialize;

/// Most points kept of a rod's sampling line.
const MAX_LINE_POINTS: usize = 48;
/// Half-angle of the phase window across the rod, seen from the facing line (the enhanced
/// mode's samples span whole stripe periods within +/- 70 degrees).
const PHASE_HALF_ANGLE_DEG: f64 = 70.0;

/// One Gray bit space: where it is sampled and the bit the decoded step says it holds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BitOverlay {
    /// Sample centre, px.
    pub centre_px: [f32; 2],
    /// The decoded bit (black print).
    pub black: bool,
}

/// Geometry of the marker found in the frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerOverlay {
    /// Start and end of the whole marker on the line, px.
    pub marker_px: [[f32; 2]; 2],
    /// Start and end of the barcode on the line, px.
    pub barcode_px: [[f32; 2]; 2],
    /// The Gray bit spaces, bit 0 first.
    pub bits: Vec<BitOverlay>,
    /// The phase window: the segment across the rod over bit space 0, px.
    pub phase_window_px: [[f32; 2]; 2],
    /// Apparent rod radius at the marker, px.
    pub radius_px: f32,
}

/// Everything the live view draws for one rod in one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RodOverlay {
    /// Rod id.
    pub rod: u32,
    /// The result's status (sets the colour).
    pub status: Status,
    /// Why the status is not `ok` (empty when it is).
    pub reason: &'static str,
    /// The rod's sampling line (its knots, decimated), px.
    pub line_px: Vec<[f32; 2]>,
    /// The marker, when the result places it on the line.
    pub marker: Option<MarkerOverlay>,
    /// Position, mm.
    pub position_mm: f64,
    /// Angle, rad.
    pub angle_rad: f64,
    /// Quality in `[0, 1]`.
    pub quality: f64,
    /// Barcode correlation peak.
    pub ncc: f64,
}

fn pt(x: f64, y: f64) -> [f32; 2] {
    [x as f32, y as f32]
}

/// The overlay of one rod from its tracker and the result of the frame shown. The marker is
/// drawn when the result carries a position (status `ok`, or `occluded` after the barcode was
/// placed); its Gray bits are those of the decoded step.
pub fn overlays_for(tracker: &RodTracker, result: &RodResult) -> RodOverlay {
    let knots = tracker.knots();
    let n = knots.len();
    let step = n.div_ceil(MAX_LINE_POINTS).max(1);
    let mut line_px: Vec<[f32; 2]> = (0..n)
        .step_by(step)
        .map(|i| pt(knots.x_px[i], knots.y_px[i]))
        .collect();
    if n > 0 && (n - 1) % step != 0 {
        line_px.push(pt(knots.x_px[n - 1], knots.y_px[n - 1]));
    }
    let placed = result.position_mm.is_finite()
        && n >= 2
        && (result.status == Status::Ok
            || (result.status == Status::Occluded && result.position_mm != 0.0));
    let marker = placed.then(|| {
        let m = tracker.marker();
        let pos = result.position_mm;
        let at = |u: f64| {
            let p = knots.at(pos + u);
            pt(p.x, p.y)
        };
        let code = gray(result.gray_step);
        let bits = (0..m.bits())
            .map(|k| BitOverlay {
                centre_px: at(m.bit_space_centre_mm(k)),
                black: (code >> k) & 1 == 1,
            })
            .collect();
        let lp = knots.at(pos + m.bit_space_centre_mm(0));
        let half = lp.radius_px * PHASE_HALF_ANGLE_DEG.to_radians().sin();
        let (ax, ay) = lp.offset(0.0, -half);
        let (bx, by) = lp.offset(0.0, half);
        MarkerOverlay {
            marker_px: [at(0.0), at(m.length_mm())],
            barcode_px: [
                at(m.barcode_start_mm()),
                at(m.barcode_start_mm() + m.barcode_len_mm()),
            ],
            bits,
            phase_window_px: [pt(ax, ay), pt(bx, by)],
            radius_px: lp.radius_px as f32,
        }
    });
    RodOverlay {
        rod: tracker.rod(),
        status: result.status,
        reason: result.reason,
        line_px,
        marker,
        position_mm: finite(result.position_mm),
        angle_rad: finite(result.angle_rad),
        quality: finite(result.quality),
        ncc: finite(result.ncc),
    }
}

fn finite(v: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}
