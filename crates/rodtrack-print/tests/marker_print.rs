//! The printable marker: geometry against SPEC section 3 and the core's `is_black`, the SVG
//! read back and rasterized, the wrap direction on a simulated rod, the PDF's structure and (with
//! poppler's `pdftoppm`) its rendering.
#![allow(clippy::unwrap_used, missing_docs)]

use rodtrack_core::marker::{gray_decode, Marker, MarkerSpec};
use rodtrack_print::{
    circumference_mm, layout, marker_geometry, pdf, svg, svg_pages, PageSize, Placement,
    PrintError, PrintOptions, RectKind, Shape, PRINT_AT_100, WRAP_RULE,
};
use std::f64::consts::{PI, TAU};
use std::path::PathBuf;

const TOL_MM: f64 = 0.01;

fn v1() -> Marker {
    Marker::v1()
}

// ---------------------------------------------------------------------------------------------
// Geometry

#[test]
fn geometry_v1_matches_spec() {
    let m = v1();
    let opts = PrintOptions::default();
    let c = circumference_mm(&m);
    assert!((c - PI * 16.0).abs() < 1e-9);
    let rects = marker_geometry(&m, &opts);

    // Glue strip: 5 mm left of psi = 0, full length 106 mm.
    let glue: Vec<_> = rects.iter().filter(|r| r.kind == RectKind::Glue).collect();
    assert_eq!(glue.len(), 1);
    assert!((glue[0].x_mm + 5.0).abs() < TOL_MM && (glue[0].w_mm - 5.0).abs() < TOL_MM);
    assert!(glue[0].y_mm.abs() < TOL_MM && (glue[0].h_mm - 106.0).abs() < TOL_MM);

    // Barcode: full-width bars whose edges are cell edges 4 + 4 i and exactly the core's edges.
    let bars: Vec<_> = rects
        .iter()
        .filter(|r| r.kind == RectKind::BarcodeBar)
        .collect();
    assert_eq!(bars.len(), 6, "6 black bars");
    let mut edges = Vec::new();
    for b in &bars {
        assert!(
            b.x_mm.abs() < TOL_MM && (b.w_mm - c).abs() < TOL_MM,
            "{b:?}"
        );
        for e in [b.y_mm, b.y_mm + b.h_mm] {
            let i = ((e - 4.0) / 4.0).round();
            assert!(
                (e - (4.0 + 4.0 * i)).abs() < TOL_MM,
                "edge {e} is not 4 + 4 i"
            );
            assert!((0.0..=16.0).contains(&i));
        }
        edges.push((b.y_mm, true));
        edges.push((b.y_mm + b.h_mm, false));
    }
    let core = m.barcode_edges_mm();
    assert_eq!(edges.len(), core.len());
    for (a, b) in edges.iter().zip(&core) {
        assert!((a.0 - b.0).abs() < TOL_MM && a.1 == b.1, "{a:?} vs {b:?}");
    }

    // Gray code: bit space k spans 72 + 6 k .. 78 + 6 k; stripe edges on multiples of c / 32;
    // 8, 4, 2, 1, 1 black stripes.
    for (k, want) in [(0u32, 8usize), (1, 4), (2, 2), (3, 1), (4, 1)] {
        let stripes: Vec<_> = rects
            .iter()
            .filter(|r| r.kind == RectKind::GrayStripe { bit: k })
            .collect();
        assert_eq!(stripes.len(), want, "bit {k}");
        for s in stripes {
            assert!((s.y_mm - (72.0 + 6.0 * k as f64)).abs() < TOL_MM);
            assert!((s.h_mm - 6.0).abs() < TOL_MM);
            for e in [s.x_mm, s.x_mm + s.w_mm] {
                let n = (e / (c / 32.0)).round();
                assert!((e - n * c / 32.0).abs() < TOL_MM, "stripe edge {e}");
                assert!((0.0..=32.0).contains(&n));
            }
        }
    }
    // The pattern spans exactly [0, c) x [0, 106): bit 4 is black from step 16 to the end.
    let pattern: Vec<_> = rects.iter().filter(|r| r.kind.is_pattern()).collect();
    let right = pattern.iter().map(|r| r.x_mm + r.w_mm).fold(0.0, f64::max);
    let bottom = pattern.iter().map(|r| r.y_mm + r.h_mm).fold(0.0, f64::max);
    assert!((right - c).abs() < TOL_MM);
    assert!(
        (bottom - 102.0).abs() < TOL_MM,
        "last bit space ends at 102"
    );
    assert!(pattern
        .iter()
        .all(|r| r.x_mm >= -1e-9 && r.y_mm >= 4.0 - 1e-9));
    assert_eq!(m.length_mm(), 106.0);
}

/// Black in the geometry exactly where the core's `is_black` says, on a 0.1 mm grid (offset so
/// that no sample lies on an edge), for marker v1 and for other descriptions.
#[test]
fn geometry_matches_core_is_black() {
    let mut other = MarkerSpec {
        rod_diameter_mm: 20.0,
        ..MarkerSpec::default()
    };
    other.barcode.kernel = "110100111".into();
    other.barcode.cell_mm = 3.0;
    other.gray_code.start_mm = 40.0;
    other.gray_code.bits = 4;
    other.gray_code.bit_space_mm = 5.0;
    other.length_mm = Some(70.0);
    let mut three = MarkerSpec::default();
    three.gray_code.bits = 3;
    for m in [v1(), other.validate().unwrap(), three.validate().unwrap()] {
        let rects = marker_geometry(
            &m,
            &PrintOptions {
                glue_mm: 0.0,
                ..PrintOptions::default()
            },
        );
        assert!(rects.iter().all(|r| r.kind.is_pattern()));
        let c = circumference_mm(&m);
        let r = m.radius_mm();
        let (nx, ny) = ((c / 0.1) as usize, (m.length_mm() / 0.1) as usize);
        let mut mismatches = 0;
        for j in 0..ny {
            let u = (j as f64 + 0.37) * 0.1;
            for i in 0..nx {
                let x = (i as f64 + 0.41) * 0.1;
                let ours = rects.iter().any(|q| q.contains(x, u));
                if ours != m.is_black(u, x / r) {
                    mismatches += 1;
                }
            }
        }
        assert_eq!(mismatches, 0, "{:?}", m.spec());
    }
}

#[test]
fn options_and_inputs_are_checked() {
    let m = v1();
    assert_eq!(
        layout(&[], &PrintOptions::default()).unwrap_err(),
        PrintError::Empty
    );
    for glue in [-1.0, f64::NAN, 80.0] {
        let e = layout(
            &[(0, &m)],
            &PrintOptions {
                glue_mm: glue,
                ..PrintOptions::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("glue_mm"), "{e}");
    }
    let tiny = PrintOptions {
        page: PageSize::Custom {
            width_mm: 100.0,
            height_mm: 100.0,
        },
        ..PrintOptions::default()
    };
    assert!(matches!(
        layout(&[(7, &m)], &tiny).unwrap_err(),
        PrintError::TooLarge { rod: 7, .. }
    ));
    // Eight markers need two A4 pages: fine for PDF and svg_pages, an error for svg.
    let eight: Vec<(u32, &Marker)> = (0..8).map(|r| (r, &m)).collect();
    assert_eq!(
        svg(&eight, &PrintOptions::default()).unwrap_err(),
        PrintError::MultiPage { pages: 2 }
    );
    assert_eq!(
        svg_pages(&eight, &PrintOptions::default()).unwrap().len(),
        2
    );
}

/// Pages: everything inside the page, markers in order and not overlapping, six v1 markers on
/// an A4 page, a fitted page just big enough.
#[test]
fn layout_places_markers() {
    let m = v1();
    let eight: Vec<(u32, &Marker)> = (0..8).map(|r| (r, &m)).collect();
    for (page, pages_expected) in [(PageSize::A4, 2), (PageSize::Letter, 3), (PageSize::Fit, 1)] {
        let opts = PrintOptions {
            page,
            ..PrintOptions::default()
        };
        let pages = layout(&eight, &opts).unwrap();
        assert_eq!(pages.len(), pages_expected, "{page:?}");
        if page == PageSize::A4 {
            assert_eq!(pages[0].markers.len(), 6);
            assert_eq!((pages[0].width_mm, pages[0].height_mm), (210.0, 297.0));
        }
        let placed: Vec<Placement> = pages.iter().flat_map(|p| p.markers.clone()).collect();
        let rods: Vec<u32> = placed.iter().map(|p| p.rod).collect();
        assert_eq!(rods, (0..8).collect::<Vec<_>>());
        for p in &pages {
            for s in &p.shapes {
                for (x, y) in shape_points(s) {
                    assert!(
                        (0.0..=p.width_mm).contains(&x) && (0.0..=p.height_mm).contains(&y),
                        "{s:?} leaves the {} x {} page",
                        p.width_mm,
                        p.height_mm
                    );
                }
            }
            // Strips (glue included) with their crop zones do not overlap.
            for (i, a) in p.markers.iter().enumerate() {
                for b in &p.markers[i + 1..] {
                    let sep_x = (a.x_mm - b.x_mm).abs() >= a.circumference_mm + 5.0 + 9.0;
                    let sep_y = (a.y_mm - b.y_mm).abs() >= a.length_mm + 9.0;
                    assert!(sep_x || sep_y, "{a:?} overlaps {b:?}");
                }
            }
        }
    }
}

fn shape_points(s: &Shape) -> Vec<(f64, f64)> {
    match s {
        Shape::Rect(r) => vec![(r.x_mm, r.y_mm), (r.x_mm + r.w_mm, r.y_mm + r.h_mm)],
        Shape::Line {
            x0_mm,
            y0_mm,
            x1_mm,
            y1_mm,
            ..
        } => vec![(*x0_mm, *y0_mm), (*x1_mm, *y1_mm)],
        Shape::Polygon { points_mm, .. } => points_mm.clone(),
        Shape::Text(t) => vec![(t.x_mm, t.y_mm)],
    }
}

// ---------------------------------------------------------------------------------------------
// SVG read back and rasterized

/// `(x, y, w, h, fill)` of every `<rect .../>` in an SVG (our own output: one element a line,
/// double-quoted attributes).
fn svg_rects(svg: &str) -> Vec<(f64, f64, f64, f64, String)> {
    let mut out = Vec::new();
    for line in svg.lines() {
        let Some(body) = line.trim().strip_prefix("<rect ") else {
            continue;
        };
        let attr = |name: &str| -> String {
            let key = format!("{name}=\"");
            let start = body.find(&key).unwrap() + key.len();
            let len = body[start..].find('"').unwrap();
            body[start..start + len].to_string()
        };
        let f = |name: &str| attr(name).parse::<f64>().unwrap();
        out.push((f("x"), f("y"), f("width"), f("height"), attr("fill")));
    }
    out
}

/// A raster of the print around one placed marker, `PX_MM` mm per pixel, from the page's
/// black rectangles.
struct Texture {
    origin: Placement,
    w: usize,
    h: usize,
    black: Vec<bool>,
}

const PX_MM: f64 = 0.05;

impl Texture {
    fn from_svg(svg: &str, origin: Placement) -> Texture {
        let w = (origin.circumference_mm / PX_MM).ceil() as usize;
        let h = (origin.length_mm / PX_MM).ceil() as usize;
        let mut black = vec![false; w * h];
        for (x, y, rw, rh, fill) in svg_rects(svg) {
            if fill != "#000000" {
                continue;
            }
            // Pixel centres inside the rectangle.
            let (x0, y0) = (x - origin.x_mm, y - origin.y_mm);
            let i0 = ((x0 / PX_MM - 0.5).ceil().max(0.0)) as usize;
            let i1 = (((x0 + rw) / PX_MM - 0.5).ceil().max(0.0) as usize).min(w);
            let j0 = ((y0 / PX_MM - 0.5).ceil().max(0.0)) as usize;
            let j1 = (((y0 + rh) / PX_MM - 0.5).ceil().max(0.0) as usize).min(h);
            for j in j0..j1 {
                for i in i0..i1 {
                    black[j * w + i] = true;
                }
            }
        }
        Texture {
            origin,
            w,
            h,
            black,
        }
    }
    /// The print at `(u, psi)` (nearest pixel).
    fn at(&self, u_mm: f64, psi_rad: f64) -> bool {
        let x = psi_rad.rem_euclid(TAU) / TAU * self.origin.circumference_mm;
        let i = ((x / PX_MM) as usize).min(self.w - 1);
        let j = ((u_mm / PX_MM) as usize).min(self.h - 1);
        self.black[j * self.w + i]
    }
    /// Gray bits read at the bit space centres along the line `psi`, decoded.
    fn decode(&self, m: &Marker, psi_rad: f64) -> u32 {
        let mut code = 0;
        for k in 0..m.bits() {
            if self.at(m.bit_space_centre_mm(k), psi_rad) {
                code |= 1 << k;
            }
        }
        gray_decode(code)
    }
}

fn placed_textures(markers: &[(u32, &Marker)], opts: &PrintOptions) -> Vec<Texture> {
    let pages = layout(markers, opts).unwrap();
    let svgs = svg_pages(markers, opts).unwrap();
    pages
        .iter()
        .zip(&svgs)
        .flat_map(|(p, s)| p.markers.iter().map(|pl| Texture::from_svg(s, *pl)))
        .collect()
}

#[test]
fn svg_header_and_text() {
    let m = v1();
    let s = svg(&[(3, &m)], &PrintOptions::default()).unwrap();
    assert!(s.contains("width=\"210mm\" height=\"297mm\" viewBox=\"0 0 210 297\""));
    let text: String = s
        .lines()
        .filter(|l| l.starts_with("<text"))
        .filter_map(|l| l.split('>').nth(1))
        .map(|t| t.trim_end_matches("</text").replace("&quot;", "\"") + " ")
        .collect();
    for needle in [
        PRINT_AT_100,
        "rod 3",
        "10 mm",
        "GLUE",
        "wrap this way: psi grows",
        "kernel 1001101010000101, cell 4 mm",
        "5 bits, bit space 6 mm",
        "rod diameter 16 mm: 50.27 x 106 mm",
        "counter-clockwise",
        "right-handed",
    ] {
        assert!(text.contains(needle), "{needle:?} missing from the page");
    }
    // The wrap rule is printed whole (wrapped over lines).
    let words: Vec<&str> = text.split_whitespace().collect();
    let rule: Vec<&str> = WRAP_RULE.split_whitespace().collect();
    assert!(words.windows(rule.len()).any(|w| w == rule.as_slice()));
}

/// Read back from the SVG: the barcode along `u` is the kernel with white quiet zones, and at
/// the centre of every Gray step the bits decode to that step, in every marker on the page.
#[test]
fn svg_rasterized_decodes() {
    let m = v1();
    let rods: Vec<(u32, &Marker)> = (0..8).map(|r| (r, &m)).collect();
    let textures = placed_textures(&rods, &PrintOptions::default());
    assert_eq!(textures.len(), 8);
    for t in &textures {
        for psi in [0.1, 1.0, 3.0, 5.9] {
            let read: Vec<bool> = (0..16)
                .map(|i| t.at(4.0 + 4.0 * i as f64 + 2.0, psi))
                .collect();
            assert_eq!(read, m.kernel(), "rod {}", t.origin.rod);
            for u in [1.0, 3.5, 68.5, 71.5, 102.5, 105.5] {
                assert!(!t.at(u, psi), "quiet zone at u = {u}");
            }
        }
        for n in 0..32 {
            let psi = (n as f64 + 0.5) * TAU / 32.0;
            assert_eq!(t.decode(&m, psi), n, "step {n}");
            // Close to the step's edges too (0.1 mm inside).
            let dpsi = 0.1 / m.radius_mm();
            assert_eq!(t.decode(&m, n as f64 * TAU / 32.0 + dpsi), n);
            assert_eq!(t.decode(&m, (n + 1) as f64 * TAU / 32.0 - dpsi), n);
        }
        // Pixel parity with the core away from edges.
        let mut bad = 0;
        for j in 0..t.h {
            for i in 0..t.w {
                let (x, u) = ((i as f64 + 0.5) * PX_MM, (j as f64 + 0.5) * PX_MM);
                let psi = x / m.radius_mm();
                if x > t.origin.circumference_mm - PX_MM {
                    continue; // past psi = 2 pi: white paper (or cut off)
                }
                let near_edge = [-1.0, 1.0].iter().any(|d| {
                    m.is_black(u + d * PX_MM, psi) != m.is_black(u, psi)
                        || m.is_black(u, (x + d * PX_MM) / m.radius_mm()) != m.is_black(u, psi)
                });
                if !near_edge && t.black[j * t.w + i] != m.is_black(u, psi) {
                    bad += 1;
                }
            }
        }
        assert_eq!(bad, 0);
    }
}

/// The wrap rule, checked on a simulated rod. The page lies flat, print up: page `x` right,
/// page `y` (= `u`) down, `z = x * y` into the paper, so the print faces `-z`. The paper is
/// wrapped print side out around a rod behind it whose axis runs along `+y` (= `+u`); the rod
/// then turns right-handed about `+u` by `theta`. A camera looks at the rod from a fixed
/// direction; the page line it sees must read `psi = theta + const`.
#[test]
fn wrapped_print_reads_theta_plus_const() {
    let m = v1();
    let t = &placed_textures(&[(0, &m)], &PrintOptions::default())[0];
    let r = m.radius_mm();
    let c = circumference_mm(&m);
    // Page x (from psi = 0) -> point on the rod, relative to the axis, and its outward normal.
    let wrap = |x: f64| -> [f64; 3] { [r * (x / r).sin(), 0.0, -r * (x / r).cos()] };
    // Print side out: the print normal -(d/dx x d/dy) equals the outward radial direction.
    for x in [0.0, 7.0, 20.0, 40.0] {
        let h = 1e-6;
        let (a, b) = (wrap(x + h), wrap(x - h));
        let dx = [(a[0] - b[0]) / (2.0 * h), 0.0, (a[2] - b[2]) / (2.0 * h)];
        let dy = [0.0, 1.0, 0.0];
        let n = [
            -(dx[1] * dy[2] - dx[2] * dy[1]),
            -(dx[2] * dy[0] - dx[0] * dy[2]),
            -(dx[0] * dy[1] - dx[1] * dy[0]),
        ];
        let p = wrap(x);
        for k in 0..3 {
            assert!(
                (n[k] - p[k] / r).abs() < 1e-6,
                "print faces inwards at x = {x}"
            );
        }
    }
    // Right-handed rotation about +y (Rodrigues with axis (0, 1, 0)).
    let rot = |theta: f64, p: [f64; 3]| -> [f64; 3] {
        let (s, co) = theta.sin_cos();
        [co * p[0] + s * p[2], p[1], -s * p[0] + co * p[2]]
    };
    for camera_dir in [[0.0, 0.0, -1.0], [0.6, 0.0, -0.8], [-1.0, 0.0, 0.0]] {
        let mut offsets = Vec::new();
        for n in 0..64 {
            let theta = (n as f64 + 0.5) * TAU / 32.0;
            // The page x whose surface point faces the camera (largest dot product).
            let best_x = (0..20_000)
                .map(|i| (i as f64 + 0.5) * c / 20_000.0)
                .max_by(|&a, &b| {
                    let da = dot(rot(theta, wrap(a)), camera_dir);
                    let db = dot(rot(theta, wrap(b)), camera_dir);
                    da.total_cmp(&db)
                })
                .unwrap();
            let step = t.decode(&m, best_x / r);
            offsets.push((step + 64 - n % 32) % 32);
        }
        // The decoded step minus theta's step is the same at every angle: psi = theta + const
        // (with the opposite wrap it would be psi = const - theta and the difference would run).
        assert!(
            offsets.iter().all(|o| *o == offsets[0]),
            "camera {camera_dir:?}: {offsets:?}"
        );
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

// ---------------------------------------------------------------------------------------------
// PDF

/// Checks the cross-reference table: every offset points at `N 0 obj`, `startxref` points at
/// `xref`, `/Size` and every stream's `/Length` are right. Returns the number of pages.
fn check_pdf_structure(bytes: &[u8]) -> usize {
    assert!(bytes.starts_with(b"%PDF-1.4\n"));
    // Byte for byte (the binary comment becomes '?'), so string offsets are byte offsets.
    let text: String = bytes
        .iter()
        .map(|&b| if b.is_ascii() { b as char } else { '?' })
        .collect();
    assert!(text.ends_with("%%EOF\n"));
    let sx = text.rfind("startxref\n").unwrap();
    let xref_at: usize = text[sx + 10..].lines().next().unwrap().parse().unwrap();
    assert!(bytes[xref_at..].starts_with(b"xref\n"));
    let mut lines = text[xref_at..].lines().skip(1);
    let header: Vec<usize> = lines
        .next()
        .unwrap()
        .split(' ')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(header[0], 0);
    let n = header[1];
    // Every entry is exactly 20 bytes.
    let table = &bytes[xref_at + 5 + format!("0 {n}\n").len()..];
    assert!(table[..20].starts_with(b"0000000000 65535 f"));
    for id in 1..n {
        let e = &table[20 * id..20 * id + 20];
        assert_eq!(&e[10..], b" 00000 n \n", "entry {id}");
        let off: usize = std::str::from_utf8(&e[..10]).unwrap().parse().unwrap();
        assert!(
            bytes[off..].starts_with(format!("{id} 0 obj\n").as_bytes()),
            "object {id}"
        );
    }
    assert!(text.contains(&format!("trailer\n<< /Size {n} /Root 1 0 R")));
    // Streams: /Length matches the bytes between `stream\n` and `endstream`.
    let mut pos = 0;
    let mut streams = 0;
    while let Some(i) = text[pos..].find("/Length ") {
        let at = pos + i + 8;
        let len: usize = text[at..]
            .split(|c: char| !c.is_ascii_digit())
            .next()
            .unwrap()
            .parse()
            .unwrap();
        let data = at + text[at..].find("stream\n").unwrap() + 7;
        assert!(
            bytes[data + len..].starts_with(b"endstream"),
            "stream length"
        );
        streams += 1;
        pos = data + len;
    }
    let pages = text.matches("/Type /Page ").count();
    assert_eq!(streams, pages);
    assert!(text.contains(&format!("/Count {pages}")));
    pages
}

#[test]
fn pdf_is_structurally_valid() {
    let m = v1();
    let eight: Vec<(u32, &Marker)> = (0..8).map(|r| (r, &m)).collect();
    let bytes = pdf(&eight, &PrintOptions::default()).unwrap();
    assert_eq!(check_pdf_structure(&bytes), 2);
    let text = String::from_utf8_lossy(&bytes);
    assert!(
        text.contains("/MediaBox [0 0 595.2756 841.8898]"),
        "A4 in points"
    );
    assert!(text.contains("/BaseFont /Helvetica"));
    assert!(text.contains(" re f\n"));
    assert!(text.contains("(rod 7) Tj"));
    let one = pdf(
        &[(2, &m)],
        &PrintOptions {
            page: PageSize::Fit,
            ..PrintOptions::default()
        },
    )
    .unwrap();
    assert_eq!(check_pdf_structure(&one), 1);
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rodtrack-marker-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A binary PGM (P5, 8 bit) as (width, height, pixels).
fn read_pgm(bytes: &[u8]) -> (usize, usize, Vec<u8>) {
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        if bytes[i] == b'#' {
            while bytes[i] != b'\n' {
                i += 1;
            }
            continue;
        }
        let s = i;
        while !bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&bytes[s..i]).into_owned());
    }
    assert_eq!(fields[0], "P5");
    let (w, h): (usize, usize) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    assert_eq!(fields[3], "255");
    let data = bytes[i + 1..i + 1 + w * h].to_vec();
    (w, h, data)
}

/// Renders the PDF with poppler's `pdftoppm` at 10 px/mm and reads the markers back: page size,
/// barcode edges to 0.15 mm, the kernel, every Gray step. Skipped when `pdftoppm` is missing.
#[test]
fn pdf_renders_at_exact_size() {
    if std::process::Command::new("pdftoppm")
        .arg("-v")
        .output()
        .is_err()
    {
        eprintln!(
            "SKIPPED pdf_renders_at_exact_size: pdftoppm not found (apt-get install poppler-utils)"
        );
        return;
    }
    let m = v1();
    let rods: Vec<(u32, &Marker)> = (0..3).map(|r| (r, &m)).collect();
    let opts = PrintOptions::default();
    let dir = tmpdir("pdf");
    let file = dir.join("m.pdf");
    std::fs::write(&file, pdf(&rods, &opts).unwrap()).unwrap();
    let status = std::process::Command::new("pdftoppm")
        .args([
            "-gray",
            "-r",
            "254",
            "-aa",
            "no",
            "-aaVector",
            "no",
            "-singlefile",
        ])
        .arg(&file)
        .arg(dir.join("m"))
        .status()
        .unwrap();
    assert!(status.success());
    let (w, h, px) = read_pgm(&std::fs::read(dir.join("m.pgm")).unwrap());
    assert!(
        w.abs_diff(2100) <= 1 && h.abs_diff(2970) <= 1,
        "A4 at 10 px/mm, got {w} x {h}"
    );
    let dark = |x_mm: f64, y_mm: f64| -> bool {
        let (i, j) = ((x_mm * 10.0) as usize, (y_mm * 10.0) as usize);
        px[j * w + i] < 128
    };
    let page = &layout(&rods, &opts).unwrap()[0];
    for pl in &page.markers {
        let c = pl.circumference_mm;
        // The kernel along the middle of the strip.
        let read: Vec<bool> = (0..16)
            .map(|i| dark(pl.x_mm + c * 0.5, pl.y_mm + 6.0 + 4.0 * i as f64))
            .collect();
        assert_eq!(read, m.kernel(), "rod {}", pl.rod);
        // Barcode edges found by scanning down a column, within 0.15 mm of the spec.
        let col = ((pl.x_mm + c * 0.3) * 10.0) as usize;
        let j0 = (pl.y_mm * 10.0) as usize;
        let mut edges = Vec::new();
        let mut prev = false;
        for j in j0..j0 + 700 {
            let b = px[j * w + col] < 128;
            if b != prev {
                edges.push(((j as f64) / 10.0 - pl.y_mm, b));
            }
            prev = b;
        }
        let want = m.barcode_edges_mm();
        assert_eq!(edges.len(), want.len(), "{edges:?}");
        for (a, b) in edges.iter().zip(&want) {
            assert!((a.0 - b.0).abs() <= 0.15 && a.1 == b.1, "{a:?} vs {b:?}");
        }
        // Gray steps decode at their centres, across the page's x (psi).
        for n in 0..32u32 {
            let x = pl.x_mm + (n as f64 + 0.5) * c / 32.0;
            let mut code = 0;
            for k in 0..5 {
                if dark(x, pl.y_mm + m.bit_space_centre_mm(k)) {
                    code |= 1 << k;
                }
            }
            assert_eq!(gray_decode(code), n, "rod {} step {n}", pl.rod);
        }
        // The strip's right edge (psi = 2 pi) is where bit 4's last stripe ends.
        let y4 = ((pl.y_mm + m.bit_space_centre_mm(4)) * 10.0) as usize;
        let (i0, i1) = (
            (pl.x_mm * 10.0) as usize,
            ((pl.x_mm + c + 3.0) * 10.0) as usize,
        );
        let last = (i0..i1).rev().find(|&i| px[y4 * w + i] < 128).unwrap();
        let right_mm = (last + 1) as f64 / 10.0;
        assert!((right_mm - (pl.x_mm + c)).abs() <= 0.15, "{right_mm}");
    }
    // The 10 mm check bar across: 100 dark pixels in its row.
    let bar = page
        .shapes
        .iter()
        .find_map(|s| match s {
            Shape::Rect(r) if r.kind == RectKind::CheckBar && r.w_mm > r.h_mm => Some(*r),
            _ => None,
        })
        .unwrap();
    let j = ((bar.y_mm + bar.h_mm * 0.5) * 10.0) as usize;
    let (i0, i1) = (
        ((bar.x_mm - 3.0) * 10.0) as usize,
        ((bar.x_mm + 11.0) * 10.0) as usize,
    );
    let run = (i0..i1).filter(|&i| px[j * w + i] < 128).count();
    assert!((99..=101).contains(&run), "check bar is {run} px");
    let _ = std::fs::remove_dir_all(&dir);
}
