//! Automatic calibration: find markers in a frame without clicks, and path points from a
//! recording in which each rod sweeps its travel.
//!
//! The barcode's rings look the same at every rotation, so a marker shows up in the luminance
//! along any image line that crosses its axis. [`find_markers`] scans image columns (for rods
//! along image rows) or rows, correlates each profile with the kernel at several scales and in
//! both directions (O(samples x cells) with prefix sums), and groups the hits of neighbouring
//! lines into one marker each: its barcode centre, direction and scale.

use crate::frame::FrameView;
use crate::marker::Marker;
use crate::signal::{ncc_cells_prefix, prefix_sums};

/// One scan line's best hit: (line, barcode centre along the line, direction, cell px, NCC).
type Hit = (usize, f64, i32, f64, f64);

/// A marker found in a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FoundMarker {
    /// Barcode centre, image x, px.
    pub x_px: f64,
    /// Barcode centre, image y, px.
    pub y_px: f64,
    /// +1 when the marker's `u` (barcode to Gray code) runs towards larger image coordinates
    /// along the scan, -1 otherwise.
    pub direction: i32,
    /// Barcode cell length along the scan, px.
    pub cell_px: f64,
    /// Correlation peak.
    pub ncc: f64,
    /// True when the centre across the rod was refined on the silhouette of the barcode's
    /// white rings (else it is the middle of the scan lines that saw the barcode, +/- 1 px).
    pub refined: bool,
}

/// Finds the markers in a frame. `along_rows`: rods run along image rows (the scan lines are
/// image columns). Markers whose correlation stays below `min_ncc` are ignored.
pub fn find_markers(
    frame: &FrameView,
    marker: &Marker,
    along_rows: bool,
    min_ncc: f64,
) -> Vec<FoundMarker> {
    find_markers_in(
        frame,
        marker,
        along_rows,
        min_ncc,
        0..usize::MAX,
        (3.0, 16.0),
    )
}

/// [`find_markers`] over the scan lines `lines` only (image columns for rods along rows, else
/// rows; clamped to the frame) and barcode cells of `cell_px_range.0` to `cell_px_range.1` px: where a
/// marker is already roughly known (a rod's line in a sweep), an order of magnitude faster.
pub fn find_markers_in(
    frame: &FrameView,
    marker: &Marker,
    along_rows: bool,
    min_ncc: f64,
    lines: std::ops::Range<usize>,
    cell_px_range: (f64, f64),
) -> Vec<FoundMarker> {
    let (n_lines, len) = if along_rows {
        (frame.width(), frame.height())
    } else {
        (frame.height(), frame.width())
    };
    let lines = lines.start.max(2)..lines.end.min(n_lines.saturating_sub(2));
    let cells: Vec<f32> = marker
        .kernel()
        .iter()
        .map(|&b| if b { 0.0 } else { 1.0 })
        .collect();
    let rev: Vec<f32> = cells.iter().rev().copied().collect();
    let mut profile = vec![0.0f32; len];
    let mut resampled = Vec::with_capacity(len);
    let mut p1 = Vec::with_capacity(len + 1);
    let mut p2 = Vec::with_capacity(len + 1);
    let mut corr = Vec::new();
    // (line, position of barcode centre, direction, cell px, ncc)
    let mut hits: Vec<Hit> = Vec::new();
    let step = 2;
    let cell_len = 4usize;
    for line in lines.step_by(step) {
        for (t, v) in profile.iter_mut().enumerate() {
            let (x, y) = if along_rows { (line, t) } else { (t, line) };
            *v = frame.luma_nearest(x as f32, y as f32);
        }
        let mut best: Option<(f64, i32, f64, f64)> = None;
        // Cells of 3 to 16 px (by default), 3 % apart: the profile is resampled so a cell is
        // 4 samples.
        let mut cell_px = cell_px_range.0.max(1.0);
        while cell_px <= cell_px_range.1 {
            let ds = cell_px / cell_len as f64;
            let n_s = ((len - 1) as f64 / ds) as usize;
            resampled.clear();
            for i in 0..n_s {
                let t = i as f64 * ds;
                let t0 = t as usize;
                let f = (t - t0 as f64) as f32;
                let a = profile[t0];
                let b = profile[(t0 + 1).min(len - 1)];
                resampled.push(a + (b - a) * f);
            }
            let n = cells.len() * cell_len;
            if n + 1 < n_s {
                p1.resize(n_s + 1, 0.0);
                p2.resize(n_s + 1, 0.0);
                prefix_sums(&resampled, &mut p1, &mut p2);
                corr.resize(n_s - n + 1, 0.0);
                for (dir, kernel) in [(1, &cells), (-1, &rev)] {
                    ncc_cells_prefix(kernel, cell_len, &p1, &p2, &mut corr);
                    for (k, &c) in corr.iter().enumerate() {
                        if c as f64 >= min_ncc && best.is_none_or(|b| c as f64 > b.3) {
                            best = Some(((k as f64 + 0.5 * n as f64) * ds, dir, cell_px, c as f64));
                        }
                    }
                }
            }
            cell_px *= 1.03;
        }
        // One hit per line is enough to find rods that are far apart along the scan; a second
        // marker on the same line (rods crossing the scan twice) is not expected.
        if let Some((pos, dir, cell, c)) = best {
            hits.push((line, pos, dir, cell, c));
        }
    }
    // Group hits of neighbouring lines with close positions.
    let mut groups: Vec<Vec<Hit>> = Vec::new();
    for h in hits {
        match groups.iter_mut().find(|g| {
            let last = g[g.len() - 1];
            h.0 - last.0 <= 3 * step && (h.1 - last.1).abs() < 3.0 * h.3 && h.2 == last.2
        }) {
            Some(g) => g.push(h),
            None => groups.push(vec![h]),
        }
    }
    groups
        .into_iter()
        .filter(|g| g.len() >= 3)
        .map(|g| {
            // The rod's centre: the middle of the lines where the correlation is within 10 % of
            // its best (the barcode is as wide as the rod).
            let best = g.iter().map(|h| h.4).fold(0.0, f64::max);
            let strong: Vec<_> = g.iter().filter(|h| h.4 >= 0.9 * best).collect();
            let line = strong.iter().map(|h| h.0 as f64).sum::<f64>() / strong.len() as f64;
            let pos = strong.iter().map(|h| h.1).sum::<f64>() / strong.len() as f64;
            let cell = strong.iter().map(|h| h.3).sum::<f64>() / strong.len() as f64;
            let (mut x_px, mut y_px) = if along_rows { (line, pos) } else { (pos, line) };
            // Refine across the rod with the silhouette of the barcode's widest white ring.
            let dir = g[0].2 as f64;
            let u_ring = crate::track::ring_rows(marker);
            let centre_u = marker.barcode_start_mm() + 0.5 * marker.barcode_len_mm();
            let px_per_mm = cell / marker.cell_mm();
            let mut offs = Vec::new();
            for u in u_ring
                .iter()
                .filter(|u| **u < centre_u + marker.barcode_len_mm() * 0.5)
            {
                let along = dir * (u - centre_u) * px_per_mm;
                let (tx, ty) = if along_rows { (0.0, 1.0) } else { (1.0, 0.0) };
                let lp = crate::line::LinePoint {
                    x: x_px + tx * along,
                    y: y_px + ty * along,
                    tx,
                    ty,
                    radius_px: marker.radius_mm() * px_per_mm,
                    px_per_mm,
                };
                if let Some((c, _)) = crate::track::ring_silhouette(frame, &lp) {
                    offs.push(c);
                }
            }
            let refined = !offs.is_empty();
            if refined {
                let c = offs.iter().sum::<f64>() / offs.len() as f64;
                // The normal of a line along +y is (-1, 0); along +x it is (0, 1).
                if along_rows {
                    x_px -= c;
                } else {
                    y_px += c;
                }
            }
            FoundMarker {
                x_px,
                y_px,
                direction: g[0].2,
                cell_px: cell,
                ncc: best,
                refined,
            }
        })
        .collect()
}

/// Path points of one rod from the markers found in many frames of a sweep: detections of the
/// rod are those whose line coordinate (image x for rods along rows) lies within `tolerance_px`
/// of `line_px`; returns their barcode centres, the rod's path.
pub fn path_points_from_sweep(
    detections: &[FoundMarker],
    line_px: f64,
    along_rows: bool,
    tolerance_px: f64,
) -> Vec<[f64; 2]> {
    let mut pts: Vec<[f64; 2]> = detections
        .iter()
        .filter(|d| {
            let l = if along_rows { d.x_px } else { d.y_px };
            (l - line_px).abs() <= tolerance_px
        })
        .map(|d| [d.x_px, d.y_px])
        .collect();
    pts.sort_by(|a, b| {
        let (ka, kb) = if along_rows {
            (a[1], b[1])
        } else {
            (a[0], b[0])
        };
        ka.total_cmp(&kb)
    });
    pts
}
