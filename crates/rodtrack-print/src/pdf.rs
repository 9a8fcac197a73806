//! The PDF writer: a minimal hand-written PDF 1.4 (vector rectangles, lines and Helvetica text,
//! uncompressed).

use crate::layout::{layout, Page, Shape};
use crate::text::{num, num6};
use crate::{PrintError, PrintOptions};
use rodtrack_core::marker::Marker;
use std::fmt::Write as _;

/// A PDF document with one page per laid-out page.
pub fn pdf(markers: &[(u32, &Marker)], opts: &PrintOptions) -> Result<Vec<u8>, PrintError> {
    Ok(pdf_document(&layout(markers, opts)?))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers() {
        assert_eq!(pdf_escape("a(b)\\c\u{e9}"), "a\\(b\\)\\\\c?");
    }
}
