//! Preview frames: a camera node's downscaled image of its latest frame, a few per second, for
//! remote consoles (`rodtrack/<table>/cam/<camera>/preview`). No zenoh in this module.
//!
//! Binary layout, version 1, little endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `RTZP` (bytes `52 54 5A 50`) |
//! | 4 | 2 | version, u16 = 1 |
//! | 6 | 1 | pixel format: 0 mono8 (1 byte per pixel), 1 RGB8 (3 bytes per pixel, R G B) |
//! | 7 | 1 | reserved, 0 |
//! | 8 | 4 | camera index, u32 (the camera's in the calibration) |
//! | 12 | 4 | sequence number, u32 (per camera node, +1 per preview, wraps) |
//! | 16 | 8 | frame id, u64 |
//! | 24 | 8 | capture timestamp, u64 ns |
//! | 32 | 4 | width `w`, px, u32 |
//! | 36 | 4 | height `h`, px, u32 |
//! | 40 | 4 | the camera frame's width, px, u32 |
//! | 44 | 4 | the camera frame's height, px, u32 |
//! | 48 | `w` x `h` x bytes per pixel | pixels, row-major, packed (no row padding) |

use crate::ZenohError;
use rodtrack_core::preview::Preview;
use rodtrack_core::Timestamp;

/// Preview message magic.
pub const PREVIEW_MAGIC: [u8; 4] = *b"RTZP";
/// Preview layout version.
pub const PREVIEW_VERSION: u16 = 1;
/// Preview header size, bytes.
pub const PREVIEW_HEADER_BYTES: usize = 48;
/// Widest or tallest preview a decoder accepts, px.
pub const PREVIEW_MAX_SIDE_PX: u32 = 4096;
/// Widest preview a camera node sends, px (a 1440x1080 Bayer camera: 360x270 RGB).
pub const PREVIEW_MAX_WIDTH_PX: usize = 360;
/// Preview frames per second of a camera node by default (`--preview-fps`).
pub const DEFAULT_PREVIEW_FPS: f64 = 2.0;

/// A preview's pixel format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PreviewFormat {
    /// 8-bit grey, 1 byte per pixel.
    Mono8,
    /// 8-bit R, G, B, 3 bytes per pixel.
    Rgb8,
}

impl PreviewFormat {
    /// Bytes per pixel.
    pub fn channels(self) -> usize {
        match self {
            PreviewFormat::Mono8 => 1,
            PreviewFormat::Rgb8 => 3,
        }
    }
    fn code(self) -> u8 {
        match self {
            PreviewFormat::Mono8 => 0,
            PreviewFormat::Rgb8 => 1,
        }
    }
    fn from_code(c: u8) -> Option<PreviewFormat> {
        match c {
            0 => Some(PreviewFormat::Mono8),
            1 => Some(PreviewFormat::Rgb8),
            _ => None,
        }
    }
    /// The format of a preview of `channels` channels (1 or 3).
    pub fn from_channels(channels: usize) -> Option<PreviewFormat> {
        match channels {
            1 => Some(PreviewFormat::Mono8),
            3 => Some(PreviewFormat::Rgb8),
            _ => None,
        }
    }
}

/// A preview message's header fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PreviewHeader {
    /// The camera's index in the calibration.
    pub camera: u32,
    /// Sequence number.
    pub seq: u32,
    /// The frame's id.
    pub frame: u64,
    /// The frame's capture timestamp.
    pub timestamp_ns: Timestamp,
    /// Pixel format.
    pub format: PreviewFormat,
    /// Preview width, px.
    pub width_px: u32,
    /// Preview height, px.
    pub height_px: u32,
    /// The camera frame's width, px.
    pub source_width_px: u32,
    /// The camera frame's height, px.
    pub source_height_px: u32,
}

/// A decoded preview message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PreviewMessage {
    /// The header.
    pub header: PreviewHeader,
    /// `width x height x channels` bytes, row-major.
    pub pixels: Vec<u8>,
}

/// The header of a preview `p` of a frame.
pub fn header_of(
    p: &Preview,
    camera: u32,
    frame: u64,
    timestamp_ns: Timestamp,
    source_px: (usize, usize),
) -> Result<PreviewHeader, ZenohError> {
    let px = |v: usize, what: &str| {
        u32::try_from(v).map_err(|_| ZenohError::Message(format!("preview {what} {v} px")))
    };
    Ok(PreviewHeader {
        camera,
        seq: 0,
        frame,
        timestamp_ns,
        format: PreviewFormat::from_channels(p.channels)
            .ok_or_else(|| ZenohError::Message(format!("a preview of {} channels", p.channels)))?,
        width_px: px(p.width, "width")?,
        height_px: px(p.height, "height")?,
        source_width_px: px(source_px.0, "source width")?,
        source_height_px: px(source_px.1, "source height")?,
    })
}

fn pixel_bytes(h: &PreviewHeader) -> Option<usize> {
    (h.width_px as usize)
        .checked_mul(h.height_px as usize)?
        .checked_mul(h.format.channels())
}

/// Encodes a preview into `out` (cleared first; no allocation once `out` has held one).
/// Fails when `pixels` is not `width x height x channels` bytes or a side is 0 or over
/// [`PREVIEW_MAX_SIDE_PX`].
pub fn encode_preview(
    h: &PreviewHeader,
    pixels: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), ZenohError> {
    check_size(h, pixels.len())?;
    out.clear();
    out.extend_from_slice(&PREVIEW_MAGIC);
    out.extend_from_slice(&PREVIEW_VERSION.to_le_bytes());
    out.push(h.format.code());
    out.push(0);
    out.extend_from_slice(&h.camera.to_le_bytes());
    out.extend_from_slice(&h.seq.to_le_bytes());
    out.extend_from_slice(&h.frame.to_le_bytes());
    out.extend_from_slice(&h.timestamp_ns.as_nanos().to_le_bytes());
    for v in [
        h.width_px,
        h.height_px,
        h.source_width_px,
        h.source_height_px,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(pixels);
    Ok(())
}

fn check_size(h: &PreviewHeader, got: usize) -> Result<(), ZenohError> {
    let bad = |s: String| Err(ZenohError::Message(s));
    let sides = [h.width_px, h.height_px];
    if sides.iter().any(|&s| s == 0 || s > PREVIEW_MAX_SIDE_PX) {
        return bad(format!(
            "preview of {}x{} px: each side must be 1 to {PREVIEW_MAX_SIDE_PX}",
            h.width_px, h.height_px
        ));
    }
    match pixel_bytes(h) {
        Some(n) if n == got => Ok(()),
        n => bad(format!(
            "a {}x{} {:?} preview needs {} pixel bytes, got {got}",
            h.width_px,
            h.height_px,
            h.format,
            n.unwrap_or(usize::MAX)
        )),
    }
}

fn le<const N: usize>(b: &[u8], at: usize) -> [u8; N] {
    let mut a = [0u8; N];
    a.copy_from_slice(&b[at..at + N]);
    a
}

/// Decodes a preview message ([`encode_preview`]).
pub fn decode_preview(b: &[u8]) -> Result<PreviewMessage, ZenohError> {
    let bad = |s: String| Err(ZenohError::Message(s));
    if b.len() < PREVIEW_HEADER_BYTES {
        return bad(format!(
            "preview of {} bytes, shorter than the {PREVIEW_HEADER_BYTES}-byte header",
            b.len()
        ));
    }
    if b[0..4] != PREVIEW_MAGIC {
        return bad("bad preview magic (expected RTZP)".into());
    }
    let version = u16::from_le_bytes(le(b, 4));
    if version != PREVIEW_VERSION {
        return bad(format!(
            "preview version {version}, this decoder reads {PREVIEW_VERSION}"
        ));
    }
    let Some(format) = PreviewFormat::from_code(b[6]) else {
        return bad(format!("unknown preview pixel format {}", b[6]));
    };
    let u32_at = |at: usize| u32::from_le_bytes(le(b, at));
    let header = PreviewHeader {
        camera: u32_at(8),
        seq: u32_at(12),
        frame: u64::from_le_bytes(le(b, 16)),
        timestamp_ns: Timestamp(u64::from_le_bytes(le(b, 24))),
        format,
        width_px: u32_at(32),
        height_px: u32_at(36),
        source_width_px: u32_at(40),
        source_height_px: u32_at(44),
    };
    let pixels = &b[PREVIEW_HEADER_BYTES..];
    check_size(&header, pixels.len())?;
    Ok(PreviewMessage {
        header,
        pixels: pixels.to_vec(),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use rodtrack_core::{FrameView, PixelFormat};

    fn message() -> (PreviewHeader, Vec<u8>) {
        // A 8x4 RGGB frame whose 2x2 blocks are (r, g, b) = (x, 100, 200): a 4x2 preview.
        let (w, h) = (8usize, 4usize);
        let mut data = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                data[y * w + x] = match (y % 2, x % 2) {
                    (0, 0) => (x / 2 * 10) as u8,
                    (1, 1) => 200,
                    _ => 100,
                };
            }
        }
        let f = FrameView::new(&data, w, h, w, PixelFormat::BayerRggb8).unwrap();
        let mut p = Preview::default();
        rodtrack_core::preview::preview_into(&f, 4, &mut p, &mut Vec::new());
        let mut header = header_of(&p, 3, 77, Timestamp(1_234_567_890), (w, h)).unwrap();
        header.seq = 5;
        (header, p.pixels)
    }

    #[test]
    fn preview_round_trips_every_field_and_pixel() {
        let (h, pixels) = message();
        assert_eq!(
            (h.width_px, h.height_px, h.format),
            (4, 2, PreviewFormat::Rgb8)
        );
        assert_eq!(&pixels[..6], &[0, 100, 200, 10, 100, 200]);
        let mut out = Vec::new();
        encode_preview(&h, &pixels, &mut out).unwrap();
        assert_eq!(out.len(), PREVIEW_HEADER_BYTES + 4 * 2 * 3);
        assert_eq!(&out[..4], b"RTZP");
        let m = decode_preview(&out).unwrap();
        assert_eq!(m.header, h);
        assert_eq!(m.pixels, pixels);
        assert_eq!(
            (m.header.source_width_px, m.header.source_height_px),
            (8, 4)
        );
    }

    #[test]
    fn truncated_or_foreign_previews_are_refused_by_reason() {
        let (h, pixels) = message();
        let mut out = Vec::new();
        encode_preview(&h, &pixels, &mut out).unwrap();
        let msg = |b: &[u8]| decode_preview(b).unwrap_err().to_string();
        assert!(msg(&out[..20]).contains("shorter than the 48-byte header"));
        let e = msg(&out[..out.len() - 1]);
        assert!(e.contains("needs 24 pixel bytes, got 23"), "{e}");
        let mut v = out.clone();
        v[4] = 2;
        let e = msg(&v);
        assert!(
            e.contains("preview version 2") && e.contains("reads 1"),
            "{e}"
        );
        let mut v = out.clone();
        v[0] = b'X';
        assert!(msg(&v).contains("magic"));
        let mut v = out.clone();
        v[6] = 9;
        assert!(msg(&v).contains("pixel format 9"));
        let mut v = out.clone();
        v[32..36].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(msg(&v).contains("each side"));
        assert!(encode_preview(&h, &pixels[1..], &mut out)
            .unwrap_err()
            .to_string()
            .contains("got 23"));
    }
}
