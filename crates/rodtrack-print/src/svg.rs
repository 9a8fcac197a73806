//! The SVG writer: one document per page, sizes in mm.

use crate::layout::{layout, Page, Shape, PRINT_AT_100};
use crate::text::{num, text_width};
use crate::{PrintError, PrintOptions};
use rodtrack_core::marker::Marker;
use std::fmt::Write as _;

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
