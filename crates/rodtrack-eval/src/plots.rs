//! Line plots for the evaluation report, as PNG and SVG (plotters, bundled DejaVu Sans font: no
//! system font library).
//!
//! A [`Figure`] is a stack of [`Panel`]s sharing the figure's width; every panel holds line
//! [`Series`]. A NaN in a series breaks its line (a gap where the rod was not measured).

use crate::{EvalError, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// DejaVu Sans (Bitstream Vera licence, see `assets/DejaVuSans-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static FONT_ONCE: Once = Once::new();

fn register_font() {
    FONT_ONCE.call_once(|| {
        // The font is bundled and known good; a failure would only lose the labels.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Line {
    /// Solid line of this width (px).
    Solid(u32),
    /// Dots of this radius (px), no line: for noisy raw measurements.
    Dots(u32),
}

/// One curve.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Colour.
    pub colour: RGBColor,
    /// Line or dots.
    pub line: Line,
    /// Points `(x, y)`; a NaN `y` breaks the line.
    pub points: Vec<(f64, f64)>,
}

/// One panel (axes).
#[derive(Debug, Clone, Default)]
pub struct Panel {
    /// Caption above the panel.
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
    /// X range (default: the data's).
    pub x_range: Option<(f64, f64)>,
    /// Y range (default: the data's within the x range, with a margin).
    pub y_range: Option<(f64, f64)>,
    /// Curves.
    pub series: Vec<Series>,
}

/// A stack of panels.
#[derive(Debug, Clone, Default)]
pub struct Figure {
    /// Panels, top to bottom.
    pub panels: Vec<Panel>,
    /// Size in px.
    pub size: (u32, u32),
}

/// Colours for up to 8 series (colour-blind-friendly, after Okabe and Ito).
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(150, 150, 150),
];

impl Panel {
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let (mut x0, mut x1) = (f64::INFINITY, f64::NEG_INFINITY);
        for s in &self.series {
            for &(x, y) in &s.points {
                if x.is_finite() && y.is_finite() {
                    x0 = x0.min(x);
                    x1 = x1.max(x);
                }
            }
        }
        let xr = self.x_range.unwrap_or((x0, x1));
        let xr = fix_range(xr);
        let yr = self.y_range.unwrap_or_else(|| {
            let (mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY);
            for s in &self.series {
                for &(x, y) in &s.points {
                    if x >= xr.0 && x <= xr.1 && y.is_finite() {
                        y0 = y0.min(y);
                        y1 = y1.max(y);
                    }
                }
            }
            let m = 0.05 * (y1 - y0).max(1e-9);
            (y0 - m, y1 + m)
        });
        (xr, fix_range(yr))
    }
}

fn fix_range((a, b): (f64, f64)) -> (f64, f64) {
    if !(a.is_finite() && b.is_finite()) {
        (0.0, 1.0)
    } else if b - a < 1e-9 {
        (a - 0.5, b + 0.5)
    } else {
        (a, b)
    }
}

/// Splits points at NaNs into drawable runs.
fn runs(points: &[(f64, f64)]) -> Vec<&[(f64, f64)]> {
    points
        .split(|p| !(p.0.is_finite() && p.1.is_finite()))
        .filter(|r| !r.is_empty())
        .collect()
}

fn err<E: std::fmt::Debug>(e: E) -> EvalError {
    EvalError::Failed(format!("plotting: {e:?}"))
}

/// `e` in the context `what` (`drawing fig13.png`).
fn context(what: String) -> impl FnOnce(EvalError) -> EvalError {
    move |e| EvalError::Plot {
        context: what,
        source: Box::new(e),
    }
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let ((x0, x1), (y0, y1)) = p.ranges();
    let mut chart = ChartBuilder::on(area)
        .caption(&p.title, ("sans-serif", 18))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;
    for s in &p.series {
        let colour = s.colour;
        // Points outside the x range are dropped (zoom panels); keep one on either side so
        // lines reach the frame.
        let inside: Vec<(f64, f64)> = s
            .points
            .iter()
            .map(|&(x, y)| {
                if x >= x0 && x <= x1 {
                    (x, y.clamp(y0 - (y1 - y0), y1 + (y1 - y0)))
                } else {
                    (x, f64::NAN)
                }
            })
            .collect();
        let mut first = true;
        for run in runs(&inside) {
            let anno = match s.line {
                Line::Solid(w) => chart
                    .draw_series(LineSeries::new(run.iter().copied(), colour.stroke_width(w)))
                    .map_err(err)?,
                Line::Dots(r) => chart
                    .draw_series(
                        run.iter()
                            .map(|&(x, y)| Circle::new((x, y), r, colour.filled())),
                    )
                    .map_err(err)?,
            };
            if first && !s.label.is_empty() {
                first = false;
                anno.label(s.label.as_str()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(3))
                });
            }
        }
    }
    if p.series.iter().any(|s| !s.label.is_empty()) {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

fn draw_figure<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, fig: &Figure) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(err)?;
    let n = fig.panels.len().max(1);
    let areas = root.split_evenly((n, 1));
    for (a, p) in areas.iter().zip(&fig.panels) {
        draw_panel(a, p)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// Writes `dir/stem.png` and `dir/stem.svg`; returns their paths.
pub fn write_figure(fig: &Figure, dir: &Path, stem: &str) -> Result<(PathBuf, PathBuf)> {
    register_font();
    let (w, h) = fig.size;
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    let mut rgb = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        draw_figure(root, fig).map_err(context(format!("drawing {}", png.display())))?;
    }
    image::save_buffer(&png, &rgb, w, h, image::ExtendedColorType::Rgb8)
        .map_err(|e| EvalError::Failed(e.to_string()))
        .map_err(context(format!("writing {}", png.display())))?;
    {
        let root = SVGBackend::new(&svg, (w, h)).into_drawing_area();
        draw_figure(root, fig).map_err(context(format!("writing {}", svg.display())))?;
    }
    Ok((png, svg))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_png_and_svg_with_gaps() {
        let dir = std::env::temp_dir().join(format!("rodtrack-plots-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut pts: Vec<(f64, f64)> = (0..200)
            .map(|i| (i as f64, (i as f64 * 0.1).sin()))
            .collect();
        pts[50].1 = f64::NAN;
        let fig = Figure {
            size: (600, 400),
            panels: vec![
                Panel {
                    title: "sine".into(),
                    x_label: "t".into(),
                    y_label: "y".into(),
                    series: vec![Series {
                        label: "sin".into(),
                        colour: PALETTE[0],
                        line: Line::Solid(2),
                        points: pts.clone(),
                    }],
                    ..Panel::default()
                },
                Panel {
                    x_range: Some((10.0, 20.0)),
                    series: vec![Series {
                        label: String::new(),
                        colour: PALETTE[1],
                        line: Line::Dots(2),
                        points: pts,
                    }],
                    ..Panel::default()
                },
            ],
        };
        let (png, svg) = write_figure(&fig, &dir, "t").unwrap();
        let img = image::open(&png).unwrap();
        assert_eq!((img.width(), img.height()), (600, 400));
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("<svg") && text.contains("sine"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
