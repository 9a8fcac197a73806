//! A small image of a frame for the eye (the web console's live view, a camera node's preview
//! frames): block averaging, Bayer demosaiced by the blocks themselves.

use crate::{FrameView, LumaKind, PixelFormat};

/// A small image for the eye: 8-bit grey (1 channel) or RGB (3 channels), row-major, packed.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Preview {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// 1 (grey) or 3 (RGB).
    pub channels: usize,
    /// Downscale factor from the frame (full-resolution pixel = preview pixel x factor).
    pub factor: usize,
    /// The pixels.
    pub pixels: Vec<u8>,
}

/// Colour channel (0 R, 1 G, 2 B) of Bayer pixel `(x % 2, y % 2)`.
fn bayer_channels(format: PixelFormat) -> [[usize; 2]; 2] {
    // [y % 2][x % 2]
    match format {
        PixelFormat::BayerRggb8 | PixelFormat::BayerRggb16 => [[0, 1], [1, 2]],
        PixelFormat::BayerBggr8 | PixelFormat::BayerBggr16 => [[2, 1], [1, 0]],
        PixelFormat::BayerGrbg8 | PixelFormat::BayerGrbg16 => [[1, 0], [2, 1]],
        _ => [[1, 2], [0, 1]], // GBRG
    }
}

/// Downscales a frame by block averaging so that its width is at most `max_width`: grey for
/// mono, colour for RGB and Bayer (each block averages its own red, green and blue pixels, so a
/// Bayer frame is demosaiced for free; the factor is even for Bayer).
pub fn preview(frame: &FrameView, max_width: usize) -> Preview {
    let mut out = Preview::default();
    preview_into(frame, max_width, &mut out, &mut Vec::new());
    out
}

/// [`preview`] into `out`, reusing its pixel buffer and the scratch row `acc` (no allocation
/// once they have held a preview of this size: a camera node's preview thread calls it a few
/// times per second).
pub fn preview_into(frame: &FrameView, max_width: usize, out: &mut Preview, acc: &mut Vec<u32>) {
    let (w, h) = (frame.width(), frame.height());
    let kind = frame.format().luma_kind();
    let mut f = w.div_ceil(max_width.max(1)).max(1);
    if kind == LumaKind::Bayer && f % 2 == 1 {
        f += 1;
    }
    let (pw, ph) = ((w / f).max(1), (h / f).max(1));
    let channels = if kind == LumaKind::Mono { 1 } else { 3 };
    let bpp = frame.format().bytes_per_pixel();
    let is16 = frame.format().is_16bit();
    let data = frame.data();
    let stride = frame.stride();
    let sample = |off: usize| -> u32 {
        if is16 {
            (u16::from_le_bytes([data[off], data[off + 1]]) >> 8) as u32
        } else {
            data[off] as u32
        }
    };
    acc.clear();
    acc.resize(pw * 3, 0);
    let pixels = &mut out.pixels;
    pixels.clear();
    pixels.reserve(pw * ph * channels);
    let chan = bayer_channels(frame.format());
    // Samples per channel in a block.
    let per = match kind {
        LumaKind::Bayer => [(f * f / 4) as u32, (f * f / 2) as u32, (f * f / 4) as u32],
        _ => [(f * f) as u32; 3],
    };
    for oy in 0..ph {
        acc.iter_mut().for_each(|a| *a = 0);
        for y in oy * f..(oy + 1) * f {
            let row = y * stride;
            match kind {
                LumaKind::Mono => {
                    for (ox, a) in acc.iter_mut().take(pw).enumerate() {
                        for x in ox * f..(ox + 1) * f {
                            *a += sample(row + x * bpp);
                        }
                    }
                }
                LumaKind::Rgb => {
                    for ox in 0..pw {
                        for x in ox * f..(ox + 1) * f {
                            let o = row + x * 3;
                            acc[ox * 3] += sample(o);
                            acc[ox * 3 + 1] += sample(o + 1);
                            acc[ox * 3 + 2] += sample(o + 2);
                        }
                    }
                }
                LumaKind::Bayer => {
                    let cy = chan[y % 2];
                    for ox in 0..pw {
                        for x in ox * f..(ox + 1) * f {
                            acc[ox * 3 + cy[x % 2]] += sample(row + x * bpp);
                        }
                    }
                }
            }
        }
        for ox in 0..pw {
            if channels == 1 {
                pixels.push((acc[ox] / per[0]) as u8);
            } else {
                for c in 0..3 {
                    pixels.push((acc[ox * 3 + c] / per[c]).min(255) as u8);
                }
            }
        }
    }
    out.width = pw;
    out.height = ph;
    out.channels = channels;
    out.factor = f;
}
