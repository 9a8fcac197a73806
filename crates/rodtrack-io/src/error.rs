//! The crate's error type: every variant names the file (or input, or address) and what is
//! wrong with it.

use rodtrack_core::CoreError;
use std::path::PathBuf;
use thiserror::Error;

/// Everything that can go wrong in rodtrack's I/O.
///
/// Errors about one frame (see [`IoError::is_fatal`]) do not end a frame source: the next call
/// to [`crate::FrameSource::next_frame`] goes on with the next frame.
#[derive(Debug, Error)]
pub enum IoError {
    /// An input folder does not exist or is not a folder.
    #[error("{path}: folder does not exist")]
    MissingFolder {
        /// The folder.
        path: PathBuf,
    },
    /// An input folder (or pattern) holds no image files.
    #[error("{path}: no image files (.png, .pgm, .ppm, .pnm, .tif, .tiff) found")]
    NoImages {
        /// The folder or pattern.
        path: PathBuf,
    },
    /// A file could not be opened, read or written.
    #[error("{path}: {action}: {source}")]
    File {
        /// The file.
        path: PathBuf,
        /// What was being done (`cannot read`, `cannot write`, ...).
        action: &'static str,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// An image file is corrupt, truncated or in an unsupported encoding.
    #[error("{path}: cannot decode image: {reason}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// The decoder's message.
        reason: String,
    },
    /// A frame's size differs from the sequence's size.
    #[error("{path}: wrong frame size: expected {expected_width}x{expected_height}, got {width}x{height}")]
    WrongSize {
        /// The file.
        path: PathBuf,
        /// Expected width, px.
        expected_width: usize,
        /// Expected height, px.
        expected_height: usize,
        /// Width found, px.
        width: usize,
        /// Height found, px.
        height: usize,
    },
    /// A frame's pixel format cannot be used as the sequence's format.
    #[error("{path}: wrong pixel format: expected {expected}, got {got}")]
    WrongFormat {
        /// The file.
        path: PathBuf,
        /// What the sequence needs.
        expected: String,
        /// What the file holds.
        got: String,
    },
    /// A frame size (from a file header or an input string) whose bytes overflow or exceed
    /// the limit: refused before anything is allocated.
    #[error("frame size {width}x{height} is too large (more than {max_bytes} bytes)")]
    FrameTooLarge {
        /// Width, px.
        width: usize,
        /// Height, px.
        height: usize,
        /// The limit, bytes.
        max_bytes: usize,
    },
    /// A file is larger than any frame of the expected size can be: not read.
    #[error("{path}: file too large for a frame: {len} bytes, at most {max} expected")]
    FileTooLarge {
        /// The file.
        path: PathBuf,
        /// Its length, bytes.
        len: u64,
        /// The most a frame file of the expected size may take, bytes.
        max: u64,
    },
    /// A path in an input folder is not a regular file (after following symlinks): a device,
    /// a FIFO, a socket, a dangling link. Never opened.
    #[error("{path}: not a regular file ({kind}), skipped")]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What it is.
        kind: &'static str,
    },
    /// A raw frame is shorter (or longer) than width x height x bytes per pixel.
    #[error("{path}: raw frame {frame} is truncated: expected {expected} bytes, got {got}")]
    TruncatedRaw {
        /// The file.
        path: PathBuf,
        /// Frame index (in the file) or frame id (folder of raw files).
        frame: u64,
        /// Bytes needed for one frame.
        expected: u64,
        /// Bytes available.
        got: u64,
    },
    /// A raw file holds more bytes than one frame (folder of `.raw` files).
    #[error("{path}: raw file has the wrong length: expected {expected} bytes, got {got}")]
    RawLength {
        /// The file.
        path: PathBuf,
        /// Bytes of one frame.
        expected: u64,
        /// Bytes in the file.
        got: u64,
    },
    /// An input string (`--input`) is malformed.
    #[error("input `{input}`: {reason}")]
    BadInput {
        /// The input string.
        input: String,
        /// What is wrong.
        reason: String,
    },
    /// An input scheme exists but is not compiled into this build.
    #[error("input `{input}`: `{scheme}` sources are not supported in this build")]
    Unsupported {
        /// The input string.
        input: String,
        /// The scheme (`video`, `genicam`, `sim`, ...).
        scheme: String,
    },
    /// A text file (CSV, JSON Lines, sidecar) has a bad value.
    #[error("{path}: line {line}, column `{column}`: {reason}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// Line number, from 1.
        line: usize,
        /// Column name.
        column: String,
        /// What is wrong.
        reason: String,
    },
    /// A network send or receive failed.
    #[error("udp {addr}: {source}")]
    Net {
        /// The address.
        addr: String,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// A UDP datagram does not follow the documented layout.
    #[error("udp packet: {0}")]
    Packet(String),
    /// A frame buffer's metadata does not fit its data.
    #[error("frame {frame_id} (camera {camera}): {source}")]
    Frame {
        /// Camera index.
        camera: u32,
        /// Frame id.
        frame_id: u64,
        /// The core's check.
        #[source]
        source: CoreError,
    },
    /// A source stopped for good (a camera disconnected, ...). Ends the stream.
    #[error("source `{name}`: {reason}")]
    SourceFailed {
        /// The source's name.
        name: String,
        /// Why.
        reason: String,
    },
    /// A pipeline's configuration is invalid.
    #[error("pipeline: {0}")]
    Config(String),
    /// A recording file (MCAP) that cannot be read, or a message that cannot be recorded.
    #[error("{path}: {reason}")]
    Recording {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// The error of [`crate::FrameSource`]s.
pub type SourceError = IoError;

impl IoError {
    /// True when the error ends the stream or the operation (missing folder, bad input string,
    /// failed source); false for an error about one frame or one file, after which a source
    /// goes on with the next frame.
    pub fn is_fatal(&self) -> bool {
        matches!(
            self,
            IoError::MissingFolder { .. }
                | IoError::NoImages { .. }
                | IoError::BadInput { .. }
                | IoError::Unsupported { .. }
                | IoError::SourceFailed { .. }
                | IoError::Config(_)
        )
    }

    pub(crate) fn file(
        path: impl Into<PathBuf>,
        action: &'static str,
        source: std::io::Error,
    ) -> Self {
        IoError::File {
            path: path.into(),
            action,
            source,
        }
    }
}
