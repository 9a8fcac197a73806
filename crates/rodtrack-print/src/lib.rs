//! The printable marker (SPEC section 3) at exact physical size, as vector SVG and PDF.
//!
//! # What is printed
//!
//! One marker is a rectangle as wide as the rod's circumference (`pi * rod_diameter_mm`) and as
//! long as the marker ([`Marker::length_mm`]); `u` (along the rod) runs down the page's long
//! axis, from the barcode (top) to the Gray code (bottom); `psi` (around the rod) runs across,
//! from `psi = 0` at the left cut edge to `psi = 2 pi` at the right one. Barcode cells are
//! full-width black bars (adjacent black cells merged), each Gray bit space `k` holds one black
//! bar per black run of bit `k` of `gray(n)` over the steps `n`, quiet zones and the gap are
//! white. Left of `psi = 0` lies an optional glue strip (hatched grey): it is stuck to the rod
//! first and the `psi = 2 pi` end overlaps it. Crop marks sit outside the corners of the whole
//! strip (glue included) and a tick marks `psi = 0`.
//!
//! Each page also carries the rod id and the marker's parameters above each marker, the
//! instruction "print at 100 %, no scaling", the wrap rule ([`WRAP_RULE`]) and a 10 mm check bar
//! in both directions.
//!
//! # Wrap direction
//!
//! Wrap the strip print side out, glue strip first. Then, seen from the barcode end of the rod
//! (looking along `u` towards the Gray code), `psi` grows counter-clockwise; a right-handed turn
//! of the rod about `u` is clockwise in that view and brings growing `psi` under the camera: at
//! rod angle `theta` the surface line facing the camera reads `psi = theta + const`, the
//! convention of [`rodtrack_core::marker`] and SPEC section 2. Any wrap of this page with the
//! print outside has this handedness (a strip printed mirrored, e.g. read through clear film,
//! would have the opposite one). The barcode end is the rod's `-u` end: the rod's position
//! grows when it slides towards the Gray-code end.
//!
//! # Layers
//!
//! [`marker_geometry`] gives one marker's filled rectangles in mm ("geometry as data");
//! [`layout`](fn@layout) places markers, labels and marks on pages as [`Shape`]s;
//! [`svg`](fn@svg), [`svg_pages`] and [`pdf`](fn@pdf) write those pages. The PDF is a minimal
//! hand-written PDF 1.4 (vector rectangles, lines and Helvetica text, uncompressed).
//!
//! Modules: [`geometry`] (one marker as rectangles), [`layout`](mod@layout) (pages of shapes),
//! [`svg`](mod@svg), [`pdf`](mod@pdf) (the writers) and [`text`] (Helvetica metrics, word wrap,
//! number formatting); everything public is re-exported here.

pub mod geometry;
pub mod layout;
pub mod pdf;
pub mod svg;
pub mod text;

pub use geometry::{circumference_mm, marker_geometry, Rect, RectKind};
pub use layout::{layout, Page, Placement, Shape, Text, PRINT_AT_100, WRAP_RULE};
pub use pdf::pdf;
pub use svg::{svg, svg_page, svg_pages};
pub use text::text_width;

use thiserror::Error;

#[cfg(doc)]
use rodtrack_core::marker::Marker;

/// Everything that can stop a marker print.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PrintError {
    /// No marker was asked for.
    #[error("no markers to print")]
    Empty,
    /// A print option is out of range.
    #[error("print option {field}: {reason}")]
    Option {
        /// The option.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A marker does not fit on the page.
    #[error(
        "the marker of rod {rod} needs {width_mm:.1} x {height_mm:.1} mm with its labels and \
         crop marks; it does not fit on the {page_width_mm:.1} x {page_height_mm:.1} mm page \
         (use a larger page or the fitted page)"
    )]
    TooLarge {
        /// The rod.
        rod: u32,
        /// Width needed, mm.
        width_mm: f64,
        /// Height needed, mm.
        height_mm: f64,
        /// Page width, mm.
        page_width_mm: f64,
        /// Page height, mm.
        page_height_mm: f64,
    },
    /// An SVG file holds one page but the markers need more.
    #[error(
        "the markers need {pages} pages and an SVG holds one: write PDF, use svg_pages, print \
         fewer rods per file, or use the fitted page"
    )]
    MultiPage {
        /// Pages needed.
        pages: usize,
    },
}

/// The page to print on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PageSize {
    /// ISO A4 portrait, 210 x 297 mm; markers that do not fit go on further pages.
    A4,
    /// US Letter portrait, 215.9 x 279.4 mm; markers that do not fit go on further pages.
    Letter,
    /// One page just big enough for all markers (up to 4 per row).
    Fit,
    /// Any page size, portrait or landscape; markers that do not fit go on further pages.
    Custom {
        /// Width, mm.
        width_mm: f64,
        /// Height, mm.
        height_mm: f64,
    },
}

/// How to print.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrintOptions {
    /// Width of the glue strip left of `psi = 0`, mm; 0 for none.
    pub glue_mm: f64,
    /// The page.
    pub page: PageSize,
}

impl Default for PrintOptions {
    fn default() -> Self {
        PrintOptions {
            glue_mm: 5.0,
            page: PageSize::A4,
        }
    }
}

impl PrintOptions {
    fn check(&self) -> Result<(), PrintError> {
        if !(self.glue_mm.is_finite() && (0.0..=50.0).contains(&self.glue_mm)) {
            return Err(PrintError::Option {
                field: "glue_mm",
                reason: format!("must be 0 to 50 mm, got {}", self.glue_mm),
            });
        }
        if let PageSize::Custom {
            width_mm,
            height_mm,
        } = self.page
        {
            for (field, v) in [("page width_mm", width_mm), ("page height_mm", height_mm)] {
                if !(v.is_finite() && v > 0.0 && v <= 10_000.0) {
                    return Err(PrintError::Option {
                        field,
                        reason: format!("must be a positive size up to 10 m, got {v}"),
                    });
                }
            }
        }
        Ok(())
    }
}
