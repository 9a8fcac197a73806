//! Owned frame copies and the cheap preview "demosaic for the eye".

use rodtrack_core::{CoreError, FrameView, LumaKind, PixelFormat};

/// The downscale lives in `rodtrack_core::preview` (the camera nodes use it too).
pub use rodtrack_core::preview::{preview, Preview};

/// An owned, tightly packed copy of a frame (the console's frozen and latest frames).
#[derive(Debug, Clone)]
pub struct OwnedFrame {
    data: Vec<u8>,
    stride: usize,
    width: usize,
    height: usize,
    format: PixelFormat,
    frame_id: u64,
    timestamp_s: f64,
}

impl Default for OwnedFrame {
    fn default() -> Self {
        OwnedFrame {
            data: Vec::new(),
            stride: 0,
            width: 0,
            height: 0,
            format: PixelFormat::Mono8,
            frame_id: 0,
            timestamp_s: 0.0,
        }
    }
}

impl OwnedFrame {
    /// Copies a view (rows packed, stride dropped).
    pub fn from_view(frame: &FrameView, frame_id: u64, timestamp_s: f64) -> OwnedFrame {
        let mut f = OwnedFrame::default();
        f.copy_from(frame, frame_id, timestamp_s);
        f
    }

    /// Copies a view into this buffer, reusing its allocation when it is large enough.
    pub fn copy_from(&mut self, frame: &FrameView, frame_id: u64, timestamp_s: f64) {
        let row = frame.width() * frame.format().bytes_per_pixel();
        let stride = frame.stride();
        let src = frame.data();
        self.data.clear();
        if stride == row {
            self.data.extend_from_slice(&src[..row * frame.height()]);
        } else {
            for chunk in src.chunks(stride).take(frame.height()) {
                self.data.extend_from_slice(&chunk[..row]);
            }
        }
        self.stride = row;
        self.width = frame.width();
        self.height = frame.height();
        self.format = frame.format();
        self.frame_id = frame_id;
        self.timestamp_s = timestamp_s;
    }

    /// Copies every `d`-th pixel of every `d`-th row of a view (for Bayer formats, every `d`-th
    /// 2x2 block of every `d`-th row of blocks, so that the copy is a Bayer frame of the same
    /// pattern): the live view's cheap copy, `d x d` times less data than [`OwnedFrame::copy_from`]
    /// and about that much less memory traffic (the skipped rows are never read). Kept pixel
    /// `(x, y)` of the copy is pixel `(x * d, y * d)` of the frame (blocks: block `(i, j)` is
    /// block `(i * d, j * d)`); `d <= 1` copies everything. Reuses the allocation.
    pub fn copy_decimated(&mut self, frame: &FrameView, d: usize, frame_id: u64, timestamp_s: f64) {
        if d <= 1 {
            self.copy_from(frame, frame_id, timestamp_s);
            return;
        }
        let format = frame.format();
        let bpp = format.bytes_per_pixel();
        // Pixels kept together along each axis.
        let unit = if format.luma_kind() == LumaKind::Bayer {
            2
        } else {
            1
        };
        let (w, h) = (frame.width(), frame.height());
        let out_w = (w / unit).div_ceil(d) * unit;
        let out_h = (h / unit).div_ceil(d) * unit;
        let (row_in, row_out) = (w * bpp, out_w * bpp);
        let (stride, src) = (frame.stride(), frame.data());
        // Every byte is overwritten: no clearing.
        self.data.resize(row_out * out_h, 0);
        let step = d * unit * bpp;
        for (oy, out) in self.data.chunks_exact_mut(row_out.max(1)).enumerate() {
            let y = (oy / unit) * d * unit + oy % unit;
            let Some(row) = src.get(y * stride..y * stride + row_in) else {
                break;
            };
            match (unit * bpp, d) {
                (1, 2) => decimate_row::<1, 2>(row, out),
                (2, 2) => decimate_row::<2, 4>(row, out),
                (3, 2) => decimate_row::<3, 6>(row, out),
                (4, 2) => decimate_row::<4, 8>(row, out),
                (1, _) => decimate_row_by::<1>(row, out, step),
                (2, _) => decimate_row_by::<2>(row, out, step),
                (3, _) => decimate_row_by::<3>(row, out, step),
                (4, _) => decimate_row_by::<4>(row, out, step),
                (u, _) => {
                    for (s, o) in row.chunks(step).zip(out.chunks_exact_mut(u)) {
                        if let Some(s) = s.get(..u) {
                            o.copy_from_slice(s);
                        }
                    }
                }
            }
        }
        self.stride = row_out;
        self.width = out_w;
        self.height = out_h;
        self.format = format;
        self.frame_id = frame_id;
        self.timestamp_s = timestamp_s;
    }

    /// Takes the caller's frame buffer without copying: swaps it with this frame's buffer
    /// (which the caller gets back, resized to the same length, to fill with a later frame).
    /// The buffer is checked first; when it does not hold the frame described, nothing changes.
    #[allow(clippy::too_many_arguments)]
    pub fn swap_in(
        &mut self,
        buf: &mut Vec<u8>,
        width: usize,
        height: usize,
        stride: usize,
        format: PixelFormat,
        frame_id: u64,
        timestamp_s: f64,
    ) -> Result<(), CoreError> {
        FrameView::new(buf, width, height, stride, format)?;
        let len = buf.len();
        std::mem::swap(&mut self.data, buf);
        buf.resize(len, 0);
        self.stride = stride;
        self.width = width;
        self.height = height;
        self.format = format;
        self.frame_id = frame_id;
        self.timestamp_s = timestamp_s;
        Ok(())
    }

    /// A view of the copy; an error when nothing was copied yet.
    pub fn view(&self) -> Result<FrameView<'_>, CoreError> {
        FrameView::new(
            &self.data,
            self.width,
            self.height,
            self.stride,
            self.format,
        )
    }

    /// True before the first copy.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
    /// Width, px.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height, px.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Pixel format.
    pub fn format(&self) -> PixelFormat {
        self.format
    }
    /// The frame id given when it was copied.
    pub fn frame_id(&self) -> u64 {
        self.frame_id
    }
    /// The timestamp given when it was copied, s.
    pub fn timestamp_s(&self) -> f64 {
        self.timestamp_s
    }
    /// The bytes (rows `stride` bytes apart).
    pub fn data(&self) -> &[u8] {
        &self.data
    }
    /// Row stride, bytes.
    pub fn stride(&self) -> usize {
        self.stride
    }
}

/// Copies the first `U` bytes of every `S` bytes of `src` into `out` (`U` and `S` constant,
/// so that the compiler vectorises the common decimation by 2).
fn decimate_row<const U: usize, const S: usize>(src: &[u8], out: &mut [u8]) {
    let mut srcs = src.chunks_exact(S);
    let mut outs = out.chunks_exact_mut(U);
    for (s, o) in (&mut srcs).zip(&mut outs) {
        o.copy_from_slice(&s[..U]);
    }
    // A last unit that starts in the row's incomplete last step.
    if let (Some(o), Some(s)) = (outs.next(), srcs.remainder().get(..U)) {
        o.copy_from_slice(s);
    }
}

/// [`decimate_row`] for any step.
fn decimate_row_by<const U: usize>(src: &[u8], out: &mut [u8], step: usize) {
    for (s, o) in src.chunks(step).zip(out.chunks_exact_mut(U)) {
        if let Some(s) = s.get(..U) {
            o.copy_from_slice(s);
        }
    }
}

/// Writes a frame as binary PNM (P5 grey for mono and Bayer, 8 or 16 bit; P6 for RGB), the
/// form `rodtrack calibrate` reads back (Bayer stored as mono).
pub fn to_pnm(frame: &OwnedFrame) -> Vec<u8> {
    let fmt = frame.format();
    let (magic, maxval) = match (fmt.luma_kind(), fmt.is_16bit()) {
        (LumaKind::Rgb, _) => ("P6", 255),
        (_, true) => ("P5", 65535),
        (_, false) => ("P5", 255),
    };
    let mut out = format!("{magic}\n{} {}\n{maxval}\n", frame.width(), frame.height()).into_bytes();
    let row = frame.width() * fmt.bytes_per_pixel();
    for r in frame
        .data()
        .chunks(frame.stride().max(1))
        .take(frame.height())
    {
        let r = &r[..row.min(r.len())];
        if fmt.is_16bit() {
            // PNM stores 16-bit samples big endian.
            for px in r.chunks_exact(2) {
                out.push(px[1]);
                out.push(px[0]);
            }
        } else {
            out.extend_from_slice(r);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bayer_preview_is_the_colour_of_each_block() {
        // R=200, G=100, B=40 everywhere, RGGB, with a padded stride.
        let (w, h, stride) = (8, 6, 11);
        let mut data = vec![7u8; stride * h];
        for y in 0..h {
            for x in 0..w {
                data[y * stride + x] = [[200, 100], [100, 40]][y % 2][x % 2];
            }
        }
        let f = FrameView::new(&data, w, h, stride, PixelFormat::BayerRggb8).unwrap();
        let p = preview(&f, 3);
        assert_eq!((p.width, p.height, p.channels, p.factor), (2, 1, 3, 4));
        assert_eq!(p.pixels, vec![200, 100, 40, 200, 100, 40]);
        let owned = OwnedFrame::from_view(&f, 5, 0.5);
        assert_eq!(owned.data().len(), w * h);
        assert_eq!(owned.view().unwrap().luma_node(2, 2), 110.0);
    }

    #[test]
    fn decimated_copies_keep_every_dth_pixel_or_bayer_block() {
        // Pixel (x, y) holds x + 10 y (mod 256), 2 bytes per pixel for the 16-bit formats.
        let (w, h) = (11, 9);
        for format in PixelFormat::ALL {
            let bpp = format.bytes_per_pixel();
            let stride = w * bpp + 3;
            let mut data = vec![0u8; stride * h];
            for y in 0..h {
                for x in 0..w {
                    for b in 0..bpp {
                        data[y * stride + x * bpp + b] = (x + 10 * y + 100 * b) as u8;
                    }
                }
            }
            let f = FrameView::new(&data, w, h, stride, format).unwrap();
            let bayer = format.luma_kind() == LumaKind::Bayer;
            for d in 1..5 {
                let mut o = OwnedFrame::default();
                o.copy_decimated(&f, d, 3, 0.25);
                // Source coordinate of kept pixel i along an axis.
                let src = |i: usize| {
                    if bayer && d > 1 {
                        (i / 2) * 2 * d + i % 2
                    } else {
                        i * d
                    }
                };
                let (ew, eh) = if bayer && d > 1 {
                    ((w / 2).div_ceil(d) * 2, (h / 2).div_ceil(d) * 2)
                } else {
                    (w.div_ceil(d), h.div_ceil(d))
                };
                assert_eq!((o.width(), o.height()), (ew, eh), "{format:?} d {d}");
                assert_eq!(
                    (o.frame_id(), o.timestamp_s(), o.format()),
                    (3, 0.25, format)
                );
                assert_eq!(o.data().len(), ew * eh * bpp);
                for y in 0..eh {
                    for x in 0..ew {
                        for b in 0..bpp {
                            assert_eq!(
                                o.data()[y * o.stride() + x * bpp + b],
                                (src(x) + 10 * src(y) + 100 * b) as u8,
                                "{format:?} d {d} ({x}, {y})"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn mono_preview_averages_blocks() {
        let data: Vec<u8> = (0..16).map(|i| (i * 10) as u8).collect();
        let f = FrameView::packed(&data, 4, 4, PixelFormat::Mono8).unwrap();
        let p = preview(&f, 2);
        assert_eq!((p.width, p.height, p.channels), (2, 2, 1));
        // Block (0,0): 0, 10, 40, 50.
        assert_eq!(p.pixels[0], 25);
        let pnm = to_pnm(&OwnedFrame::from_view(&f, 0, 0.0));
        assert!(pnm.starts_with(b"P5\n4 4\n255\n"));
        assert_eq!(pnm.len(), 11 + 16);
    }
}
