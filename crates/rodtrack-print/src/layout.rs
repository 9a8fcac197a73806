//! Pages: markers, their labels, crop marks, the header and check bars placed as [`Shape`]s.

use crate::geometry::{circumference_mm, marker_geometry, Rect, RectKind};
use crate::text::{num, num2, text_width, wrap_text, FONT_SLACK};
use crate::{PageSize, PrintError, PrintOptions};
use rodtrack_core::marker::Marker;
use std::fmt::Write as _;

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

/// Grey level of the glue strip's hatching.
const HATCH_GREY: f64 = 0.55;

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
