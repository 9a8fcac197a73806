//! Frame metadata, owned frame buffers and the buffer pool.
//!
//! A [`FrameBuffer`] owns the bytes of one frame plus its [`FrameMeta`]; sources decode into it,
//! reusing its `Vec`, and [`FrameBuffer::view`] lends it to the core as a validated
//! [`FrameView`]. A [`BufferPool`] recycles buffers between the capture thread and the
//! processing stage, so that steady-state reading allocates nothing per frame.

use crate::IoError;
use crossbeam_channel::{Receiver, Sender};
pub use rodtrack_core::Timestamp;
use rodtrack_core::{CoreError, FrameView, PixelFormat};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// What is known about one frame besides its pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMeta {
    /// Camera index within a pipeline (set by the pipeline; 0 for a lone source).
    pub camera: u32,
    /// The frame id: the camera's frame counter, or the number in the file name.
    pub frame_id: u64,
    /// Capture time.
    pub timestamp_ns: Timestamp,
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// Distance between rows, bytes (at least `width * bytes_per_pixel`).
    pub stride: usize,
    /// Pixel format.
    pub format: PixelFormat,
}

impl Default for FrameMeta {
    fn default() -> Self {
        FrameMeta {
            camera: 0,
            frame_id: 0,
            timestamp_ns: Timestamp(0),
            width: 0,
            height: 0,
            stride: 0,
            format: PixelFormat::Mono8,
        }
    }
}

/// One frame's bytes and metadata. The `Vec` is reused from frame to frame.
#[derive(Debug, Clone, Default)]
pub struct FrameBuffer {
    /// Metadata.
    pub meta: FrameMeta,
    /// Pixel bytes: `height` rows of `stride` bytes (the last row may stop after its pixels).
    pub data: Vec<u8>,
}

impl FrameBuffer {
    /// An empty buffer (no allocation).
    pub fn new() -> Self {
        FrameBuffer::default()
    }

    /// An empty buffer with room for `bytes` bytes.
    pub fn with_capacity(bytes: usize) -> Self {
        FrameBuffer {
            meta: FrameMeta::default(),
            data: Vec::with_capacity(bytes),
        }
    }

    /// Sets size, stride and format and resizes `data` to `stride * height` bytes, reusing the
    /// allocation when it is large enough. New bytes are zero; old bytes are left as they were.
    pub fn reshape(&mut self, width: usize, height: usize, stride: usize, format: PixelFormat) {
        self.meta.width = width;
        self.meta.height = height;
        self.meta.stride = stride;
        self.meta.format = format;
        self.data.resize(stride * height, 0);
    }

    /// Like [`FrameBuffer::reshape`] with a packed stride (`width * bytes_per_pixel`).
    pub fn reshape_packed(&mut self, width: usize, height: usize, format: PixelFormat) {
        self.reshape(width, height, width * format.bytes_per_pixel(), format);
    }

    /// Like [`FrameBuffer::reshape`], for sizes that came from outside (a file header, an
    /// input string): refuses, before allocating anything, a size whose bytes overflow or
    /// exceed `max_bytes` (see [`MAX_FRAME_BYTES`]). On error the buffer is unchanged.
    pub fn try_reshape(
        &mut self,
        width: usize,
        height: usize,
        stride: usize,
        format: PixelFormat,
        max_bytes: usize,
    ) -> Result<(), IoError> {
        let bytes = frame_bytes(width, height, stride, format).filter(|b| *b <= max_bytes);
        let Some(bytes) = bytes else {
            return Err(IoError::FrameTooLarge {
                width,
                height,
                max_bytes,
            });
        };
        self.meta.width = width;
        self.meta.height = height;
        self.meta.stride = stride;
        self.meta.format = format;
        self.data.resize(bytes, 0);
        Ok(())
    }

    /// [`FrameBuffer::try_reshape`] with a packed stride.
    pub fn try_reshape_packed(
        &mut self,
        width: usize,
        height: usize,
        format: PixelFormat,
        max_bytes: usize,
    ) -> Result<(), IoError> {
        let stride = width
            .checked_mul(format.bytes_per_pixel())
            .ok_or(IoError::FrameTooLarge {
                width,
                height,
                max_bytes,
            })?;
        self.try_reshape(width, height, stride, format, max_bytes)
    }

    /// A validated view for the core.
    pub fn view(&self) -> Result<FrameView<'_>, CoreError> {
        FrameView::new(
            &self.data,
            self.meta.width,
            self.meta.height,
            self.meta.stride,
            self.meta.format,
        )
    }

    /// Like [`FrameBuffer::view`], with an [`IoError`] that names the camera and frame.
    pub fn try_view(&self) -> Result<FrameView<'_>, IoError> {
        self.view().map_err(|source| IoError::Frame {
            camera: self.meta.camera,
            frame_id: self.meta.frame_id,
            source,
        })
    }

    /// Bytes of row `y` (its pixels only, without padding), or `None` out of range.
    pub fn row(&self, y: usize) -> Option<&[u8]> {
        if y >= self.meta.height {
            return None;
        }
        let start = y * self.meta.stride;
        let len = self.meta.width * self.meta.format.bytes_per_pixel();
        self.data.get(start..start + len)
    }
}

/// The largest frame a [`FrameBuffer`] takes from outside data (file headers, input strings)
/// by default: 256 MiB, far above any camera here (1440x1080 Bayer is 1.5 MB).
pub const MAX_FRAME_BYTES: usize = 256 << 20;

/// `stride * height` bytes, checked: `None` on overflow or when `stride` is shorter than a
/// row of `width` pixels.
pub fn frame_bytes(
    width: usize,
    height: usize,
    stride: usize,
    format: PixelFormat,
) -> Option<usize> {
    let row = width.checked_mul(format.bytes_per_pixel())?;
    if stride < row {
        return None;
    }
    stride.checked_mul(height)
}

/// A bounded pool of [`FrameBuffer`]s shared between threads (cheap to clone).
///
/// [`BufferPool::get`] hands out a recycled buffer, or a new one when the pool is empty;
/// [`BufferPool::put`] returns it, or drops it when the pool already holds `capacity` buffers.
/// Once as many buffers as are ever in flight have been made, no more are allocated.
#[derive(Debug, Clone)]
pub struct BufferPool {
    tx: Sender<FrameBuffer>,
    rx: Receiver<FrameBuffer>,
    created: Arc<AtomicUsize>,
}

impl BufferPool {
    /// A pool keeping at most `capacity` idle buffers.
    pub fn new(capacity: usize) -> Self {
        let (tx, rx) = crossbeam_channel::bounded(capacity.max(1));
        BufferPool {
            tx,
            rx,
            created: Arc::new(AtomicUsize::new(0)),
        }
    }

    /// A recycled buffer, or a new empty one.
    pub fn get(&self) -> FrameBuffer {
        match self.rx.try_recv() {
            Ok(buf) => buf,
            Err(_) => {
                self.created.fetch_add(1, Ordering::Relaxed);
                FrameBuffer::new()
            }
        }
    }

    /// Returns a buffer to the pool (dropped if the pool is full).
    pub fn put(&self, buf: FrameBuffer) {
        let _ = self.tx.try_send(buf);
    }

    /// How many buffers this pool has created so far.
    pub fn created(&self) -> usize {
        self.created.load(Ordering::Relaxed)
    }

    /// How many idle buffers the pool holds now.
    pub fn idle(&self) -> usize {
        self.rx.len()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn pool_recycles_without_new_allocations() {
        let pool = BufferPool::new(2);
        let mut a = pool.get();
        a.reshape_packed(64, 48, PixelFormat::Mono8);
        let ptr = a.data.as_ptr();
        pool.put(a);
        for _ in 0..100 {
            let mut b = pool.get();
            b.reshape_packed(64, 48, PixelFormat::Mono8);
            assert_eq!(b.data.as_ptr(), ptr);
            pool.put(b);
        }
        assert_eq!(pool.created(), 1);
    }

    #[test]
    fn try_reshape_refuses_huge_and_overflowing_sizes_without_allocating() {
        let mut b = FrameBuffer::new();
        let e = b
            .try_reshape_packed(
                2_000_000_000,
                2_000_000_000,
                PixelFormat::Mono8,
                MAX_FRAME_BYTES,
            )
            .unwrap_err();
        assert!(e.to_string().contains("2000000000x2000000000"), "{e}");
        assert!(b
            .try_reshape_packed(usize::MAX, 3, PixelFormat::Mono16, usize::MAX)
            .is_err());
        assert!(b.try_reshape(4, 4, 2, PixelFormat::Mono8, 1 << 20).is_err());
        assert_eq!(b.data.capacity(), 0);
        b.try_reshape_packed(64, 48, PixelFormat::Mono16, 64 * 48 * 2)
            .unwrap();
        assert_eq!(b.data.len(), 64 * 48 * 2);
    }

    #[test]
    fn view_honours_padded_stride() {
        let mut b = FrameBuffer::new();
        b.reshape(4, 3, 8, PixelFormat::Mono8);
        for y in 0..3 {
            for x in 0..8 {
                b.data[y * 8 + x] = if x < 4 { (10 * y + x) as u8 } else { 255 };
            }
        }
        let v = b.view().unwrap();
        assert_eq!(v.luma_node(3, 2), 23.0);
        assert_eq!(b.row(1).unwrap(), &[10, 11, 12, 13]);
        assert!(b.row(3).is_none());
    }
}
