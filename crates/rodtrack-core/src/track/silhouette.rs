//! A ring's silhouette across the rod (where its edges stand against the background), and the
//! marker's rings the tracker and calibration measure it at. Helpers: no tracker state.

use super::tuning::MAX_RINGS;
use crate::frame::FrameView;
use crate::line::LinePoint;
use crate::marker::Marker;

/// Marker `u` of the white rings used to find the rod's silhouette: the middle of the longest
/// white run of the barcode and the gap before the Gray code (next to bit space 0).
pub fn ring_rows(marker: &Marker) -> Vec<f64> {
    let k = marker.kernel();
    let mut rows = Vec::new();
    let mut i = 0;
    let mut best = (0usize, 0usize);
    while i < k.len() {
        if !k[i] {
            let j = (i..k.len()).find(|&j| k[j]).unwrap_or(k.len());
            if j - i > best.1 - best.0 {
                best = (i, j);
            }
            i = j;
        } else {
            i += 1;
        }
    }
    let cell = marker.cell_mm();
    let bc0 = marker.barcode_start_mm();
    for c in best.0..best.1 {
        rows.push(bc0 + (c as f64 + 0.5) * cell);
    }
    let gap0 = bc0 + marker.barcode_len_mm();
    let gap = marker.gray_start_mm() - gap0;
    if gap >= 2.0 {
        rows.push(gap0 + 0.5 * gap);
    }
    rows
}

/// Marker `u` of the full rings whose silhouettes the tracker learns the rod's centre line
/// from, and whether each is white: the middle of every barcode cell, and of the gap before
/// the Gray code when there is one (white). Each is a witness of its own (see [`CentreFit`](super::CentreFit)):
/// the more there are, the fewer of them something beside the rod can sway.
pub fn silhouette_rings(marker: &Marker) -> Vec<(f64, bool)> {
    let cell = marker.cell_mm();
    let bc0 = marker.barcode_start_mm();
    let mut rows: Vec<(f64, bool)> = marker
        .kernel()
        .iter()
        .enumerate()
        .map(|(c, &black)| (bc0 + (c as f64 + 0.5) * cell, !black))
        .collect();
    let gap0 = bc0 + marker.barcode_len_mm();
    let gap = marker.gray_start_mm() - gap0;
    if gap >= 2.0 {
        rows.push((gap0 + 0.5 * gap, true));
    }
    rows.truncate(MAX_RINGS);
    rows
}

/// The tracker's fast scan for a white ring's silhouette: 0.5 px steps over 0.75 R .. 1.35 R.
pub const WHITE_RING_SCAN: SilhouetteScan = SilhouetteScan {
    bright: true,
    step_px: 0.5,
    min_contrast: 20.0,
    from_radii: 0.75,
    span_radii: 0.6,
};

/// The same for a black ring, with the least contrast that calibration's careful scan asks of
/// either polarity (12 DN). Whether the black rings serve is decided by their measured
/// contrast against the white rings' (see [`CentreFit`](super::CentreFit)), not by this floor.
pub const BLACK_RING_SCAN: SilhouetteScan = SilhouetteScan {
    bright: false,
    min_contrast: 12.0,
    ..WHITE_RING_SCAN
};

/// The silhouette of a white ring across the rod at `lp`: (centre offset along the normal,
/// half width), px. Each edge is where the profile crosses halfway between the print inside
/// and the background outside; `None` when the ring does not stand out from the background.
/// The tracker's fast scan: 0.5 px steps over 0.75 R .. 1.35 R.
pub fn ring_silhouette(frame: &FrameView, lp: &LinePoint) -> Option<(f64, f64)> {
    ring_silhouette_scan(frame, lp, &WHITE_RING_SCAN)
}

/// How [`ring_silhouette_scan`] looks for a ring's edges.
#[derive(Debug, Clone, Copy)]
pub struct SilhouetteScan {
    /// A white ring (brighter than the background) or a black one (darker).
    pub bright: bool,
    /// Scan step, px.
    pub step_px: f64,
    /// Least difference between the print (at 0.6 R) and the background (at 1.5 R).
    pub min_contrast: f64,
    /// Where the scan for an edge starts, in radii from the line.
    pub from_radii: f64,
    /// How far it goes, in radii.
    pub span_radii: f64,
}

/// The silhouette of a full ring across the rod at `lp`, bright or dark against the
/// background: (centre offset along the normal, half width), px. Each edge is where the
/// profile crosses halfway between the print inside and the background outside.
pub fn ring_silhouette_scan(
    frame: &FrameView,
    lp: &LinePoint,
    scan: &SilhouetteScan,
) -> Option<(f64, f64)> {
    ring_silhouette_measure(frame, lp, scan).map(|m| (m.centre_px, m.half_width_px))
}

/// A ring's silhouette across the rod, from [`ring_silhouette_measure`].
#[derive(Debug, Clone, Copy)]
pub struct RingSilhouette {
    /// Centre offset along the normal, px.
    pub centre_px: f64,
    /// Half width, px.
    pub half_width_px: f64,
    /// The print's contrast with the background, the lesser of the two sides, DN.
    pub contrast_dn: f64,
}

/// [`ring_silhouette_scan`], with the ring's contrast with the background.
pub fn ring_silhouette_measure(
    frame: &FrameView,
    lp: &LinePoint,
    scan: &SilhouetteScan,
) -> Option<RingSilhouette> {
    let r = lp.radius_px;
    let step = scan.step_px;
    let sign = if scan.bright { 1.0 } else { -1.0 };
    let at = |x: f64| {
        let (px, py) = lp.offset(0.0, x);
        sign * frame.luma_bilinear(px as f32, py as f32) as f64
    };
    let mut edge = [0.0f64; 2];
    let mut contrast = f64::MAX;
    for (k, side) in [-1.0f64, 1.0].into_iter().enumerate() {
        let x_out = side * 1.5 * r;
        if !frame.contains(
            (lp.x - lp.ty * x_out) as f32,
            (lp.y + lp.tx * x_out) as f32,
            1.0,
        ) {
            return None;
        }
        let inside = at(side * 0.6 * r);
        let outside = at(x_out);
        if inside - outside < scan.min_contrast {
            return None;
        }
        contrast = contrast.min(inside - outside);
        let level = 0.5 * (inside + outside);
        let x_from = side * scan.from_radii * r;
        let n = ((scan.span_radii * r) / step) as usize;
        let mut prev = (x_from, at(x_from));
        if prev.1 < level {
            return None;
        }
        let mut found = None;
        for i in 1..=n {
            let x = x_from + side * step * i as f64;
            let v = at(x);
            if prev.1 >= level && v < level {
                let f = (prev.1 - level) / (prev.1 - v);
                found = Some(prev.0 + f * (x - prev.0));
                break;
            }
            prev = (x, v);
        }
        edge[k] = found?;
    }
    Some(RingSilhouette {
        centre_px: 0.5 * (edge[0] + edge[1]),
        half_width_px: 0.5 * (edge[1] - edge[0]),
        contrast_dn: contrast,
    })
}
