//! What the live view draws over a frame for one rod, computed from the tracker's line (knots)
//! and the frame's result. Coordinates are full-resolution pixels.
//!
//! A live frame's overlays are computed on the tracking thread, so their constant part is
//! computed once per rod ([`RodGeometry`], per camera [`CameraOverlays`]): the sampling line as
//! drawn is shared by every frame's overlay ([`LinePx`], a reference-counted slice), and the
//! marker's points come from a compact copy of the knots. A frame's overlay then holds no heap
//! memory of its own ([`BitOverlays`] is a fixed array), and filling or copying one allocates
//! nothing ([`RodOverlay`]'s `clone_from` keeps the line when it is the same one). The JSON the
//! page gets is the same as with plain vectors.

use rodtrack_core::{gray, RodResult, RodTracker, Status};
use serde::ser::SerializeSeq;
use serde::{Serialize, Serializer};
use std::ops::Deref;
use std::sync::Arc;

/// Most points kept of a rod's sampling line.
const MAX_LINE_POINTS: usize = 48;
/// Most Gray bits of a marker (markers have 1 to 8).
pub const MAX_BITS: usize = 8;
/// Half-angle of the phase window across the rod, seen from the facing line (the enhanced
/// mode's samples span whole stripe periods within +/- 70 degrees).
const PHASE_HALF_ANGLE_DEG: f64 = 70.0;

/// A rod's sampling line as drawn (its knots, decimated), px: computed once per rod and shared
/// by the overlays of every frame (cloning it is a reference count; serialised as a plain list
/// of points).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LinePx(Arc<[[f32; 2]]>);

impl LinePx {
    /// True when both are the same shared line (not only equal points).
    pub fn same(&self, other: &LinePx) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
    /// Takes `source`'s line, without touching the reference counts when it is the same one.
    fn assign(&mut self, source: &LinePx) {
        if !self.same(source) {
            self.0 = source.0.clone();
        }
    }
}

impl Deref for LinePx {
    type Target = [[f32; 2]];
    fn deref(&self) -> &[[f32; 2]] {
        &self.0
    }
}

impl From<Vec<[f32; 2]>> for LinePx {
    fn from(points: Vec<[f32; 2]>) -> LinePx {
        LinePx(points.into())
    }
}

impl Serialize for LinePx {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

/// One Gray bit space: where it is sampled and the bit the decoded step says it holds.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct BitOverlay {
    /// Sample centre, px.
    pub centre_px: [f32; 2],
    /// The decoded bit (black print).
    pub black: bool,
}

/// The Gray bit spaces of a marker, bit 0 first: at most [`MAX_BITS`], in place (no heap).
/// Serialised as a plain list.
#[derive(Debug, Clone, Copy, Default)]
pub struct BitOverlays {
    len: u8,
    bits: [BitOverlay; MAX_BITS],
}

impl BitOverlays {
    /// Appends a bit; returns false (and keeps the bits) when [`MAX_BITS`] are there already.
    pub fn push(&mut self, bit: BitOverlay) -> bool {
        match self.bits.get_mut(self.len as usize) {
            Some(slot) => {
                *slot = bit;
                self.len += 1;
                true
            }
            None => false,
        }
    }
}

impl Deref for BitOverlays {
    type Target = [BitOverlay];
    fn deref(&self) -> &[BitOverlay] {
        &self.bits[..self.len as usize]
    }
}

impl PartialEq for BitOverlays {
    fn eq(&self, other: &BitOverlays) -> bool {
        **self == **other
    }
}

/// The first [`MAX_BITS`] bits; any more are dropped.
impl FromIterator<BitOverlay> for BitOverlays {
    fn from_iter<I: IntoIterator<Item = BitOverlay>>(iter: I) -> BitOverlays {
        let mut b = BitOverlays::default();
        for bit in iter.into_iter().take(MAX_BITS) {
            b.push(bit);
        }
        b
    }
}

impl Serialize for BitOverlays {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut seq = s.serialize_seq(Some(self.len()))?;
        for b in self.iter() {
            seq.serialize_element(b)?;
        }
        seq.end()
    }
}

/// Geometry of the marker found in the frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MarkerOverlay {
    /// Start and end of the whole marker on the line, px.
    pub marker_px: [[f32; 2]; 2],
    /// Start and end of the barcode on the line, px.
    pub barcode_px: [[f32; 2]; 2],
    /// The Gray bit spaces, bit 0 first.
    pub bits: BitOverlays,
    /// The phase window: the segment across the rod over bit space 0, px.
    pub phase_window_px: [[f32; 2]; 2],
    /// Apparent rod radius at the marker, px.
    pub radius_px: f32,
}

/// Everything the live view draws for one rod in one frame.
#[derive(Debug, PartialEq, Serialize)]
pub struct RodOverlay {
    /// Rod id.
    pub rod: u32,
    /// The result's status (sets the colour).
    pub status: Status,
    /// Why the status is not `ok` (empty when it is).
    pub reason: &'static str,
    /// The rod's sampling line (its knots, decimated), px; shared by every frame's overlay.
    pub line_px: LinePx,
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

impl Clone for RodOverlay {
    fn clone(&self) -> RodOverlay {
        RodOverlay {
            line_px: self.line_px.clone(),
            ..*self
        }
    }
    /// Copies every field; the line only when it is another one (the console's copy of a
    /// frame's overlays then allocates nothing and leaves the line's counts alone).
    fn clone_from(&mut self, source: &RodOverlay) {
        let RodOverlay {
            rod,
            status,
            reason,
            line_px,
            marker,
            position_mm,
            angle_rad,
            quality,
            ncc,
        } = source;
        self.rod = *rod;
        self.status = *status;
        self.reason = reason;
        self.line_px.assign(line_px);
        self.marker = *marker;
        self.position_mm = *position_mm;
        self.angle_rad = *angle_rad;
        self.quality = *quality;
        self.ncc = *ncc;
    }
}

fn pt(x: f64, y: f64) -> [f32; 2] {
    [x as f32, y as f32]
}

/// The constant part of one rod's overlay, from its tracker: the line as drawn, the marker's
/// dimensions and a compact copy of the knots (x, y and radius of a knot side by side, so that
/// placing the marker reads a few cache lines).
#[derive(Debug, Clone)]
pub struct RodGeometry {
    rod: u32,
    line_px: LinePx,
    s0_mm: f64,
    step_mm: f64,
    /// Per knot: x, y, radius, px.
    knots: Vec<[f64; 3]>,
    /// Centres of the Gray bit spaces, mm from the marker's start.
    bit_centres_mm: BitCentres,
    length_mm: f64,
    barcode_mm: [f64; 2],
}

#[derive(Debug, Clone, Copy, Default)]
struct BitCentres {
    len: usize,
    mm: [f64; MAX_BITS],
}

/// A point of the line: position, unit tangent and radius, as [`rodtrack_core::Knots::at`]
/// computes them.
struct At {
    x: f64,
    y: f64,
    tx: f64,
    ty: f64,
    radius_px: f64,
}

impl RodGeometry {
    /// Computes the rod's constant overlay parts (once per rod: the knots never change).
    pub fn new(tracker: &RodTracker) -> RodGeometry {
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
        let m = tracker.marker();
        let mut bit_centres_mm = BitCentres::default();
        for k in 0..m.bits().min(MAX_BITS as u32) {
            bit_centres_mm.mm[k as usize] = m.bit_space_centre_mm(k);
            bit_centres_mm.len += 1;
        }
        RodGeometry {
            rod: tracker.rod(),
            line_px: line_px.into(),
            s0_mm: knots.s0_mm,
            step_mm: knots.step_mm,
            knots: (0..n)
                .map(|i| {
                    [
                        knots.x_px[i],
                        knots.y_px[i],
                        knots.radius_px.get(i).copied().unwrap_or(0.0),
                    ]
                })
                .collect(),
            bit_centres_mm,
            length_mm: m.length_mm(),
            barcode_mm: [
                m.barcode_start_mm(),
                m.barcode_start_mm() + m.barcode_len_mm(),
            ],
        }
    }

    /// The rod id.
    pub fn rod(&self) -> u32 {
        self.rod
    }

    /// The line at axis coordinate `s_mm`, clamped to the knots (at least 2): the same
    /// arithmetic as [`rodtrack_core::Knots::at`].
    fn at(&self, s_mm: f64) -> At {
        let n = self.knots.len();
        let g = ((s_mm - self.s0_mm) / self.step_mm).clamp(0.0, (n - 1) as f64);
        let i = (g.floor() as usize).min(n - 2);
        let f = g - i as f64;
        let (a, b) = (self.knots[i], self.knots[i + 1]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = (dx * dx + dy * dy).sqrt().max(1e-12);
        At {
            x: a[0] + dx * f,
            y: a[1] + dy * f,
            tx: dx / len,
            ty: dy / len,
            radius_px: a[2] + (b[2] - a[2]) * f,
        }
    }

    fn marker(&self, result: &RodResult) -> Option<MarkerOverlay> {
        let placed = result.position_mm.is_finite()
            && self.knots.len() >= 2
            && (result.status == Status::Ok
                || (result.status == Status::Occluded && result.position_mm != 0.0));
        if !placed {
            return None;
        }
        let pos = result.position_mm;
        let at = |u: f64| {
            let p = self.at(pos + u);
            pt(p.x, p.y)
        };
        let code = gray(result.gray_step);
        let centres = &self.bit_centres_mm.mm[..self.bit_centres_mm.len];
        let bits = centres
            .iter()
            .enumerate()
            .map(|(k, &c)| BitOverlay {
                centre_px: at(c),
                black: (code >> k) & 1 == 1,
            })
            .collect();
        let lp = self.at(pos + centres.first().copied().unwrap_or(0.0));
        let half = lp.radius_px * PHASE_HALF_ANGLE_DEG.to_radians().sin();
        // The offsets across the line, as `LinePoint::offset(0, -half)` and `(0, half)`.
        let (ax, ay) = (lp.x + lp.ty * half, lp.y - lp.tx * half);
        let (bx, by) = (lp.x - lp.ty * half, lp.y + lp.tx * half);
        Some(MarkerOverlay {
            marker_px: [at(0.0), at(self.length_mm)],
            barcode_px: [at(self.barcode_mm[0]), at(self.barcode_mm[1])],
            bits,
            phase_window_px: [pt(ax, ay), pt(bx, by)],
            radius_px: lp.radius_px as f32,
        })
    }

    /// The rod's overlay for the result of the frame shown. The marker is drawn when the result
    /// carries a position (status `ok`, or `occluded` after the barcode was placed); its Gray
    /// bits are those of the decoded step.
    pub fn overlay(&self, result: &RodResult) -> RodOverlay {
        RodOverlay {
            rod: self.rod,
            status: result.status,
            reason: result.reason,
            line_px: self.line_px.clone(),
            marker: self.marker(result),
            position_mm: finite(result.position_mm),
            angle_rad: finite(result.angle_rad),
            quality: finite(result.quality),
            ncc: finite(result.ncc),
        }
    }

    /// Like [`RodGeometry::overlay`], into an existing overlay (its line is kept when it is
    /// this rod's already: no allocation, no reference count).
    pub fn write(&self, result: &RodResult, out: &mut RodOverlay) {
        out.rod = self.rod;
        out.status = result.status;
        out.reason = result.reason;
        out.line_px.assign(&self.line_px);
        out.marker = self.marker(result);
        out.position_mm = finite(result.position_mm);
        out.angle_rad = finite(result.angle_rad);
        out.quality = finite(result.quality);
        out.ncc = finite(result.ncc);
    }
}

/// The constant overlay parts of one camera's rods ([`RodGeometry`], the trackers' order):
/// build it once with the camera's pipeline, then [`CameraOverlays::fill`] for every live frame.
#[derive(Debug, Clone, Default)]
pub struct CameraOverlays {
    rods: Vec<RodGeometry>,
}

impl CameraOverlays {
    /// From the camera's rod trackers (`CameraPipeline::rods`).
    pub fn new(trackers: &[RodTracker]) -> CameraOverlays {
        CameraOverlays {
            rods: trackers.iter().map(RodGeometry::new).collect(),
        }
    }

    /// The rods' geometry.
    pub fn rods(&self) -> &[RodGeometry] {
        &self.rods
    }

    /// Writes the overlays of one frame's results (`CameraPipeline::last_results`, one per rod
    /// in the trackers' order) into `out`, reusing its entries: once `out` holds this camera's
    /// overlays, a frame allocates nothing.
    pub fn fill(&self, results: &[RodResult], out: &mut Vec<RodOverlay>) {
        let n = self.rods.len().min(results.len());
        out.truncate(n);
        for (i, (g, r)) in self.rods.iter().zip(results).enumerate() {
            match out.get_mut(i) {
                Some(o) => g.write(r, o),
                None => out.push(g.overlay(r)),
            }
        }
    }
}

/// The overlay of one rod from its tracker and the result of the frame shown (computes the
/// rod's [`RodGeometry`] each time: for every frame, keep a [`CameraOverlays`]).
pub fn overlays_for(tracker: &RodTracker, result: &RodResult) -> RodOverlay {
    RodGeometry::new(tracker).overlay(result)
}

fn finite(v: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}
