//! Colour from the mosaic: one RGB sample per Bayer quad (2 x 2 pixels), its chromaticity, and
//! the calibrated ball / field colour model that classifies it.

use crate::{FrameView, PixelFormat};

/// Where red and blue sit in a 2 x 2 quad (indices `0` = top left, `1` = top right, `2` =
/// bottom left, `3` = bottom right; the two others are green), or an RGB image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadLayout {
    kind: Kind,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Bayer { r: usize, b: usize, wide: bool },
    Rgb8,
}

impl QuadLayout {
    /// The layout of `format`; `None` for formats without colour (mono).
    pub fn of(format: PixelFormat) -> Option<QuadLayout> {
        use PixelFormat::*;
        let kind = match format {
            BayerRggb8 => Kind::Bayer {
                r: 0,
                b: 3,
                wide: false,
            },
            BayerBggr8 => Kind::Bayer {
                r: 3,
                b: 0,
                wide: false,
            },
            BayerGrbg8 => Kind::Bayer {
                r: 1,
                b: 2,
                wide: false,
            },
            BayerGbrg8 => Kind::Bayer {
                r: 2,
                b: 1,
                wide: false,
            },
            BayerRggb16 => Kind::Bayer {
                r: 0,
                b: 3,
                wide: true,
            },
            BayerBggr16 => Kind::Bayer {
                r: 3,
                b: 0,
                wide: true,
            },
            BayerGrbg16 => Kind::Bayer {
                r: 1,
                b: 2,
                wide: true,
            },
            BayerGbrg16 => Kind::Bayer {
                r: 2,
                b: 1,
                wide: true,
            },
            Rgb8 => Kind::Rgb8,
            _ => return None,
        };
        Some(QuadLayout { kind })
    }

    /// The mean `[R, G, B]` of quad `(qx, qy)` (pixels `2 qx .. 2 qx + 1`, `2 qy .. 2 qy + 1`),
    /// 8-bit scale. The caller keeps the quad inside the view (`qx < width / 2`, `qy < height
    /// / 2`).
    #[inline(always)]
    pub fn rgb(&self, view: &FrameView, qx: usize, qy: usize) -> [f32; 3] {
        let d = view.data();
        let s = view.stride();
        match self.kind {
            Kind::Bayer { r, b, wide } => {
                let px = |i: usize| -> f32 {
                    let (x, y) = (2 * qx + (i & 1), 2 * qy + (i >> 1));
                    if wide {
                        let o = y * s + 2 * x;
                        u16::from_le_bytes([d[o], d[o + 1]]) as f32 / 256.0
                    } else {
                        d[y * s + x] as f32
                    }
                };
                let v = [px(0), px(1), px(2), px(3)];
                let g = 0.5 * (v[0] + v[1] + v[2] + v[3] - v[r] - v[b]);
                [v[r], g, v[b]]
            }
            Kind::Rgb8 => {
                let mut acc = [0.0f32; 3];
                for i in 0..4 {
                    let (x, y) = (2 * qx + (i & 1), 2 * qy + (i >> 1));
                    let o = y * s + 3 * x;
                    for c in 0..3 {
                        acc[c] += d[o + c] as f32;
                    }
                }
                acc.map(|v| 0.25 * v)
            }
        }
    }

    /// Calls `f(k, rgb)` with [`QuadLayout::rgb`] of quads `(qx0 + k step, qy)`, `k < n`, the
    /// layout matched once for the row (the same values, bit for bit). The caller keeps the
    /// quads inside the view.
    #[inline(always)]
    pub fn for_row(
        &self,
        view: &FrameView,
        qy: usize,
        qx0: usize,
        step: usize,
        n: usize,
        mut f: impl FnMut(usize, [f32; 3]),
    ) {
        if let Kind::Bayer { r, b, wide: false } = self.kind {
            let (d, s) = (view.data(), view.stride());
            let end = 2 * (qx0 + n.saturating_sub(1) * step) + 2;
            let rows = (
                d.get(2 * qy * s..2 * qy * s + end),
                d.get((2 * qy + 1) * s..(2 * qy + 1) * s + end),
            );
            if let (Some(top), Some(bottom)) = rows {
                // The four Bayer layouts with their red and blue places as constants (indexing
                // the quad by a variable costs more than the colour's arithmetic).
                let row = (top, bottom, qx0, step, n);
                match (r, b) {
                    (0, 3) => bayer_row::<0, 3>(row, f),
                    (3, 0) => bayer_row::<3, 0>(row, f),
                    (1, 2) => bayer_row::<1, 2>(row, f),
                    (2, 1) => bayer_row::<2, 1>(row, f),
                    _ => {
                        for k in 0..n {
                            f(k, quad_rgb(top, bottom, 2 * (qx0 + k * step), r, b));
                        }
                    }
                }
                return;
            }
        }
        for k in 0..n {
            f(k, self.rgb(view, qx0 + k * step, qy));
        }
    }
}

/// The colour of the 8-bit Bayer quad at byte `x` of the rows `top` and `bottom`, red at
/// place `r` and blue at `b` of the quad (0, 1 on top, 2, 3 below): as [`QuadLayout::rgb`].
#[inline(always)]
fn quad_rgb(top: &[u8], bottom: &[u8], x: usize, r: usize, b: usize) -> [f32; 3] {
    let v = [
        top[x] as f32,
        top[x + 1] as f32,
        bottom[x] as f32,
        bottom[x + 1] as f32,
    ];
    let g = 0.5 * (v[0] + v[1] + v[2] + v[3] - v[r] - v[b]);
    [v[r], g, v[b]]
}

/// [`QuadLayout::for_row`] over 8-bit Bayer rows `(top, bottom, qx0, step, n)` with red at
/// place `R` and blue at `B`.
#[inline(always)]
fn bayer_row<const R: usize, const B: usize>(
    (top, bottom, qx0, step, n): (&[u8], &[u8], usize, usize, usize),
    mut f: impl FnMut(usize, [f32; 3]),
) {
    for k in 0..n {
        f(k, quad_rgb(top, bottom, 2 * (qx0 + k * step), R, B));
    }
}

/// Chromaticity `(R, G) / (R + G + B)` (independent of shading); `None` for a black sample.
#[inline]
pub fn chroma(rgb: [f32; 3]) -> Option<[f32; 2]> {
    let s = rgb[0] + rgb[1] + rgb[2];
    (s > 1.0).then(|| [rgb[0] / s, rgb[1] / s])
}

/// How far apart (in chromaticity) a calibrated colour's samples may be: this many standard
/// deviations of the spread calibration measured (a statistical bound, not a tuned value).
pub const SPREAD_SIGMAS: f32 = 4.0;

/// [`ColourModel::alpha`] of a sample that is no mixture of field and ball: an occluder (a
/// rod, a figure, a hand) or the ball's highlight.
pub const OFF_AXIS: f32 = -1.0e3;

/// The ball's and the field's colours as calibration measured them, ready to classify quads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColourModel {
    ball: [f32; 2],
    field: [f32; 2],
    ball_thr: f32,
    field_thr: f32,
    axis: [f32; 2],
    /// Unit normal of the field -> ball line in chromaticity.
    normal: [f32; 2],
    /// How far from that line (chromaticity), and beyond its ends (in `alpha`), a mixture of
    /// the two colours may fall: the larger of the two colours' spreads.
    mix_thr: f32,
    mix_alpha_thr: f32,
}

impl ColourModel {
    /// From mean colours (RGB) and chromaticity spreads (RMS distance of a sample from the
    /// mean); `None` when a colour is black.
    pub fn new(
        ball_rgb: [f64; 3],
        ball_spread: f64,
        field_rgb: [f64; 3],
        field_spread: f64,
    ) -> Option<ColourModel> {
        let b = chroma(ball_rgb.map(|v| v as f32))?;
        let f = chroma(field_rgb.map(|v| v as f32))?;
        let d = [b[0] - f[0], b[1] - f[1]];
        let n2 = d[0] * d[0] + d[1] * d[1];
        if n2.is_nan() || n2 <= 0.0 {
            return None;
        }
        let n = n2.sqrt();
        let mix_thr = SPREAD_SIGMAS * ball_spread.max(field_spread) as f32;
        Some(ColourModel {
            ball: b,
            field: f,
            ball_thr: SPREAD_SIGMAS * ball_spread as f32,
            field_thr: SPREAD_SIGMAS * field_spread as f32,
            axis: [d[0] / n2, d[1] / n2],
            normal: [-d[1] / n, d[0] / n],
            mix_thr,
            mix_alpha_thr: mix_thr / n,
        })
    }

    /// Distance of the chromaticities of ball and field.
    pub fn separation(&self) -> f32 {
        dist(self.ball, self.field)
    }

    /// A sample of the ball's colour: within the ball's spread and nearer the ball than the
    /// field.
    #[inline]
    pub fn is_ball(&self, rgb: [f32; 3]) -> bool {
        // In chromaticity: |c - ball| < thr and |c - ball| < |c - field|, c = (R, G) / S. Both
        // sides times S (squared), so without a division or a root per sample.
        let s = rgb[0] + rgb[1] + rgb[2];
        let db = scaled_dist2(rgb, self.ball, s);
        s > 1.0
            && db < self.ball_thr * self.ball_thr * s * s
            && db < scaled_dist2(rgb, self.field, s)
    }

    /// A sample of the empty field's colour.
    #[inline]
    pub fn is_field(&self, rgb: [f32; 3]) -> bool {
        // As in `is_ball`, times the sample's sum.
        let s = rgb[0] + rgb[1] + rgb[2];
        let df = scaled_dist2(rgb, self.field, s);
        s > 1.0
            && df < self.field_thr * self.field_thr * s * s
            && df < scaled_dist2(rgb, self.ball, s)
    }

    /// Position of the sample along the field -> ball chromaticity axis (0 field, 1 ball), or
    /// [`OFF_AXIS`] for a colour that is no mixture of the two (off their line, or beyond
    /// its ends, by more than their spreads): a grey rod, say, whose chromaticity projects
    /// between them. A black sample counts as field (a shadow).
    #[inline]
    pub fn alpha(&self, rgb: [f32; 3]) -> f32 {
        // In chromaticity times the sample's sum `s` (as `is_ball`): one division, for an
        // on-axis sample only.
        let s = rgb[0] + rgb[1] + rgb[2];
        if s <= 1.0 {
            return 0.0;
        }
        let (dx, dy) = (rgb[0] - self.field[0] * s, rgb[1] - self.field[1] * s);
        let a_s = dx * self.axis[0] + dy * self.axis[1];
        let off_s = (dx * self.normal[0] + dy * self.normal[1]).abs();
        if off_s > self.mix_thr * s
            || a_s < -self.mix_alpha_thr * s
            || a_s > (1.0 + self.mix_alpha_thr) * s
        {
            OFF_AXIS
        } else {
            a_s / s
        }
    }
}

/// The squared chromaticity distance of `rgb` (sum `s`) from `c`, times `s` squared.
#[inline]
fn scaled_dist2(rgb: [f32; 3], c: [f32; 2], s: f32) -> f32 {
    (rgb[0] - c[0] * s).powi(2) + (rgb[1] - c[1] * s).powi(2)
}

#[inline]
fn dist(a: [f32; 2], b: [f32; 2]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row's quads read at once are each quad's own colour, bit for bit, in every layout.
    #[test]
    fn a_row_of_quads_is_each_quad_read_alone() {
        let (w, h) = (24, 6);
        // Bytes that fill every value's range (a fixed pseudo-random sequence).
        let data: Vec<u8> = (0..w * h)
            .map(|i: usize| (i.wrapping_mul(2_654_435_761) >> 7) as u8)
            .collect();
        for format in [
            PixelFormat::BayerRggb8,
            PixelFormat::BayerBggr8,
            PixelFormat::BayerGrbg8,
            PixelFormat::BayerGbrg8,
            PixelFormat::BayerRggb16,
        ] {
            let layout = QuadLayout::of(format).unwrap();
            // The same bytes: `w` pixels of 8 bits or `w / 2` of 16 per row.
            let width = w / format.bytes_per_pixel();
            let v = FrameView::new(&data, width, h, w, format).unwrap();
            for (qx0, step) in [(0, 1), (1, 2), (2, 3)] {
                let n = (v.width() / 2 - qx0).div_ceil(step);
                for qy in 0..v.height() / 2 {
                    let mut got = Vec::new();
                    layout.for_row(&v, qy, qx0, step, n, |k, rgb| got.push((k, rgb)));
                    let want: Vec<(usize, [f32; 3])> = (0..n)
                        .map(|k| (k, layout.rgb(&v, qx0 + k * step, qy)))
                        .collect();
                    assert_eq!(got, want, "{format:?} row {qy} from {qx0} step {step}");
                }
            }
        }
    }

    #[test]
    fn bayer_quads_read_their_channels() {
        // RGGB quad: R 200, G 100 and 120, B 40.
        let data = [200u8, 100, 120, 40];
        let v = FrameView::new(&data, 2, 2, 2, PixelFormat::BayerRggb8).unwrap();
        assert_eq!(
            QuadLayout::of(PixelFormat::BayerRggb8)
                .unwrap()
                .rgb(&v, 0, 0),
            [200.0, 110.0, 40.0]
        );
        let v = FrameView::new(&data, 2, 2, 2, PixelFormat::BayerGbrg8).unwrap();
        assert_eq!(
            QuadLayout::of(PixelFormat::BayerGbrg8)
                .unwrap()
                .rgb(&v, 0, 0),
            [120.0, 120.0, 100.0]
        );
        assert!(QuadLayout::of(PixelFormat::Mono8).is_none());
    }

    #[test]
    fn classifies_by_chromaticity_whatever_the_shading() {
        let m = ColourModel::new([240.0, 150.0, 40.0], 0.01, [25.0, 95.0, 30.0], 0.01).unwrap();
        assert!(m.is_ball([120.0, 75.0, 20.0]));
        assert!(!m.is_ball([200.0, 150.0, 115.0]), "skin is not the ball");
        assert!(m.is_field([50.0, 190.0, 60.0]));
        assert!((m.alpha([240.0, 150.0, 40.0]) - 1.0).abs() < 1e-4);
        assert!(m.alpha([25.0, 95.0, 30.0]).abs() < 1e-4);
        // Half and half (a blurred edge): on the line, at the brighter ball's share of the
        // light (a mixture's chromaticity is weighted by brightness: 430 / (430 + 150)).
        let mix = m.alpha([132.5, 122.5, 35.0]);
        assert!((mix - 430.0 / 580.0).abs() < 1e-3, "{mix}");
        // Grey (a rod) projects between field and ball, but is no mixture of them; nor is a
        // red figure, beyond the ball on the line.
        assert_eq!(m.alpha([120.0, 120.0, 120.0]), OFF_AXIS);
        assert_eq!(m.alpha([200.0, 30.0, 30.0]), OFF_AXIS);
    }
}
