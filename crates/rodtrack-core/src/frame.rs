//! Borrowed frame views with explicit stride and pixel format.
//!
//! A [`FrameView`] is validated once when it is made; after that, the samplers read luminance
//! straight from the raw bytes. Coordinates follow OpenCV: pixel `(i, j)` has its centre at
//! `(i, j)`.
//!
//! Luminance is defined per format so that no full-frame demosaic is ever needed:
//! - mono: the pixel value;
//! - RGB: `(r + 2g + b) / 4`;
//! - Bayer (any of the four layouts): every 2x2 block holds one red, two green and one blue
//!   pixel, so the block mean is `(r + 2g + b) / 4` whatever the layout. The luminance at
//!   `(x, y)` is the mean of the 2x2 block centred there; on the pixel grid this is the block
//!   whose top-left pixel is `(floor(x - 0.5), floor(y - 0.5))`.
//!
//! All luminance values are returned on the 8-bit scale (0..255), also for 16-bit formats, so that
//! thresholds mean the same thing for every camera.

use crate::CoreError;
use serde::{Deserialize, Serialize};

/// Pixel layout of a raw frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PixelFormat {
    /// 8-bit grey.
    Mono8,
    /// 16-bit grey, little endian.
    Mono16,
    /// 8-bit Bayer, first row R G R G ...
    BayerRggb8,
    /// 8-bit Bayer, first row B G B G ...
    BayerBggr8,
    /// 8-bit Bayer, first row G R G R ...
    BayerGrbg8,
    /// 8-bit Bayer, first row G B G B ...
    BayerGbrg8,
    /// 16-bit Bayer RGGB, little endian.
    BayerRggb16,
    /// 16-bit Bayer BGGR, little endian.
    BayerBggr16,
    /// 16-bit Bayer GRBG, little endian.
    BayerGrbg16,
    /// 16-bit Bayer GBRG, little endian.
    BayerGbrg16,
    /// 8-bit interleaved R, G, B.
    Rgb8,
}

/// How luminance is formed from a format's samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LumaKind {
    /// One sample per pixel.
    Mono,
    /// Three interleaved samples per pixel.
    Rgb,
    /// A colour mosaic: luminance is the mean of a 2x2 block.
    Bayer,
}

impl PixelFormat {
    /// Every format, for tests and help texts.
    pub const ALL: [PixelFormat; 11] = [
        PixelFormat::Mono8,
        PixelFormat::Mono16,
        PixelFormat::BayerRggb8,
        PixelFormat::BayerBggr8,
        PixelFormat::BayerGrbg8,
        PixelFormat::BayerGbrg8,
        PixelFormat::BayerRggb16,
        PixelFormat::BayerBggr16,
        PixelFormat::BayerGrbg16,
        PixelFormat::BayerGbrg16,
        PixelFormat::Rgb8,
    ];

    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            PixelFormat::Mono8
            | PixelFormat::BayerRggb8
            | PixelFormat::BayerBggr8
            | PixelFormat::BayerGrbg8
            | PixelFormat::BayerGbrg8 => 1,
            PixelFormat::Mono16
            | PixelFormat::BayerRggb16
            | PixelFormat::BayerBggr16
            | PixelFormat::BayerGrbg16
            | PixelFormat::BayerGbrg16 => 2,
            PixelFormat::Rgb8 => 3,
        }
    }

    /// True for 16-bit formats.
    pub fn is_16bit(self) -> bool {
        self.bytes_per_pixel() == 2
    }

    /// How luminance is formed.
    pub fn luma_kind(self) -> LumaKind {
        match self {
            PixelFormat::Mono8 | PixelFormat::Mono16 => LumaKind::Mono,
            PixelFormat::Rgb8 => LumaKind::Rgb,
            _ => LumaKind::Bayer,
        }
    }

    /// The name used in files and on the command line (`bayer_rggb8`, ...).
    pub fn name(self) -> &'static str {
        match self {
            PixelFormat::Mono8 => "mono8",
            PixelFormat::Mono16 => "mono16",
            PixelFormat::BayerRggb8 => "bayer_rggb8",
            PixelFormat::BayerBggr8 => "bayer_bggr8",
            PixelFormat::BayerGrbg8 => "bayer_grbg8",
            PixelFormat::BayerGbrg8 => "bayer_gbrg8",
            PixelFormat::BayerRggb16 => "bayer_rggb16",
            PixelFormat::BayerBggr16 => "bayer_bggr16",
            PixelFormat::BayerGrbg16 => "bayer_grbg16",
            PixelFormat::BayerGbrg16 => "bayer_gbrg16",
            PixelFormat::Rgb8 => "rgb8",
        }
    }

    /// Parses a name as written by [`PixelFormat::name`]; GenICam spellings (`BayerRG8`,
    /// `Mono8`, `RGB8`) are accepted too.
    pub fn from_name(name: &str) -> Option<PixelFormat> {
        let lower = name.to_ascii_lowercase();
        let alias = match lower.as_str() {
            "bayerrg8" => "bayer_rggb8",
            "bayerbg8" => "bayer_bggr8",
            "bayergr8" => "bayer_grbg8",
            "bayergb8" => "bayer_gbrg8",
            "bayerrg16" => "bayer_rggb16",
            "bayerbg16" => "bayer_bggr16",
            "bayergr16" => "bayer_grbg16",
            "bayergb16" => "bayer_gbrg16",
            other => other,
        };
        PixelFormat::ALL.into_iter().find(|f| f.name() == alias)
    }
}

impl std::fmt::Display for PixelFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A borrowed, validated view of one raw frame.
#[derive(Debug, Clone, Copy)]
pub struct FrameView<'a> {
    data: &'a [u8],
    width: usize,
    height: usize,
    stride: usize,
    format: PixelFormat,
}

impl<'a> FrameView<'a> {
    /// Makes a view; `stride` is the distance between rows in bytes (at least
    /// `width * bytes_per_pixel`). The last row may end right after its pixels.
    pub fn new(
        data: &'a [u8],
        width: usize,
        height: usize,
        stride: usize,
        format: PixelFormat,
    ) -> Result<Self, CoreError> {
        if width < 2 || height < 2 {
            return Err(CoreError::FrameSize {
                what: "width and height must be at least 2 px",
                expected: 2,
                got: width.min(height),
            });
        }
        let row_bytes = width * format.bytes_per_pixel();
        if stride < row_bytes {
            return Err(CoreError::FrameSize {
                what: "stride (bytes) shorter than one row",
                expected: row_bytes,
                got: stride,
            });
        }
        let needed = stride * (height - 1) + row_bytes;
        if data.len() < needed {
            return Err(CoreError::FrameSize {
                what: "frame buffer (bytes) too short",
                expected: needed,
                got: data.len(),
            });
        }
        Ok(FrameView {
            data,
            width,
            height,
            stride,
            format,
        })
    }

    /// A tightly packed view (`stride = width * bytes_per_pixel`).
    pub fn packed(
        data: &'a [u8],
        width: usize,
        height: usize,
        format: PixelFormat,
    ) -> Result<Self, CoreError> {
        Self::new(
            data,
            width,
            height,
            width * format.bytes_per_pixel(),
            format,
        )
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Row stride in bytes.
    pub fn stride(&self) -> usize {
        self.stride
    }
    /// Pixel format.
    pub fn format(&self) -> PixelFormat {
        self.format
    }
    /// The raw bytes.
    pub fn data(&self) -> &'a [u8] {
        self.data
    }

    /// Raw sample at byte offset `off` on the 8-bit scale.
    #[inline(always)]
    fn raw(&self, off: usize) -> f32 {
        if self.format.is_16bit() {
            let v = u16::from_le_bytes([self.data[off], self.data[off + 1]]);
            v as f32 * (1.0 / 257.0)
        } else {
            self.data[off] as f32
        }
    }

    /// Luminance of the luma grid node `(i, j)`, on the 8-bit scale. For mono and RGB frames the
    /// node is pixel `(i, j)`; for Bayer frames it is the 2x2 block with top-left pixel `(i, j)`,
    /// centred at `(i + 0.5, j + 0.5)`. Out-of-range nodes are clamped to the frame.
    #[inline]
    pub fn luma_node(&self, i: isize, j: isize) -> f32 {
        let kind = self.format.luma_kind();
        let (maxi, maxj) = match kind {
            LumaKind::Bayer => (self.width as isize - 2, self.height as isize - 2),
            _ => (self.width as isize - 1, self.height as isize - 1),
        };
        let i = i.clamp(0, maxi) as usize;
        let j = j.clamp(0, maxj) as usize;
        let bpp = self.format.bytes_per_pixel();
        let off = j * self.stride + i * bpp;
        match kind {
            LumaKind::Mono => self.raw(off),
            LumaKind::Rgb => (self.raw(off) + 2.0 * self.raw(off + 1) + self.raw(off + 2)) * 0.25,
            LumaKind::Bayer => {
                let below = off + self.stride;
                (self.raw(off) + self.raw(off + bpp) + self.raw(below) + self.raw(below + bpp))
                    * 0.25
            }
        }
    }

    /// [`FrameView::luma_node`] for many nodes at once (the format is dispatched once); `None`
    /// reads as 0.
    pub fn luma_nodes(&self, nodes: &[Option<(isize, isize)>], out: &mut [f32]) {
        let (w, h) = (self.width as isize, self.height as isize);
        match (self.format.luma_kind(), self.format.is_16bit()) {
            (LumaKind::Bayer, false) => {
                for (v, n) in out.iter_mut().zip(nodes) {
                    *v = match *n {
                        Some((i, j)) if i >= 0 && j >= 0 && i < w - 1 && j < h - 1 => {
                            let o = j as usize * self.stride + i as usize;
                            let (r0, r1) = (&self.data[o..o + 2], &self.data[o + self.stride..]);
                            (r0[0] as u32 + r0[1] as u32 + r1[0] as u32 + r1[1] as u32) as f32
                                * 0.25
                        }
                        Some((i, j)) => self.luma_node(i, j),
                        None => 0.0,
                    };
                }
            }
            (LumaKind::Mono, false) => {
                for (v, n) in out.iter_mut().zip(nodes) {
                    *v = match *n {
                        Some((i, j)) if i >= 0 && j >= 0 && i < w && j < h => {
                            self.data[j as usize * self.stride + i as usize] as f32
                        }
                        Some((i, j)) => self.luma_node(i, j),
                        None => 0.0,
                    };
                }
            }
            _ => {
                for (v, n) in out.iter_mut().zip(nodes) {
                    *v = n.map_or(0.0, |(i, j)| self.luma_node(i, j));
                }
            }
        }
    }

    /// Offset of luma grid node coordinates from pixel coordinates: 0.5 for Bayer (a node is a
    /// 2x2 block), 0 otherwise.
    pub fn node_offset(&self) -> f32 {
        match self.format.luma_kind() {
            LumaKind::Bayer => 0.5,
            _ => 0.0,
        }
    }

    /// Luminance at the nearest luma node to pixel position `(x, y)` (no interpolation).
    pub fn luma_nearest(&self, x: f32, y: f32) -> f32 {
        let o = self.node_offset();
        self.luma_node((x - o).round() as isize, (y - o).round() as isize)
    }

    /// Bilinear luminance at pixel position `(x, y)`: the plain reference written with
    /// [`FrameView::luma_node`]; [`FrameView::luma_bilinear`] must equal it.
    pub fn luma_bilinear_reference(&self, x: f32, y: f32) -> f32 {
        let o = self.node_offset();
        let gx = x - o;
        let gy = y - o;
        let i0 = gx.floor();
        let j0 = gy.floor();
        let fx = gx - i0;
        let fy = gy - j0;
        let (i0, j0) = (i0 as isize, j0 as isize);
        let a = self.luma_node(i0, j0);
        let b = self.luma_node(i0 + 1, j0);
        let c = self.luma_node(i0, j0 + 1);
        let d = self.luma_node(i0 + 1, j0 + 1);
        (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy
    }

    /// Bilinear luminance at pixel position `(x, y)` (the samplers' hot path). Away from the
    /// border, an 8-bit frame is read directly: for Bayer, the bilinear mix of 2x2-block means is
    /// a separable 3x3 of pixels with weights `((1-f)/2, 1/2, f/2)`, 9 reads instead of 16.
    /// Near the border, and for other formats, it falls back to the reference.
    #[inline(always)]
    pub fn luma_bilinear(&self, x: f32, y: f32) -> f32 {
        if !self.format.is_16bit() && x >= 2.0 && y >= 2.0 {
            let (w, h) = (self.width as f32, self.height as f32);
            if x < w - 3.0 && y < h - 3.0 {
                match self.format.luma_kind() {
                    LumaKind::Bayer => {
                        let gx = x - 0.5;
                        let gy = y - 0.5;
                        // Positive and inside the frame here, so truncation to i32 is floor
                        // (one instruction each way, and no libm call).
                        let (i0, j0) = (gx as i32, gy as i32);
                        let fx = gx - i0 as f32;
                        let fy = gy - j0 as f32;
                        let s = self.stride;
                        let base = j0 as usize * s + i0 as usize;
                        // The 3x3 window as one slice: one bounds check for its nine reads.
                        let win = &self.data[base..base + 2 * s + 3];
                        // Each row: (1-fx)/2 a + b/2 + fx/2 c = (a + b + fx (c - a)) / 2; the
                        // rows likewise with fy, hence the 1/4:
                        // (r0 + r1 + fy (r2 - r0)) / 4. The sums and differences of pixels
                        // are exact in integers: four conversions to float instead of nine.
                        let row = |r: &[u8]| {
                            let (a, b, c) = (r[0] as i32, r[1] as i32, r[2] as i32);
                            (a + b, c - a)
                        };
                        let (s0, d0) = row(&win[..3]);
                        let (s1, d1) = row(&win[s..s + 3]);
                        let (s2, d2) = row(&win[2 * s..]);
                        let near = (s0 + s1) as f32 + fx * (d0 + d1) as f32;
                        let far = (s2 - s0) as f32 + fx * (d2 - d0) as f32;
                        return 0.25 * (near + fy * far);
                    }
                    LumaKind::Mono => {
                        let (i0, j0) = (x as i32, y as i32);
                        let fx = x - i0 as f32;
                        let fy = y - j0 as f32;
                        let s = self.stride;
                        let base = j0 as usize * s + i0 as usize;
                        let win = &self.data[base..base + s + 2];
                        let (r0, r1) = (&win[..2], &win[s..]);
                        let top = r0[0] as f32 + fx * (r0[1] as f32 - r0[0] as f32);
                        let bot = r1[0] as f32 + fx * (r1[1] as f32 - r1[0] as f32);
                        return top + fy * (bot - top);
                    }
                    LumaKind::Rgb => {}
                }
            }
        }
        self.luma_bilinear_slow(x, y)
    }

    #[inline(never)]
    fn luma_bilinear_slow(&self, x: f32, y: f32) -> f32 {
        self.luma_bilinear_reference(x, y)
    }

    /// Asks for every cache line of the pixel rectangle `[x0, x1] x [y0, y1]` (clamped to the
    /// frame), so that the samplers later find it in cache. A new frame comes from memory, not
    /// from the cache: asking for every rod's lines first lets those reads overlap with each
    /// other and with the measuring, instead of each sample waiting for its own. On x86-64 a
    /// prefetch instruction per line (it does not hold the thread up), elsewhere a read.
    /// Returns the rectangle's first byte (0 when it is empty).
    pub fn touch_rect(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> u8 {
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            return 0;
        }
        let clamp = |v: f64, max: usize| v.clamp(0.0, max as f64) as usize;
        let (x0, x1) = (clamp(x0, self.width - 1), clamp(x1, self.width - 1));
        let (y0, y1) = (clamp(y0, self.height - 1), clamp(y1, self.height - 1));
        if x1 < x0 || y1 < y0 {
            return 0;
        }
        let bpp = self.format.bytes_per_pixel();
        for y in y0..=y1 {
            let row = y * self.stride;
            let (a, b) = (row + x0 * bpp, row + x1 * bpp + bpp - 1);
            for off in (a..=b).step_by(64) {
                prefetch_line(&self.data[off]);
            }
            prefetch_line(&self.data[b]);
        }
        self.data[y0 * self.stride + x0 * bpp]
    }

    /// True when the point lies inside the frame with `margin` pixels to spare.
    pub fn contains(&self, x: f32, y: f32, margin: f32) -> bool {
        x >= margin
            && y >= margin
            && x <= self.width as f32 - 1.0 - margin
            && y <= self.height as f32 - 1.0 - margin
    }
}

/// Asks the processor to bring the cache line holding `byte` into the cache, without waiting
/// for it: the thread goes on while the line comes (a load would hold the thread's later work
/// back behind the miss once enough misses are outstanding).
#[inline(always)]
fn prefetch_line(byte: &u8) {
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    // SAFETY: a prefetch has no architectural effect and never faults; the pointer comes from a
    // reference, so it is valid anyway.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
            byte as *const u8 as *const i8,
        );
    }
    #[cfg(not(target_arch = "x86_64"))]
    std::hint::black_box(*byte);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_short_buffers_and_strides() {
        let data = vec![0u8; 100];
        assert!(matches!(
            FrameView::new(&data, 10, 10, 9, PixelFormat::Mono8),
            Err(CoreError::FrameSize { .. })
        ));
        assert!(FrameView::new(&data, 10, 10, 10, PixelFormat::Mono8).is_ok());
        assert!(FrameView::new(&data, 10, 11, 10, PixelFormat::Mono8).is_err());
        // Padded stride: last row needs only its pixels.
        assert!(FrameView::new(&data, 8, 10, 10, PixelFormat::Mono8).is_ok());
        assert!(FrameView::new(&data, 5, 10, 10, PixelFormat::Mono16).is_ok());
        assert!(FrameView::new(&data, 6, 10, 10, PixelFormat::Mono16).is_err());
    }

    #[test]
    fn bayer_luma_is_layout_independent_block_mean() {
        // A flat colour: R=200, G=100, B=40 in each layout gives (200 + 200 + 40) / 4 = 110.
        for (fmt, pattern) in [
            (PixelFormat::BayerRggb8, [200u8, 100, 100, 40]),
            (PixelFormat::BayerBggr8, [40, 100, 100, 200]),
            (PixelFormat::BayerGrbg8, [100, 200, 40, 100]),
            (PixelFormat::BayerGbrg8, [100, 40, 200, 100]),
        ] {
            let (w, h) = (8, 6);
            let mut data = vec![0u8; w * h];
            for y in 0..h {
                for x in 0..w {
                    data[y * w + x] = pattern[(y % 2) * 2 + (x % 2)];
                }
            }
            let f = FrameView::packed(&data, w, h, fmt).unwrap();
            for (x, y) in [(1.0, 1.0), (3.3, 2.7), (0.0, 0.0), (7.0, 5.0)] {
                assert!((f.luma_bilinear(x, y) - 110.0).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn mono16_is_on_8bit_scale_and_stride_is_honoured() {
        let (w, h, stride) = (4, 3, 12);
        let mut data = vec![0xAAu8; stride * h];
        for y in 0..h {
            for x in 0..w {
                let v = ((x + 10 * y) as u16) * 257;
                data[y * stride + 2 * x..y * stride + 2 * x + 2].copy_from_slice(&v.to_le_bytes());
            }
        }
        let f = FrameView::new(&data, w, h, stride, PixelFormat::Mono16).unwrap();
        assert!((f.luma_node(3, 2) - 23.0).abs() < 1e-4);
        assert!((f.luma_bilinear(1.5, 0.5) - 6.5).abs() < 1e-4);
    }

    proptest::proptest! {
        /// The fast bilinear equals the plain reference, for every format, inside and near the
        /// border, with a padded stride.
        #[test]
        fn fast_bilinear_equals_reference(x in -2.0f32..40.0, y in -2.0f32..30.0, seed in 0u64..1000) {
            let (w, h, pad) = (37usize, 27usize, 5usize);
            for fmt in PixelFormat::ALL {
                let stride = w * fmt.bytes_per_pixel() + pad;
                let mut st = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
                let data: Vec<u8> = (0..stride * h)
                    .map(|_| {
                        st ^= st << 13;
                        st ^= st >> 7;
                        st ^= st << 17;
                        (st >> 24) as u8
                    })
                    .collect();
                let f = FrameView::new(&data, w, h, stride, fmt).unwrap();
                let a = f.luma_bilinear(x, y);
                let b = f.luma_bilinear_reference(x, y);
                proptest::prop_assert!((a - b).abs() < 1e-3, "{fmt}: {a} vs {b} at ({x}, {y})");
            }
        }
    }

    proptest::proptest! {
        /// The batch node reader equals the plain node reader, for every format, nodes inside,
        /// on and beyond the border (clamped), and `None`.
        #[test]
        fn luma_nodes_equal_luma_node(
            nodes in proptest::collection::vec(
                proptest::option::of((-3isize..42, -3isize..32)), 1..40),
            seed in 0u64..1000,
        ) {
            let (w, h, pad) = (37usize, 27usize, 3usize);
            for fmt in PixelFormat::ALL {
                let stride = w * fmt.bytes_per_pixel() + pad;
                let data: Vec<u8> = (0..stride * h)
                    .map(|i| (seed as usize * 7919 + i * 2654435761) as u8)
                    .collect();
                let f = FrameView::new(&data, w, h, stride, fmt).unwrap();
                let mut out = vec![f32::NAN; nodes.len()];
                f.luma_nodes(&nodes, &mut out);
                for (n, v) in nodes.iter().zip(&out) {
                    let want = n.map_or(0.0, |(i, j)| f.luma_node(i, j));
                    proptest::prop_assert!((v - want).abs() < 1e-4, "{fmt}: {v} vs {want} at {n:?}");
                }
            }
        }

        /// Touching a rectangle never reads outside the frame, whatever the rectangle.
        #[test]
        fn touch_rect_stays_inside(
            x0 in -1e4f64..1e4, y0 in -1e4f64..1e4, x1 in -1e4f64..1e4, y1 in -1e4f64..1e4,
        ) {
            let (w, h) = (37usize, 27usize);
            for fmt in PixelFormat::ALL {
                let stride = w * fmt.bytes_per_pixel();
                let data = vec![1u8; stride * h];
                let f = FrameView::new(&data, w, h, stride, fmt).unwrap();
                let _ = f.touch_rect(x0, y0, x1, y1);
                let _ = f.touch_rect(f64::NAN, y0, f64::INFINITY, y1);
            }
        }
    }

    #[test]
    fn format_names_round_trip() {
        for f in PixelFormat::ALL {
            assert_eq!(PixelFormat::from_name(f.name()), Some(f));
        }
        assert_eq!(
            PixelFormat::from_name("BayerRG8"),
            Some(PixelFormat::BayerRggb8)
        );
        assert_eq!(PixelFormat::from_name("yuv"), None);
    }
}
