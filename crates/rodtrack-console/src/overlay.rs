//! What the live view draws over a frame for one rod, computed from the tracker's line (knots)
//! and the frame's result. Coordinates are full-resolution pixels.
//!
//! A live frame's overlays are made on the tracking thread, so they carry only what changes
//! from frame to frame: a [`RodOverlay`] is the result's numbers (status, position, angle,
//! quality, correlation, Gray step) and a shared reference to the rod's constant geometry
//! ([`RodGeometry`], computed once per rod, per camera [`CameraOverlays`]: the sampling line as
//! drawn, the marker's dimensions, a compact copy of the knots). The pixels of the marker (its
//! ends, the barcode, the Gray bit points, the phase window) are computed when the overlay is
//! serialised, on the console's thread. Making or copying a frame's overlays allocates nothing
//! and leaves the geometry's reference counts alone once the vector holds the camera's rods.
//! The JSON the page gets is the same as when everything was computed on the tracking side.

use rodtrack_core::{gray, RodResult, RodTracker, Status};
use serde::ser::{SerializeSeq, SerializeStruct};
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

/// Everything the live view draws for one rod in one frame: the frame's numbers and the rod's
/// shared [`RodGeometry`]; the line and the marker's pixels come from the geometry
/// ([`RodOverlay::line_px`], [`RodOverlay::marker`]; computed when serialised, on the console's
/// thread). Serialised as `{rod, status, reason, line_px, marker, position_mm, angle_rad,
/// quality, ncc}`.
#[derive(Debug, PartialEq)]
pub struct RodOverlay {
    geometry: Arc<RodGeometry>,
    /// The result carries a position the marker can be drawn at (status `ok`, or `occluded`
    /// after the barcode was placed).
    located: bool,
    /// Rod id.
    pub rod: u32,
    /// The result's status (sets the colour).
    pub status: Status,
    /// Why the status is not `ok` (empty when it is).
    pub reason: &'static str,
    /// Position, mm (0 when not finite).
    pub position_mm: f64,
    /// Angle, rad (0 when not finite).
    pub angle_rad: f64,
    /// Quality in `[0, 1]`.
    pub quality: f64,
    /// Barcode correlation peak.
    pub ncc: f64,
    /// The decoded Gray step (the marker's bits show its code).
    pub gray_step: u32,
}

impl RodOverlay {
    /// The overlay of `result` over the rod of `geometry`.
    pub fn new(geometry: Arc<RodGeometry>, result: &RodResult) -> RodOverlay {
        let mut o = RodOverlay {
            geometry,
            located: false,
            rod: 0,
            status: Status::default(),
            reason: "",
            position_mm: 0.0,
            angle_rad: 0.0,
            quality: 0.0,
            ncc: 0.0,
            gray_step: 0,
        };
        o.set(result);
        o
    }

    /// Takes the numbers of `result` (the geometry stays).
    fn set(&mut self, result: &RodResult) {
        self.located = result.position_mm.is_finite()
            && (result.status == Status::Ok
                || (result.status == Status::Occluded && result.position_mm != 0.0));
        self.rod = self.geometry.rod;
        self.status = result.status;
        self.reason = result.reason;
        self.position_mm = finite(result.position_mm);
        self.angle_rad = finite(result.angle_rad);
        self.quality = finite(result.quality);
        self.ncc = finite(result.ncc);
        self.gray_step = result.gray_step;
    }

    /// Points the overlay at `geometry`, touching the reference counts only when it is another
    /// rod's.
    fn set_geometry(&mut self, geometry: &Arc<RodGeometry>) {
        if !Arc::ptr_eq(&self.geometry, geometry) {
            self.geometry = geometry.clone();
        }
    }

    /// The rod's geometry.
    pub fn geometry(&self) -> &Arc<RodGeometry> {
        &self.geometry
    }

    /// The rod's sampling line (its knots, decimated), px.
    pub fn line_px(&self) -> &[[f32; 2]] {
        &self.geometry.line_px
    }

    /// The marker, when the result places it on the line; its Gray bits are those of the
    /// decoded step.
    pub fn marker(&self) -> Option<MarkerOverlay> {
        self.located
            .then(|| self.geometry.marker(self.position_mm, self.gray_step))
            .flatten()
    }
}

impl Clone for RodOverlay {
    fn clone(&self) -> RodOverlay {
        RodOverlay {
            geometry: self.geometry.clone(),
            ..*self
        }
    }
    /// Copies the numbers; the geometry only when it is another rod's (the console's copy of
    /// a frame's overlays then allocates nothing and leaves the reference counts alone).
    fn clone_from(&mut self, source: &RodOverlay) {
        self.set_geometry(&source.geometry);
        let RodOverlay {
            geometry: _,
            located,
            rod,
            status,
            reason,
            position_mm,
            angle_rad,
            quality,
            ncc,
            gray_step,
        } = *source;
        self.located = located;
        self.rod = rod;
        self.status = status;
        self.reason = reason;
        self.position_mm = position_mm;
        self.angle_rad = angle_rad;
        self.quality = quality;
        self.ncc = ncc;
        self.gray_step = gray_step;
    }
}

impl Serialize for RodOverlay {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut st = s.serialize_struct("RodOverlay", 9)?;
        st.serialize_field("rod", &self.rod)?;
        st.serialize_field("status", &self.status)?;
        st.serialize_field("reason", self.reason)?;
        st.serialize_field("line_px", self.line_px())?;
        st.serialize_field("marker", &self.marker())?;
        st.serialize_field("position_mm", &self.position_mm)?;
        st.serialize_field("angle_rad", &self.angle_rad)?;
        st.serialize_field("quality", &self.quality)?;
        st.serialize_field("ncc", &self.ncc)?;
        st.end()
    }
}

fn pt(x: f64, y: f64) -> [f32; 2] {
    [x as f32, y as f32]
}

/// The constant part of one rod's overlay, from its tracker (once per rod: the knots never
/// change): the line as drawn, the marker's dimensions and a compact copy of the knots (x, y
/// and radius of a knot side by side, so that placing the marker reads a few cache lines).
#[derive(Debug, Clone, PartialEq)]
pub struct RodGeometry {
    rod: u32,
    line_px: Vec<[f32; 2]>,
    s0_mm: f64,
    step_mm: f64,
    /// Per knot: x, y, radius, px.
    knots: Vec<[f64; 3]>,
    /// Centres of the Gray bit spaces, mm from the marker's start.
    bit_centres_mm: Vec<f64>,
    length_mm: f64,
    barcode_mm: [f64; 2],
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
    /// The rod's constant overlay parts.
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
        RodGeometry {
            rod: tracker.rod(),
            line_px,
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
            bit_centres_mm: (0..m.bits().min(MAX_BITS as u32))
                .map(|k| m.bit_space_centre_mm(k))
                .collect(),
            length_mm: m.length_mm(),
            barcode_mm: [
                m.barcode_start_mm(),
                m.barcode_start_mm() + m.barcode_len_mm(),
            ],
        }
    }

    /// A rod drawn as the line `line_px` only (no knots: no marker is ever placed on it).
    pub fn line_only(rod: u32, line_px: Vec<[f32; 2]>) -> RodGeometry {
        RodGeometry {
            rod,
            line_px,
            s0_mm: 0.0,
            step_mm: 1.0,
            knots: Vec::new(),
            bit_centres_mm: Vec::new(),
            length_mm: 0.0,
            barcode_mm: [0.0; 2],
        }
    }

    /// The rod id.
    pub fn rod(&self) -> u32 {
        self.rod
    }

    /// The rod's sampling line as drawn, px.
    pub fn line_px(&self) -> &[[f32; 2]] {
        &self.line_px
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

    /// The marker's pixels with its start at `position_mm` on the axis and the Gray code of
    /// `gray_step` (None without knots).
    pub fn marker(&self, position_mm: f64, gray_step: u32) -> Option<MarkerOverlay> {
        if self.knots.len() < 2 {
            return None;
        }
        let at = |u: f64| {
            let p = self.at(position_mm + u);
            pt(p.x, p.y)
        };
        let code = gray(gray_step);
        let bits = self
            .bit_centres_mm
            .iter()
            .enumerate()
            .map(|(k, &c)| BitOverlay {
                centre_px: at(c),
                black: (code >> k) & 1 == 1,
            })
            .collect();
        let lp = self.at(position_mm + self.bit_centres_mm.first().copied().unwrap_or(0.0));
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
}

/// The constant overlay parts of one camera's rods ([`RodGeometry`], the trackers' order):
/// build it once with the camera's pipeline, then [`CameraOverlays::fill`] for every live frame.
#[derive(Debug, Clone, Default)]
pub struct CameraOverlays {
    rods: Vec<Arc<RodGeometry>>,
}

impl CameraOverlays {
    /// From the camera's rod trackers (`CameraPipeline::rods`).
    pub fn new(trackers: &[RodTracker]) -> CameraOverlays {
        CameraOverlays {
            rods: trackers
                .iter()
                .map(|t| Arc::new(RodGeometry::new(t)))
                .collect(),
        }
    }

    /// The rods' geometry.
    pub fn rods(&self) -> &[Arc<RodGeometry>] {
        &self.rods
    }

    /// Writes the overlays of one frame's results (`CameraPipeline::last_results`, one per rod
    /// in the trackers' order) into `out`, reusing its entries: once `out` holds this camera's
    /// overlays, a frame copies the results' numbers and nothing else.
    pub fn fill(&self, results: &[RodResult], out: &mut Vec<RodOverlay>) {
        let n = self.rods.len().min(results.len());
        out.truncate(n);
        for (i, (g, r)) in self.rods.iter().zip(results).enumerate() {
            match out.get_mut(i) {
                Some(o) => {
                    o.set_geometry(g);
                    o.set(r);
                }
                None => out.push(RodOverlay::new(g.clone(), r)),
            }
        }
    }
}

/// The overlay of one rod from its tracker and the result of the frame shown (computes the
/// rod's [`RodGeometry`] each time: for every frame, keep a [`CameraOverlays`]).
pub fn overlays_for(tracker: &RodTracker, result: &RodResult) -> RodOverlay {
    RodOverlay::new(Arc::new(RodGeometry::new(tracker)), result)
}

fn finite(v: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}
