//! One marker's print as data: filled rectangles in marker coordinates, mm.

use crate::PrintOptions;
use rodtrack_core::marker::{gray_bit, Marker};
use std::f64::consts::PI;

#[cfg(doc)]
use crate::Page;

/// Grey level of the glue strip's fill (0 black, 1 white).
const GLUE_GREY: f64 = 0.85;

/// What a filled rectangle of the print is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RectKind {
    /// A run of black barcode cells (a full ring on the rod).
    BarcodeBar,
    /// A black run of Gray bit `bit` around the rod.
    GrayStripe {
        /// The bit space.
        bit: u32,
    },
    /// The glue strip (grey; hatched by the page layout).
    Glue,
    /// A black check bar (not part of the marker).
    CheckBar,
}

impl RectKind {
    /// Fill grey level: 0 black, 1 white.
    pub fn grey(self) -> f64 {
        match self {
            RectKind::Glue => GLUE_GREY,
            _ => 0.0,
        }
    }
    /// True for the marker's black pattern (barcode and Gray code).
    pub fn is_pattern(self) -> bool {
        matches!(self, RectKind::BarcodeBar | RectKind::GrayStripe { .. })
    }
}

/// A filled axis-aligned rectangle, mm. In [`marker_geometry`] `x_mm` is the arc length around
/// the rod from `psi = 0` (`x_mm = psi * radius`) and `y_mm` is `u`; on a [`Page`] both are page
/// coordinates from the top-left corner, `y` down.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    /// Left edge, mm.
    pub x_mm: f64,
    /// Top edge, mm.
    pub y_mm: f64,
    /// Width, mm.
    pub w_mm: f64,
    /// Height, mm.
    pub h_mm: f64,
    /// What it is.
    pub kind: RectKind,
}

impl Rect {
    /// True if the point lies inside (left/top edges included, right/bottom excluded).
    pub fn contains(&self, x_mm: f64, y_mm: f64) -> bool {
        x_mm >= self.x_mm
            && x_mm < self.x_mm + self.w_mm
            && y_mm >= self.y_mm
            && y_mm < self.y_mm + self.h_mm
    }
    pub(crate) fn shifted(mut self, dx: f64, dy: f64) -> Rect {
        self.x_mm += dx;
        self.y_mm += dy;
        self
    }
}

/// The rod's circumference, the printed width of the pattern: `pi * rod_diameter_mm`.
pub fn circumference_mm(marker: &Marker) -> f64 {
    PI * marker.spec().rod_diameter_mm
}

/// The print of one marker as filled rectangles in marker coordinates (see [`Rect`]): the glue
/// strip (if any) at `x` in `[-glue_mm, 0)`, then the barcode bars (adjacent black cells merged)
/// and the Gray stripes (adjacent black steps of one bit merged), all within
/// `[0, circumference) x [0, length)`. Everything else is white. Black here is exactly where
/// [`Marker::is_black`] is true at `psi = x / radius`.
pub fn marker_geometry(marker: &Marker, opts: &PrintOptions) -> Vec<Rect> {
    let c = circumference_mm(marker);
    let len = marker.length_mm();
    let mut out = Vec::new();
    if opts.glue_mm > 0.0 {
        out.push(Rect {
            x_mm: -opts.glue_mm,
            y_mm: 0.0,
            w_mm: opts.glue_mm,
            h_mm: len,
            kind: RectKind::Glue,
        });
    }
    let kernel = marker.kernel();
    let (b0, cell) = (marker.barcode_start_mm(), marker.cell_mm());
    for (i, j) in black_runs(kernel.len(), |i| kernel[i]) {
        out.push(Rect {
            x_mm: 0.0,
            y_mm: b0 + i as f64 * cell,
            w_mm: c,
            h_mm: (j - i) as f64 * cell,
            kind: RectKind::BarcodeBar,
        });
    }
    let steps = marker.steps();
    let step_mm = c / steps as f64;
    for bit in 0..marker.bits() {
        let y = marker.gray_start_mm() + bit as f64 * marker.bit_space_mm();
        for (n0, n1) in black_runs(steps as usize, |n| gray_bit(n as u32, bit)) {
            out.push(Rect {
                x_mm: n0 as f64 * step_mm,
                y_mm: y,
                w_mm: (n1 - n0) as f64 * step_mm,
                h_mm: marker.bit_space_mm(),
                kind: RectKind::GrayStripe { bit },
            });
        }
    }
    out
}

/// Half-open index ranges `[i, j)` of maximal runs where `black(i)` holds.
fn black_runs(n: usize, black: impl Fn(usize) -> bool) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut i = 0;
    while i < n {
        if black(i) {
            let mut j = i + 1;
            while j < n && black(j) {
                j += 1;
            }
            runs.push((i, j));
            i = j;
        } else {
            i += 1;
        }
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers() {
        assert_eq!(
            black_runs(6, |i| [1, 1, 0, 1, 0, 1][i] == 1),
            [(0, 2), (3, 4), (5, 6)]
        );
    }
}
