//! Frame sources: one trait, several implementations.
//!
//! Lifecycle: a source is opened by its constructor (which checks everything it can up front:
//! the folder exists, the first frame decodes, ...), delivers frames one at a time with
//! [`FrameSource::next_frame`] into a caller-owned (pooled) [`FrameBuffer`], and is closed by
//! dropping it.

mod images;
mod naming;
mod raw;
mod timestamps;
mod uri;

pub use images::{
    decode_image_file, max_image_file_bytes, ImageDecoderScratch, ImageSequence,
    ImageSequenceOptions, DEFAULT_MAX_PIXELS,
};
pub use naming::{
    frame_ids_from_names, list_files_noting, list_image_files, list_image_files_noting,
    not_a_regular_file, number_frames, parse_frame_number, IMAGE_EXTENSIONS, TIMESTAMPS_FILE,
};
pub use raw::{RawOptions, RawSource};
pub use timestamps::{
    parse_timestamps_csv, read_capped, read_timestamps_csv, read_timestamps_csv_noting,
    MAX_SIDECAR_BYTES, MAX_TIMESTAMP_S,
};
pub use uri::{InputKind, InputSpec, OpenOptions, SourceBuilder, SourceFactory};

use crate::{FrameBuffer, SourceError};
use rodtrack_core::PixelFormat;

/// The frame rate assumed when neither the caller nor a sidecar file gives one.
pub const DEFAULT_FPS: f64 = 200.0;

/// What a source can tell about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceInfo {
    /// A human-readable name (folder, file, camera id).
    pub name: String,
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// Pixel format of the frames delivered.
    pub format: PixelFormat,
    /// Nominal frame rate, if known.
    pub fps: Option<f64>,
    /// Number of frames, if known (files).
    pub frame_count: Option<u64>,
    /// True for live sources (cameras): they cannot be paused, so a slow consumer makes frames
    /// drop. False for recordings, which a pipeline may read as fast as it can.
    pub live: bool,
}

/// A source of frames: image sequence, raw file, video, camera, simulator.
///
/// Contract of [`FrameSource::next_frame`]:
/// - `Ok(Some(()))`: `buf` holds the next frame (its `meta` and `data`); the source reuses
///   `buf.data`'s allocation.
/// - `Ok(None)`: end of stream; every later call returns `Ok(None)` too.
/// - `Err(e)`: this frame is bad (corrupt, truncated, wrong size or format). The stream is
///   *not* over: the next call goes on with the next frame. Before failing, a source sets
///   `buf.meta.frame_id` and `buf.meta.timestamp_ns` to the bad frame's values when it knows
///   them, so that the tracker can report the frame as bad. An error for which
///   [`crate::IoError::is_fatal`] is true means the source cannot go on; its next call returns
///   `Ok(None)`.
///
/// `buf.meta.camera` is left to the caller (a pipeline sets its camera index).
pub trait FrameSource: Send {
    /// Name, size, format, frame rate and frame count.
    fn info(&self) -> SourceInfo;

    /// Reads the next frame into `buf`; see the trait's documentation.
    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError>;

    /// What the source noticed while opening and wants the user to know, without failing:
    /// files left out of a folder (not regular files, names without a frame number), a
    /// suspicious sidecar. Empty by default.
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }
}

impl std::fmt::Debug for dyn FrameSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "FrameSource({:?})", self.info().name)
    }
}

impl<S: FrameSource + ?Sized> FrameSource for Box<S> {
    fn info(&self) -> SourceInfo {
        (**self).info()
    }
    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        (**self).next_frame(buf)
    }
    fn warnings(&self) -> Vec<String> {
        (**self).warnings()
    }
}
