//! Text metrics (Helvetica advance widths, word wrap) and the number formatting of the writers.

/// A number with up to 4 decimals, trailing zeros dropped.
pub(crate) fn num(v: f64) -> String {
    trim(format!("{v:.4}"))
}

/// A number with up to 6 decimals, trailing zeros dropped.
pub(crate) fn num6(v: f64) -> String {
    trim(format!("{v:.6}"))
}

/// A number with up to 2 decimals, trailing zeros dropped.
pub(crate) fn num2(v: f64) -> String {
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
pub(crate) const FONT_SLACK: f64 = 0.88;

/// Greedy word wrap to lines no wider than `FONT_SLACK * max_mm` in Helvetica (a single long
/// word stays whole).
pub(crate) fn wrap_text(s: &str, size_mm: f64, max_mm: f64) -> Vec<String> {
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
        // "10 mm": 1, 0, space, m, m.
        let w = text_width("10 mm", 1000.0);
        assert_eq!(w, (556 + 556 + 278 + 833 + 833) as f64);
        let room = (text_width("aaa bbb", 1.0) + 0.01) / FONT_SLACK;
        let lines = wrap_text("aaa bbb ccc", 1.0, room);
        assert_eq!(lines, ["aaa bbb", "ccc"]);
    }
}
