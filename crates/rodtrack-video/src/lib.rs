//! rodtrack's video-file frame source: `video:FILE` inputs decoded through FFmpeg.
//!
//! Everything here sits behind the crate feature `video` (off by default), which pulls in
//! `ffmpeg-next` and so FFmpeg's development libraries (Debian: `libavcodec-dev
//! libavformat-dev libavutil-dev libswscale-dev ... clang libclang-dev pkg-config`, see
//! `.ci/video.sh`). Without the feature the crate is empty and needs no system library, so a
//! plain `cargo test --workspace` works on a fresh machine.
//!
//! Layout:
//! - `VideoSource` (module `source`): a [`rodtrack_io::FrameSource`] over one video stream
//!   (demux, decode, convert into the caller's pooled [`rodtrack_io::FrameBuffer`]);
//! - module `convert`: plain-Rust conversions from decoded planes (padded rows, any stride)
//!   to rodtrack's packed pixel formats, with no FFmpeg in them;
//! - `register` / `open_input`: the `video` scheme for [`rodtrack_io::SourceFactory`].
//!
//! What is decoded: any codec FFmpeg has (FFV1, H.264, rawvideo, ...). Grey streams give
//! `mono8` (or a Bayer format stored as grey, chosen by the `format` option, as for image
//! sequences); rawvideo Bayer streams (`bayer_rggb8` in NUT) give that Bayer format; YUV
//! streams give their luma plane as `mono8` (or `rgb8` on request); RGB streams give `rgb8` (or
//! `mono8` luminance on request).

#[cfg(feature = "video")]
mod convert;
#[cfg(feature = "video")]
mod source;

#[cfg(feature = "video")]
pub use source::{open_input, register, VideoOptions, VideoSource};
