//! Conversions from decoded planes to rodtrack's packed pixel formats, in plain Rust.
//!
//! A decoder hands out planes whose rows are padded (a 1440 px grey row is often 1472 or 1536
//! bytes apart): every function here reads rows through [`Plane`] with its own stride and
//! writes packed rows (`width * bytes_per_pixel`) into `dst`. A plane shorter than its rows
//! need is an error, never a panic.

/// One decoded image plane: `rows` rows of `stride` bytes (the last one may be shorter).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Plane<'a> {
    /// The plane's bytes.
    pub data: &'a [u8],
    /// Bytes from one row to the next.
    pub stride: usize,
}

impl<'a> Plane<'a> {
    /// The first `len` bytes of row `y`.
    fn row(&self, y: usize, len: usize) -> Result<&'a [u8], String> {
        let start = y * self.stride;
        self.data.get(start..start + len).ok_or_else(|| {
            format!(
                "decoded plane too short: row {y} needs bytes {start}..{}, plane has {}",
                start + len,
                self.data.len()
            )
        })
    }
}

/// Packed output rows of `row_bytes` bytes; `dst.len()` must be `row_bytes * height`.
fn out_rows(dst: &mut [u8], row_bytes: usize) -> std::slice::ChunksExactMut<'_, u8> {
    dst.chunks_exact_mut(row_bytes.max(1))
}

/// Copies `height` rows of `row_bytes` bytes, dropping the padding.
pub(crate) fn copy_rows(src: Plane<'_>, row_bytes: usize, dst: &mut [u8]) -> Result<(), String> {
    for (y, d) in out_rows(dst, row_bytes).enumerate() {
        d.copy_from_slice(src.row(y, row_bytes)?);
    }
    Ok(())
}

/// Copies 16-bit big-endian rows to little-endian packed rows.
pub(crate) fn copy_rows_swap16(
    src: Plane<'_>,
    row_bytes: usize,
    dst: &mut [u8],
) -> Result<(), String> {
    for (y, d) in out_rows(dst, row_bytes).enumerate() {
        let s = src.row(y, row_bytes)?;
        for (dp, sp) in d.chunks_exact_mut(2).zip(s.chunks_exact(2)) {
            dp[0] = sp[1];
            dp[1] = sp[0];
        }
    }
    Ok(())
}

/// The table that maps limited-range luma (16..=235) to full range (0..=255), rounded.
pub(crate) fn limited_to_full_lut() -> [u8; 256] {
    let mut lut = [0u8; 256];
    for (v, out) in lut.iter_mut().enumerate() {
        let full = ((v as i32 - 16) * 255 * 2 + 219) / (219 * 2);
        *out = full.clamp(0, 255) as u8;
    }
    lut
}

/// A YUV plane's luma as `mono8`: copied, or mapped through `lut` (limited range).
pub(crate) fn luma_rows(
    src: Plane<'_>,
    width: usize,
    lut: Option<&[u8; 256]>,
    dst: &mut [u8],
) -> Result<(), String> {
    match lut {
        None => copy_rows(src, width, dst),
        Some(lut) => {
            for (y, d) in out_rows(dst, width).enumerate() {
                for (o, &v) in d.iter_mut().zip(src.row(y, width)?) {
                    *o = lut[usize::from(v)];
                }
            }
            Ok(())
        }
    }
}

/// rodtrack's luminance of an RGB pixel: `(r + 2 g + b) / 4`, rounded (the core's formula).
#[inline]
pub(crate) fn rgb_luma(r: u8, g: u8, b: u8) -> u8 {
    ((u16::from(r) + 2 * u16::from(g) + u16::from(b) + 2) / 4) as u8
}

/// Where R, G and B sit in a packed pixel of `bytes` bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct PackedRgb {
    /// Byte offsets of R, G, B.
    pub rgb: [usize; 3],
    /// Bytes per pixel (3 or 4).
    pub bytes: usize,
}

/// Packed RGB-family rows to `rgb8` (`mono == false`) or `mono8` luminance.
pub(crate) fn packed_rgb_rows(
    src: Plane<'_>,
    width: usize,
    layout: PackedRgb,
    mono: bool,
    dst: &mut [u8],
) -> Result<(), String> {
    let [ro, go, bo] = layout.rgb;
    let out_px = if mono { 1 } else { 3 };
    for (y, d) in out_rows(dst, width * out_px).enumerate() {
        let s = src.row(y, width * layout.bytes)?;
        if mono {
            for (o, p) in d.iter_mut().zip(s.chunks_exact(layout.bytes)) {
                *o = rgb_luma(p[ro], p[go], p[bo]);
            }
        } else if layout
            == (PackedRgb {
                rgb: [0, 1, 2],
                bytes: 3,
            })
        {
            d.copy_from_slice(s);
        } else {
            for (o, p) in d.chunks_exact_mut(3).zip(s.chunks_exact(layout.bytes)) {
                o[0] = p[ro];
                o[1] = p[go];
                o[2] = p[bo];
            }
        }
    }
    Ok(())
}

/// Planar G, B, R rows (FFmpeg's `gbrp`) to `rgb8` or `mono8` luminance.
pub(crate) fn gbrp_rows(
    g: Plane<'_>,
    b: Plane<'_>,
    r: Plane<'_>,
    width: usize,
    mono: bool,
    dst: &mut [u8],
) -> Result<(), String> {
    let out_px = if mono { 1 } else { 3 };
    for (y, d) in out_rows(dst, width * out_px).enumerate() {
        let (gr, br, rr) = (g.row(y, width)?, b.row(y, width)?, r.row(y, width)?);
        if mono {
            for (((o, &gv), &bv), &rv) in d.iter_mut().zip(gr).zip(br).zip(rr) {
                *o = rgb_luma(rv, gv, bv);
            }
        } else {
            for (((o, &gv), &bv), &rv) in d.chunks_exact_mut(3).zip(gr).zip(br).zip(rr) {
                o[0] = rv;
                o[1] = gv;
                o[2] = bv;
            }
        }
    }
    Ok(())
}

/// How a YUV frame's chroma is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ChromaLayout {
    /// log2 of the horizontal and vertical chroma subsampling (4:2:0 is `(1, 1)`).
    pub shift: (u32, u32),
    /// U: (plane, byte offset in a chroma sample, bytes per chroma sample).
    pub u: (usize, usize, usize),
    /// V: (plane, byte offset, bytes per chroma sample).
    pub v: (usize, usize, usize),
}

/// YUV to RGB coefficients, fixed point with 8 fractional bits.
#[derive(Debug, Clone, Copy)]
struct YuvCoeffs {
    y_off: i32,
    ky: i32,
    rv: i32,
    gu: i32,
    gv: i32,
    bu: i32,
}

fn yuv_coeffs(limited: bool, bt709: bool) -> YuvCoeffs {
    match (limited, bt709) {
        (true, false) => YuvCoeffs {
            y_off: 16,
            ky: 298,
            rv: 409,
            gu: 100,
            gv: 208,
            bu: 516,
        },
        (false, false) => YuvCoeffs {
            y_off: 0,
            ky: 256,
            rv: 359,
            gu: 88,
            gv: 183,
            bu: 454,
        },
        (true, true) => YuvCoeffs {
            y_off: 16,
            ky: 298,
            rv: 459,
            gu: 55,
            gv: 136,
            bu: 541,
        },
        (false, true) => YuvCoeffs {
            y_off: 0,
            ky: 256,
            rv: 403,
            gu: 48,
            gv: 120,
            bu: 475,
        },
    }
}

/// 8-bit YUV (planar or semi-planar, any subsampling) to `rgb8`, nearest chroma sample.
/// `planes` holds the frame's planes (luma first).
pub(crate) fn yuv_to_rgb_rows(
    planes: &[Plane<'_>],
    width: usize,
    chroma: ChromaLayout,
    limited: bool,
    bt709: bool,
    dst: &mut [u8],
) -> Result<(), String> {
    let c = yuv_coeffs(limited, bt709);
    let plane = |i: usize| {
        planes
            .get(i)
            .copied()
            .ok_or_else(|| format!("decoded frame has no plane {i}"))
    };
    let (yp, up, vp) = (plane(0)?, plane(chroma.u.0)?, plane(chroma.v.0)?);
    let (sx, sy) = chroma.shift;
    let cw = (width + (1 << sx) - 1) >> sx;
    for (y, d) in out_rows(dst, width * 3).enumerate() {
        let yr = yp.row(y, width)?;
        let ur = up.row(y >> sy, cw * chroma.u.2)?;
        let vr = vp.row(y >> sy, cw * chroma.v.2)?;
        for (x, (o, &yv)) in d.chunks_exact_mut(3).zip(yr).enumerate() {
            let cx = x >> sx;
            let u = i32::from(ur[cx * chroma.u.2 + chroma.u.1]) - 128;
            let v = i32::from(vr[cx * chroma.v.2 + chroma.v.1]) - 128;
            let yy = (i32::from(yv) - c.y_off) * c.ky + 128;
            o[0] = ((yy + c.rv * v) >> 8).clamp(0, 255) as u8;
            o[1] = ((yy - c.gu * u - c.gv * v) >> 8).clamp(0, 255) as u8;
            o[2] = ((yy + c.bu * u) >> 8).clamp(0, 255) as u8;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn copy_rows_drops_padding() {
        let src: Vec<u8> = (0..4 * 8).map(|i| i as u8).collect();
        let mut dst = vec![0u8; 3 * 4];
        copy_rows(
            Plane {
                data: &src,
                stride: 8,
            },
            3,
            &mut dst,
        )
        .unwrap();
        assert_eq!(dst, [0, 1, 2, 8, 9, 10, 16, 17, 18, 24, 25, 26]);
    }

    #[test]
    fn short_plane_is_an_error() {
        let src = [0u8; 10];
        let mut dst = vec![0u8; 12];
        let e = copy_rows(
            Plane {
                data: &src,
                stride: 4,
            },
            4,
            &mut dst,
        )
        .unwrap_err();
        assert!(e.contains("too short"), "{e}");
    }

    #[test]
    fn limited_range_round_trips_within_one() {
        let lut = limited_to_full_lut();
        assert_eq!((lut[16], lut[235], lut[0], lut[255]), (0, 255, 0, 255));
        for v in 0..=255u8 {
            // what swscale does for grey -> limited-range luma
            let limited = (16.0 + f64::from(v) * 219.0 / 255.0).round() as u8;
            assert!(lut[usize::from(limited)].abs_diff(v) <= 1, "{v}");
        }
    }

    #[test]
    fn packed_rgb_orders_and_luma() {
        // bgr0, 2 px, stride 12
        let src = [30u8, 20, 10, 0, 3, 2, 1, 0, 9, 9, 9, 9];
        let plane = Plane {
            data: &src,
            stride: 12,
        };
        let layout = PackedRgb {
            rgb: [2, 1, 0],
            bytes: 4,
        };
        let mut rgb = [0u8; 6];
        packed_rgb_rows(plane, 2, layout, false, &mut rgb).unwrap();
        assert_eq!(rgb, [10, 20, 30, 1, 2, 3]);
        let mut mono = [0u8; 2];
        packed_rgb_rows(plane, 2, layout, true, &mut mono).unwrap();
        assert_eq!(mono, [rgb_luma(10, 20, 30), rgb_luma(1, 2, 3)]);
        assert_eq!(rgb_luma(10, 20, 30), 20);
    }

    #[test]
    fn grey_yuv_gives_grey_rgb() {
        // 4x2 4:2:0, neutral chroma: R = G = B = full-range luma
        let y = [16u8, 50, 128, 235, 16, 50, 128, 235];
        let u = [128u8, 128];
        let v = [128u8, 128];
        let planes = [
            Plane {
                data: &y,
                stride: 4,
            },
            Plane {
                data: &u,
                stride: 2,
            },
            Plane {
                data: &v,
                stride: 2,
            },
        ];
        let chroma = ChromaLayout {
            shift: (1, 1),
            u: (1, 0, 1),
            v: (2, 0, 1),
        };
        let mut dst = [0u8; 24];
        yuv_to_rgb_rows(&planes, 4, chroma, true, false, &mut dst).unwrap();
        let lut = limited_to_full_lut();
        for (i, px) in dst.chunks_exact(3).enumerate() {
            let want = lut[usize::from(y[i])];
            for &c in px {
                assert!(c.abs_diff(want) <= 1, "{i}: {px:?} vs {want}");
            }
        }
    }
}
