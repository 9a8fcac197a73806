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
//! [`layout`] places markers, labels and marks on pages as [`Shape`]s; [`svg`], [`svg_pages`]
//! and [`pdf`] write those pages. The PDF is a minimal hand-written PDF 1.4 (vector rectangles,
//! lines and Helvetica text, uncompressed).

use rodtrack_core::marker::{gray_bit, Marker};
use std::f64::consts::PI;
use std::fmt::Write as _;
use thiserror::Error;

/// The wrap rule as printed on every page.
pub const WRAP_RULE: &str = "Wrap print side out, glue strip first; the psi = 2 pi end overlaps \
    the glue strip. u runs from the barcode to the Gray code. Seen from the barcode end, psi grows \
    counter-clockwise: a right-handed turn of the rod about u (clockwise in that view) brings \
    growing psi under the camera (the line facing the camera reads psi = theta + const).";

/// The print-size instruction printed on every page.
pub const PRINT_AT_100: &str = "print at 100 %, no scaling (\"actual size\")";

/// Page margin, mm.
const MARGIN_MM: f64 = 6.0;
/// Gap between a corner of the strip and its crop marks, mm.
const CROP_GAP_MM: f64 = 1.5;
/// Length of a crop mark, mm.
const CROP_LEN_MM: f64 = 3.0;
/// Room for crop marks around a strip, mm.
const CROP_ZONE_MM: f64 = CROP_GAP_MM + CROP_LEN_MM;
/// Gap between neighbouring marker cells, mm.
const CELL_GAP_MM: f64 = 1.0;
/// Font size of the rod id, mm.
const ROD_FONT_MM: f64 = 3.2;
/// Font size of the marker description, mm.
const DESC_FONT_MM: f64 = 2.0;
/// Font size of the page title, mm.
const TITLE_FONT_MM: f64 = 3.2;
/// Font size of the page's instructions, mm.
const NOTE_FONT_MM: f64 = 2.2;
/// Line height / font size.
const LEADING: f64 = 1.3;
/// Width of the check-bar box, mm.
const CHECK_BOX_W_MM: f64 = 40.0;
/// Height of the check-bar box, mm.
const CHECK_BOX_H_MM: f64 = 12.0;
/// Hair line width, mm.
const HAIR_MM: f64 = 0.15;
/// Grey level of the glue strip's fill (0 black, 1 white).
const GLUE_GREY: f64 = 0.85;
/// Grey level of the glue strip's hatching.
const HATCH_GREY: f64 = 0.55;

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
    fn shifted(mut self, dx: f64, dy: f64) -> Rect {
        self.x_mm += dx;
        self.y_mm += dy;
        self
    }
}

/// A line of text; Helvetica, left-aligned at the baseline point.
#[derive(Debug, Clone, PartialEq)]
pub struct Text {
    /// Baseline start x, mm.
    pub x_mm: f64,
    /// Baseline start y, mm.
    pub y_mm: f64,
    /// Font size (em), mm.
    pub size_mm: f64,
    /// Rotation about the baseline start, degrees, clockwise on the page (-90 reads upwards).
    pub angle_deg: f64,
    /// Grey level: 0 black, 1 white.
    pub grey: f64,
    /// The text, ASCII.
    pub text: String,
}

/// One drawing element of a page, mm, `y` down.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// A filled rectangle.
    Rect(Rect),
    /// A straight line with butt caps.
    Line {
        /// Start x, mm.
        x0_mm: f64,
        /// Start y, mm.
        y0_mm: f64,
        /// End x, mm.
        x1_mm: f64,
        /// End y, mm.
        y1_mm: f64,
        /// Stroke width, mm.
        width_mm: f64,
        /// Grey level: 0 black, 1 white.
        grey: f64,
    },
    /// A filled polygon (arrow heads).
    Polygon {
        /// Corners, mm.
        points_mm: Vec<(f64, f64)>,
        /// Grey level: 0 black, 1 white.
        grey: f64,
    },
    /// Text.
    Text(Text),
}

/// Where a marker landed on a page.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// The rod.
    pub rod: u32,
    /// Page x of the marker's `psi = 0` edge, mm.
    pub x_mm: f64,
    /// Page y of the marker's start (`u = 0`), mm.
    pub y_mm: f64,
    /// Circumference (`psi = 2 pi` lies at `x_mm + circumference_mm`), mm.
    pub circumference_mm: f64,
    /// Marker length, mm.
    pub length_mm: f64,
}

/// One laid-out page.
#[derive(Debug, Clone, PartialEq)]
pub struct Page {
    /// Width, mm.
    pub width_mm: f64,
    /// Height, mm.
    pub height_mm: f64,
    /// Drawing elements, painted in order on white.
    pub shapes: Vec<Shape>,
    /// The markers on this page.
    pub markers: Vec<Placement>,
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

/// The description lines printed above a marker (without the rod id).
fn description(marker: &Marker, glue_mm: f64) -> Vec<String> {
    let s = marker.spec();
    let mut size = format!(
        "rod diameter {} mm: {} x {} mm",
        num(s.rod_diameter_mm),
        num2(circumference_mm(marker)),
        num2(marker.length_mm())
    );
    if glue_mm > 0.0 {
        let _ = write!(size, " + {} mm glue", num(glue_mm));
    }
    vec![
        format!(
            "kernel {}, cell {} mm",
            s.barcode.kernel,
            num(s.barcode.cell_mm)
        ),
        format!(
            "Gray code: {} bits, bit space {} mm",
            s.gray_code.bits,
            num(s.gray_code.bit_space_mm)
        ),
        size,
    ]
}

/// A marker's cell on the page: its size and the offsets of the marker inside it.
struct CellPlan {
    width_mm: f64,
    height_mm: f64,
    desc: Vec<String>,
}

impl CellPlan {
    fn new(marker: &Marker, glue_mm: f64) -> CellPlan {
        let wrap_w = glue_mm + circumference_mm(marker);
        let desc: Vec<String> = description(marker, glue_mm)
            .iter()
            .flat_map(|l| wrap_text(l, DESC_FONT_MM, wrap_w))
            .collect();
        CellPlan {
            width_mm: 2.0 * CROP_ZONE_MM + wrap_w,
            height_mm: label_height(desc.len()) + 2.0 * CROP_ZONE_MM + marker.length_mm(),
            desc,
        }
    }
}

/// Height of the label block above a strip's top crop zone, mm.
fn label_height(desc_lines: usize) -> f64 {
    ROD_FONT_MM * 1.2 + desc_lines as f64 * DESC_FONT_MM * LEADING + DESC_FONT_MM * 2.0
}

/// The page header: title, instructions (wrapped), check bars.
struct Header {
    title: Vec<String>,
    notes: Vec<String>,
    /// Check bars right of the text (else below it).
    bars_right: bool,
    height_mm: f64,
}

impl Header {
    fn new(content_w: f64, circumference_note: &str) -> Header {
        let bars_right = content_w >= 120.0;
        let text_w = if bars_right {
            content_w - CHECK_BOX_W_MM
        } else {
            content_w
        };
        let title = wrap_text(
            &format!("rodtrack marker - {PRINT_AT_100}"),
            TITLE_FONT_MM,
            text_w,
        );
        let mut notes = wrap_text(WRAP_RULE, NOTE_FONT_MM, text_w);
        notes.extend(wrap_text(
            &format!(
                "Check: each black bar at the right must measure 10.0 mm. Cut along the crop \
                 marks, glue strip included. {circumference_note}"
            ),
            NOTE_FONT_MM,
            text_w,
        ));
        let text_h = title.len() as f64 * TITLE_FONT_MM * LEADING
            + notes.len() as f64 * NOTE_FONT_MM * LEADING;
        let height_mm = if bars_right {
            text_h.max(CHECK_BOX_H_MM)
        } else {
            text_h + CHECK_BOX_H_MM
        } + 2.0;
        Header {
            title,
            notes,
            bars_right,
            height_mm,
        }
    }

    fn draw(&self, x0: f64, y0: f64, content_w: f64, shapes: &mut Vec<Shape>) {
        let mut y = y0;
        for l in &self.title {
            y += TITLE_FONT_MM;
            shapes.push(text(x0, y, TITLE_FONT_MM, l));
            y += TITLE_FONT_MM * (LEADING - 1.0);
        }
        for l in &self.notes {
            y += NOTE_FONT_MM;
            shapes.push(text(x0, y, NOTE_FONT_MM, l));
            y += NOTE_FONT_MM * (LEADING - 1.0);
        }
        let (bx, by) = if self.bars_right {
            (x0 + content_w - CHECK_BOX_W_MM + 4.0, y0 + 0.5)
        } else {
            (x0, y + 1.0)
        };
        check_bars(bx, by, shapes);
    }
}

/// A 10 mm check bar across and one down, with 1 mm ticks and labels; box
/// `CHECK_BOX_W_MM x CHECK_BOX_H_MM` from `(x, y)`.
fn check_bars(x: f64, y: f64, shapes: &mut Vec<Shape>) {
    // Across: bar 10 x 1 mm, ticks below.
    shapes.push(Shape::Rect(Rect {
        x_mm: x,
        y_mm: y,
        w_mm: 10.0,
        h_mm: 1.0,
        kind: RectKind::CheckBar,
    }));
    for i in 0..=10 {
        let len = if i % 5 == 0 { 2.0 } else { 1.0 };
        let tx = x + i as f64;
        let tx = tx.clamp(x + HAIR_MM * 0.5, x + 10.0 - HAIR_MM * 0.5);
        shapes.push(line(tx, y + 1.0, tx, y + 1.0 + len, HAIR_MM));
    }
    shapes.push(text(x + 11.5, y + 2.4, NOTE_FONT_MM, "10 mm"));
    // Down: bar 1 x 10 mm, ticks to the left, label reading upwards.
    let vx = x + 26.0;
    shapes.push(Shape::Rect(Rect {
        x_mm: vx,
        y_mm: y,
        w_mm: 1.0,
        h_mm: 10.0,
        kind: RectKind::CheckBar,
    }));
    for i in 0..=10 {
        let len = if i % 5 == 0 { 2.0 } else { 1.0 };
        let ty = (y + i as f64).clamp(y + HAIR_MM * 0.5, y + 10.0 - HAIR_MM * 0.5);
        shapes.push(line(vx - len, ty, vx, ty, HAIR_MM));
    }
    shapes.push(Shape::Text(Text {
        x_mm: vx + 1.0 + 0.4 + NOTE_FONT_MM * 0.75,
        y_mm: y + 5.0 + text_width("10 mm", NOTE_FONT_MM) * 0.5,
        size_mm: NOTE_FONT_MM,
        angle_deg: -90.0,
        grey: 0.0,
        text: "10 mm".to_string(),
    }));
}

/// Draws one marker cell whose top-left corner is `(cx, cy)`.
fn draw_cell(
    rod: u32,
    marker: &Marker,
    plan: &CellPlan,
    opts: &PrintOptions,
    cx: f64,
    cy: f64,
    shapes: &mut Vec<Shape>,
) -> Placement {
    let c = circumference_mm(marker);
    let len = marker.length_mm();
    let g = opts.glue_mm;
    let left = cx + CROP_ZONE_MM; // the strip's left edge (glue included)
    let ox = left + g; // psi = 0
    let oy = cy + label_height(plan.desc.len()) + CROP_ZONE_MM; // u = 0

    // Labels.
    let mut y = cy + ROD_FONT_MM;
    shapes.push(text(left, y, ROD_FONT_MM, &format!("rod {rod}")));
    y += ROD_FONT_MM * 0.2;
    for l in &plan.desc {
        y += DESC_FONT_MM * LEADING;
        shapes.push(text(left, y, DESC_FONT_MM, l));
    }
    // Wrap arrow: from psi = 0 towards psi = 2 pi.
    y += DESC_FONT_MM * 1.6;
    let label = "wrap this way: psi grows";
    shapes.push(text(ox, y, DESC_FONT_MM, label));
    let ay = y - DESC_FONT_MM * 0.35;
    let ax0 = ox + text_width(label, DESC_FONT_MM) / FONT_SLACK + 1.0;
    let ax1 = ox + c;
    if ax1 - ax0 > 3.0 {
        shapes.push(line(ax0, ay, ax1 - 1.5, ay, 0.3));
        shapes.push(Shape::Polygon {
            points_mm: vec![(ax1, ay), (ax1 - 2.0, ay - 0.9), (ax1 - 2.0, ay + 0.9)],
            grey: 0.0,
        });
    }

    // The print.
    for r in marker_geometry(marker, opts) {
        let r = r.shifted(ox, oy);
        shapes.push(Shape::Rect(r));
        if r.kind == RectKind::Glue {
            hatch(&r, shapes);
            if r.w_mm >= 3.0 {
                let t = "GLUE: the psi = 2 pi end overlaps here";
                let size = DESC_FONT_MM.min(r.w_mm * 0.45);
                let tw = text_width(t, size);
                if tw < r.h_mm {
                    shapes.push(Shape::Text(Text {
                        x_mm: r.x_mm + r.w_mm * 0.5 + size * 0.35,
                        y_mm: r.y_mm + r.h_mm * 0.5 + tw * 0.5,
                        size_mm: size,
                        angle_deg: -90.0,
                        grey: 0.25,
                        text: t.to_string(),
                    }));
                }
            }
        }
    }

    // Crop marks outside the strip's corners, and ticks at psi = 0 above and below.
    let right = ox + c;
    let (top, bottom) = (oy, oy + len);
    for &x in &[left, right] {
        shapes.push(line(x, top - CROP_ZONE_MM, x, top - CROP_GAP_MM, HAIR_MM));
        shapes.push(line(
            x,
            bottom + CROP_GAP_MM,
            x,
            bottom + CROP_ZONE_MM,
            HAIR_MM,
        ));
    }
    for &yy in &[top, bottom] {
        shapes.push(line(
            left - CROP_ZONE_MM,
            yy,
            left - CROP_GAP_MM,
            yy,
            HAIR_MM,
        ));
        shapes.push(line(
            right + CROP_GAP_MM,
            yy,
            right + CROP_ZONE_MM,
            yy,
            HAIR_MM,
        ));
    }
    if g > 0.0 {
        shapes.push(line(ox, top - CROP_ZONE_MM, ox, top - CROP_GAP_MM, HAIR_MM));
        shapes.push(line(
            ox,
            bottom + CROP_GAP_MM,
            ox,
            bottom + CROP_ZONE_MM,
            HAIR_MM,
        ));
    }
    let small = DESC_FONT_MM * 0.8;
    let by = bottom + CROP_GAP_MM + small;
    shapes.push(text(ox + 0.5, by, small, "psi = 0"));
    let t = "psi = 2 pi";
    shapes.push(text(right - 0.5 - text_width(t, small), by, small, t));

    Placement {
        rod,
        x_mm: ox,
        y_mm: oy,
        circumference_mm: c,
        length_mm: len,
    }
}

/// 45-degree hatching inside a rectangle.
fn hatch(r: &Rect, shapes: &mut Vec<Shape>) {
    let step = 1.5;
    let (w, h) = (r.w_mm, r.h_mm);
    let mut s = step * 0.5;
    while s < w + h {
        let xa = (s - h).max(0.0);
        let xb = s.min(w);
        if xb - xa > 0.05 {
            shapes.push(Shape::Line {
                x0_mm: r.x_mm + xa,
                y0_mm: r.y_mm + (s - xa),
                x1_mm: r.x_mm + xb,
                y1_mm: r.y_mm + (s - xb),
                width_mm: HAIR_MM,
                grey: HATCH_GREY,
            });
        }
        s += step;
    }
}

fn text(x_mm: f64, y_mm: f64, size_mm: f64, s: &str) -> Shape {
    Shape::Text(Text {
        x_mm,
        y_mm,
        size_mm,
        angle_deg: 0.0,
        grey: 0.0,
        text: s.to_string(),
    })
}

fn line(x0_mm: f64, y0_mm: f64, x1_mm: f64, y1_mm: f64, width_mm: f64) -> Shape {
    Shape::Line {
        x0_mm,
        y0_mm,
        x1_mm,
        y1_mm,
        width_mm,
        grey: 0.0,
    }
}

fn page_dims(page: PageSize) -> Option<(f64, f64)> {
    match page {
        PageSize::A4 => Some((210.0, 297.0)),
        PageSize::Letter => Some((215.9, 279.4)),
        PageSize::Custom {
            width_mm,
            height_mm,
        } => Some((width_mm, height_mm)),
        PageSize::Fit => None,
    }
}

/// Lays markers out on pages: a grid of equal cells (label block, crop zone, strip, crop zone)
/// under a header, on as many pages as needed (one page for [`PageSize::Fit`]). Markers keep
/// their order, row by row.
pub fn layout(markers: &[(u32, &Marker)], opts: &PrintOptions) -> Result<Vec<Page>, PrintError> {
    opts.check()?;
    if markers.is_empty() {
        return Err(PrintError::Empty);
    }
    let plans: Vec<CellPlan> = markers
        .iter()
        .map(|(_, m)| CellPlan::new(m, opts.glue_mm))
        .collect();
    let cell_w = plans.iter().map(|p| p.width_mm).fold(0.0, f64::max);
    let cell_h = plans.iter().map(|p| p.height_mm).fold(0.0, f64::max);
    let circ: Vec<f64> = markers.iter().map(|(_, m)| circumference_mm(m)).collect();
    let same = circ.iter().all(|c| (c - circ[0]).abs() < 1e-9);
    let circumference_note = if same {
        format!(
            "The pattern (psi = 0 to 2 pi) is {} mm wide: the rod's circumference.",
            num2(circ[0])
        )
    } else {
        "The pattern (psi = 0 to 2 pi) is as wide as its rod's circumference.".to_string()
    };

    let n = markers.len();
    let (page_w, page_h, cols, rows) = match page_dims(opts.page) {
        None => {
            let cols = n.min(4);
            let rows = n.div_ceil(cols);
            let content_w = cols as f64 * (cell_w + CELL_GAP_MM) - CELL_GAP_MM;
            let header = Header::new(content_w, &circumference_note);
            let content_h = header.height_mm + rows as f64 * (cell_h + CELL_GAP_MM) - CELL_GAP_MM;
            (
                content_w + 2.0 * MARGIN_MM,
                content_h + 2.0 * MARGIN_MM,
                cols,
                rows,
            )
        }
        Some((w, h)) => {
            let content_w = w - 2.0 * MARGIN_MM;
            let header = Header::new(content_w, &circumference_note);
            let avail_h = h - 2.0 * MARGIN_MM - header.height_mm;
            let cols = ((content_w + CELL_GAP_MM) / (cell_w + CELL_GAP_MM)).floor();
            let rows = ((avail_h + CELL_GAP_MM) / (cell_h + CELL_GAP_MM)).floor();
            if cols < 1.0 || rows < 1.0 {
                let worst = plans
                    .iter()
                    .zip(markers)
                    .max_by(|a, b| {
                        (a.0.width_mm * a.0.height_mm).total_cmp(&(b.0.width_mm * b.0.height_mm))
                    })
                    .map(|(_, (rod, _))| *rod)
                    .unwrap_or(markers[0].0);
                return Err(PrintError::TooLarge {
                    rod: worst,
                    width_mm: cell_w + 2.0 * MARGIN_MM,
                    height_mm: cell_h + header.height_mm + 2.0 * MARGIN_MM,
                    page_width_mm: w,
                    page_height_mm: h,
                });
            }
            (w, h, cols as usize, rows as usize)
        }
    };
    let content_w = page_w - 2.0 * MARGIN_MM;
    let header = Header::new(content_w, &circumference_note);
    let per_page = cols * rows;
    let mut pages = Vec::new();
    for (chunk_idx, chunk) in markers.chunks(per_page).enumerate() {
        let mut shapes = Vec::new();
        header.draw(MARGIN_MM, MARGIN_MM, content_w, &mut shapes);
        let grid_y = MARGIN_MM + header.height_mm;
        let mut placed = Vec::new();
        for (i, (rod, marker)) in chunk.iter().enumerate() {
            let (col, row) = (i % cols, i / cols);
            let cx = MARGIN_MM + col as f64 * (cell_w + CELL_GAP_MM);
            let cy = grid_y + row as f64 * (cell_h + CELL_GAP_MM);
            let plan = &plans[chunk_idx * per_page + i];
            placed.push(draw_cell(*rod, marker, plan, opts, cx, cy, &mut shapes));
        }
        pages.push(Page {
            width_mm: page_w,
            height_mm: page_h,
            shapes,
            markers: placed,
        });
    }
    Ok(pages)
}

/// One SVG page holding all markers; [`PrintError::MultiPage`] if they need more than one page
/// of the chosen size.
pub fn svg(markers: &[(u32, &Marker)], opts: &PrintOptions) -> Result<String, PrintError> {
    let pages = layout(markers, opts)?;
    match pages.as_slice() {
        [page] => Ok(svg_page(page)),
        _ => Err(PrintError::MultiPage { pages: pages.len() }),
    }
}

/// One SVG document per page.
pub fn svg_pages(
    markers: &[(u32, &Marker)],
    opts: &PrintOptions,
) -> Result<Vec<String>, PrintError> {
    Ok(layout(markers, opts)?.iter().map(svg_page).collect())
}

/// A PDF document with one page per laid-out page.
pub fn pdf(markers: &[(u32, &Marker)], opts: &PrintOptions) -> Result<Vec<u8>, PrintError> {
    Ok(pdf_document(&layout(markers, opts)?))
}

/// Writes one page as SVG: `width`/`height` in mm, `viewBox` in mm.
pub fn svg_page(page: &Page) -> String {
    let (w, h) = (num(page.width_mm), num(page.height_mm));
    let mut s = String::new();
    s.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"{w}mm\" \
         height=\"{h}mm\" viewBox=\"0 0 {w} {h}\">"
    );
    let rods: Vec<String> = page.markers.iter().map(|p| p.rod.to_string()).collect();
    let _ = writeln!(
        s,
        "<title>rodtrack marker, rods {}: {}</title>",
        rods.join(", "),
        PRINT_AT_100.replace('"', "")
    );
    let _ = writeln!(
        s,
        "<rect x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\" fill=\"#ffffff\"/>"
    );
    for shape in &page.shapes {
        match shape {
            Shape::Rect(r) => {
                let _ = writeln!(
                    s,
                    "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\"/>",
                    num(r.x_mm),
                    num(r.y_mm),
                    num(r.w_mm),
                    num(r.h_mm),
                    svg_grey(r.kind.grey())
                );
            }
            Shape::Line {
                x0_mm,
                y0_mm,
                x1_mm,
                y1_mm,
                width_mm,
                grey,
            } => {
                let _ = writeln!(
                    s,
                    "<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\" \
                     stroke-width=\"{}\"/>",
                    num(*x0_mm),
                    num(*y0_mm),
                    num(*x1_mm),
                    num(*y1_mm),
                    svg_grey(*grey),
                    num(*width_mm)
                );
            }
            Shape::Polygon { points_mm, grey } => {
                let pts: Vec<String> = points_mm
                    .iter()
                    .map(|(x, y)| format!("{},{}", num(*x), num(*y)))
                    .collect();
                let _ = writeln!(
                    s,
                    "<polygon points=\"{}\" fill=\"{}\"/>",
                    pts.join(" "),
                    svg_grey(*grey)
                );
            }
            Shape::Text(t) => {
                let rot = if t.angle_deg != 0.0 {
                    format!(
                        " transform=\"rotate({} {} {})\"",
                        num(t.angle_deg),
                        num(t.x_mm),
                        num(t.y_mm)
                    )
                } else {
                    String::new()
                };
                // textLength pins the width to Helvetica's, whatever font the viewer has.
                let _ = writeln!(
                    s,
                    "<text x=\"{}\" y=\"{}\" font-family=\"Helvetica, Arial, 'Liberation Sans', \
                     'Nimbus Sans', sans-serif\" font-size=\"{}\" textLength=\"{}\" \
                     lengthAdjust=\"spacingAndGlyphs\" fill=\"{}\"{rot}>{}</text>",
                    num(t.x_mm),
                    num(t.y_mm),
                    num(t.size_mm),
                    num(text_width(&t.text, t.size_mm)),
                    svg_grey(t.grey),
                    xml_escape(&t.text)
                );
            }
        }
    }
    s.push_str("</svg>\n");
    s
}

fn svg_grey(grey: f64) -> String {
    let v = (grey.clamp(0.0, 1.0) * 255.0).round() as u8;
    format!("#{v:02x}{v:02x}{v:02x}")
}

fn xml_escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            c => o.push(c),
        }
    }
    o
}

/// Points per mm.
const PT_PER_MM: f64 = 72.0 / 25.4;

/// The content stream of one page: a `cm` maps mm with `y` down onto PDF points.
fn pdf_content(page: &Page) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "q\n{} 0 0 {} 0 {} cm",
        num6(PT_PER_MM),
        num6(-PT_PER_MM),
        num(page.height_mm * PT_PER_MM)
    );
    for shape in &page.shapes {
        match shape {
            Shape::Rect(r) => {
                let _ = writeln!(
                    s,
                    "{} g {} {} {} {} re f",
                    num(r.kind.grey()),
                    num(r.x_mm),
                    num(r.y_mm),
                    num(r.w_mm),
                    num(r.h_mm)
                );
            }
            Shape::Line {
                x0_mm,
                y0_mm,
                x1_mm,
                y1_mm,
                width_mm,
                grey,
            } => {
                let _ = writeln!(
                    s,
                    "{} G {} w {} {} m {} {} l S",
                    num(*grey),
                    num(*width_mm),
                    num(*x0_mm),
                    num(*y0_mm),
                    num(*x1_mm),
                    num(*y1_mm)
                );
            }
            Shape::Polygon { points_mm, grey } => {
                let _ = write!(s, "{} g", num(*grey));
                for (i, (x, y)) in points_mm.iter().enumerate() {
                    let op = if i == 0 { "m" } else { "l" };
                    let _ = write!(s, " {} {} {op}", num(*x), num(*y));
                }
                s.push_str(" h f\n");
            }
            Shape::Text(t) => {
                // In the y-down mm space a text matrix [cos sin sin -cos] sets glyphs upright,
                // turned clockwise by the angle.
                let (sin, cos) = t.angle_deg.to_radians().sin_cos();
                let _ = writeln!(
                    s,
                    "{} g BT /F1 {} Tf {} {} {} {} {} {} Tm ({}) Tj ET",
                    num(t.grey),
                    num(t.size_mm),
                    num6(cos),
                    num6(sin),
                    num6(sin),
                    num6(-cos),
                    num(t.x_mm),
                    num(t.y_mm),
                    pdf_escape(&t.text)
                );
            }
        }
    }
    s.push_str("Q\n");
    s
}

fn pdf_escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '(' | ')' | '\\' => {
                o.push('\\');
                o.push(ch);
            }
            c if (' '..='~').contains(&c) => o.push(c),
            _ => o.push('?'),
        }
    }
    o
}

/// A minimal PDF 1.4: catalog, page tree, Helvetica, info, then a page and its content stream
/// per page; a cross-reference table with exact byte offsets.
fn pdf_document(pages: &[Page]) -> Vec<u8> {
    let n_obj = 4 + 2 * pages.len();
    let mut out: Vec<u8> = b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n".to_vec();
    let mut offsets = vec![0usize; n_obj + 1];
    let mut obj = |out: &mut Vec<u8>, id: usize, body: &[u8]| {
        offsets[id] = out.len();
        out.extend_from_slice(format!("{id} 0 obj\n").as_bytes());
        out.extend_from_slice(body);
        out.extend_from_slice(b"\nendobj\n");
    };
    obj(
        &mut out,
        1,
        b"<< /Type /Catalog /Pages 2 0 R /ViewerPreferences << /PrintScaling /None >> >>",
    );
    let kids: Vec<String> = (0..pages.len())
        .map(|i| format!("{} 0 R", 5 + 2 * i))
        .collect();
    obj(
        &mut out,
        2,
        format!(
            "<< /Type /Pages /Kids [{}] /Count {} >>",
            kids.join(" "),
            pages.len()
        )
        .as_bytes(),
    );
    obj(
        &mut out,
        3,
        b"<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica /Encoding /WinAnsiEncoding >>",
    );
    obj(
        &mut out,
        4,
        b"<< /Title (rodtrack marker) /Producer (rodtrack marker_print) >>",
    );
    for (i, page) in pages.iter().enumerate() {
        let (pid, cid) = (5 + 2 * i, 6 + 2 * i);
        obj(
            &mut out,
            pid,
            format!(
                "<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {} {}] /Resources << /Font << \
                 /F1 3 0 R >> >> /Contents {cid} 0 R >>",
                num(page.width_mm * PT_PER_MM),
                num(page.height_mm * PT_PER_MM)
            )
            .as_bytes(),
        );
        let content = pdf_content(page);
        let mut body = format!("<< /Length {} >>\nstream\n", content.len()).into_bytes();
        body.extend_from_slice(content.as_bytes());
        body.extend_from_slice(b"endstream");
        obj(&mut out, cid, &body);
    }
    let xref = out.len();
    let mut t = format!("xref\n0 {}\n0000000000 65535 f \n", n_obj + 1);
    for off in &offsets[1..] {
        let _ = writeln!(t, "{off:010} 00000 n ");
    }
    let _ = write!(
        t,
        "trailer\n<< /Size {} /Root 1 0 R /Info 4 0 R >>\nstartxref\n{xref}\n%%EOF\n",
        n_obj + 1
    );
    out.extend_from_slice(t.as_bytes());
    out
}

/// A number with up to 4 decimals, trailing zeros dropped.
fn num(v: f64) -> String {
    trim(format!("{v:.4}"))
}

/// A number with up to 6 decimals, trailing zeros dropped.
fn num6(v: f64) -> String {
    trim(format!("{v:.6}"))
}

/// A number with up to 2 decimals, trailing zeros dropped.
fn num2(v: f64) -> String {
    trim(format!("{v:.2}"))
}

fn trim(s: String) -> String {
    let t = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        s.as_str()
    };
    if t == "-0" {
        "0".to_string()
    } else {
        t.to_string()
    }
}

/// Helvetica advance widths (1/1000 em) of ASCII 32..=126, from the standard AFM.
const HELVETICA_WIDTHS: [u16; 95] = [
    278, 278, 355, 556, 556, 889, 667, 191, 333, 333, 389, 584, 278, 333, 278, 278, // ' '../
    556, 556, 556, 556, 556, 556, 556, 556, 556, 556, 278, 278, 584, 584, 584, 556, // 0..?
    1015, 667, 667, 722, 722, 667, 611, 778, 722, 278, 500, 667, 556, 833, 722, 778, // @..O
    667, 778, 722, 667, 611, 722, 667, 944, 667, 667, 611, 278, 278, 278, 469, 556, // P.._
    333, 556, 556, 500, 556, 556, 278, 556, 556, 222, 222, 500, 222, 833, 556, 556, // `..o
    556, 556, 333, 500, 278, 556, 500, 722, 500, 500, 500, 334, 260, 334, 584, // p..~
];

/// Width of `s` in Helvetica at `size_mm`, mm.
pub fn text_width(s: &str, size_mm: f64) -> f64 {
    s.chars()
        .map(|c| {
            let i = (c as u32).wrapping_sub(32) as usize;
            HELVETICA_WIDTHS.get(i).copied().unwrap_or(556) as f64
        })
        .sum::<f64>()
        * size_mm
        / 1000.0
}

/// How much of a line's room Helvetica may fill, so that a wider substitute font (an SVG viewer
/// without Helvetica or Arial, e.g. DejaVu Sans, about 12 % wider) still fits.
const FONT_SLACK: f64 = 0.88;

/// Greedy word wrap to lines no wider than `FONT_SLACK * max_mm` in Helvetica (a single long
/// word stays whole).
fn wrap_text(s: &str, size_mm: f64, max_mm: f64) -> Vec<String> {
    let max_mm = max_mm * FONT_SLACK;
    let mut lines = Vec::new();
    let mut cur = String::new();
    for word in s.split_whitespace() {
        let cand = if cur.is_empty() {
            word.to_string()
        } else {
            format!("{cur} {word}")
        };
        if !cur.is_empty() && text_width(&cand, size_mm) > max_mm {
            lines.push(std::mem::take(&mut cur));
            cur = word.to_string();
        } else {
            cur = cand;
        }
    }
    if !cur.is_empty() {
        lines.push(cur);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers() {
        assert_eq!(num(1.0), "1");
        assert_eq!(num(-0.00001), "0");
        assert_eq!(num(50.26548), "50.2655");
        assert_eq!(num2(106.0), "106");
        assert_eq!(
            black_runs(6, |i| [1, 1, 0, 1, 0, 1][i] == 1),
            [(0, 2), (3, 4), (5, 6)]
        );
        // "10 mm": 1, 0, space, m, m.
        let w = text_width("10 mm", 1000.0);
        assert_eq!(w, (556 + 556 + 278 + 833 + 833) as f64);
        let room = (text_width("aaa bbb", 1.0) + 0.01) / FONT_SLACK;
        let lines = wrap_text("aaa bbb ccc", 1.0, room);
        assert_eq!(lines, ["aaa bbb", "ccc"]);
        assert_eq!(pdf_escape("a(b)\\c\u{e9}"), "a\\(b\\)\\\\c?");
    }
}
