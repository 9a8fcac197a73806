//! Raw frames: one file of concatenated frames, or a folder of `.raw` files (one frame each).

use super::naming::{list_files_noting, number_frames, TIMESTAMPS_FILE};
use super::timestamps::read_timestamps_csv_noting;
use super::{FrameSource, SourceInfo, DEFAULT_FPS};
use crate::frame::{frame_bytes, FrameBuffer, Timestamp, MAX_FRAME_BYTES};
use crate::{IoError, SourceError};
use rodtrack_core::PixelFormat;
use std::collections::HashMap;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Geometry of raw frames, which the files do not record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawOptions {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// Pixel format (16-bit formats are little endian).
    pub format: PixelFormat,
    /// Bytes from one row to the next (padding included); `None`: packed. Every row, the last
    /// included, takes `stride` bytes in the file.
    pub stride: Option<usize>,
    /// Frame rate for timestamps (`frame id / fps`); `None`: [`DEFAULT_FPS`].
    pub fps: Option<f64>,
    /// Bytes to skip at the start of a single raw file (a header).
    pub header_bytes: u64,
}

impl RawOptions {
    /// Packed frames of the given size and format, default fps, no header.
    pub fn new(width: usize, height: usize, format: PixelFormat) -> Self {
        RawOptions {
            width,
            height,
            format,
            stride: None,
            fps: None,
            header_bytes: 0,
        }
    }

    fn stride(&self) -> usize {
        self.stride
            .unwrap_or(self.width.saturating_mul(self.format.bytes_per_pixel()))
    }

    fn frame_bytes(&self) -> usize {
        self.stride().saturating_mul(self.height)
    }
}

#[derive(Debug)]
enum Layout {
    /// One file; `count` whole frames, then `tail` bytes of a partial frame.
    File {
        path: PathBuf,
        file: File,
        count: u64,
        tail: u64,
    },
    /// A folder of one-frame files.
    Folder {
        files: Vec<(u64, PathBuf)>,
        timestamps: Option<HashMap<u64, f64>>,
    },
}

/// Raw frames of a known size and format (e.g. Bayer 8-bit straight from a camera).
#[derive(Debug)]
pub struct RawSource {
    name: String,
    options: RawOptions,
    layout: Layout,
    pos: u64,
    done: bool,
    warnings: Vec<String>,
}

impl RawSource {
    /// Opens a raw file or a folder of `.raw` files. Checks the geometry (width and height at
    /// least 2, stride at least one row).
    pub fn open(path: &Path, options: RawOptions) -> Result<Self, IoError> {
        let bad = |reason: String| IoError::BadInput {
            input: path.display().to_string(),
            reason,
        };
        if options.width < 2 || options.height < 2 {
            return Err(bad(format!(
                "raw frame size {}x{} is too small (at least 2x2)",
                options.width, options.height
            )));
        }
        let row = options
            .width
            .saturating_mul(options.format.bytes_per_pixel());
        if frame_bytes(
            options.width,
            options.height,
            options.stride(),
            options.format,
        )
        .is_none_or(|b| b > MAX_FRAME_BYTES)
            && options.stride() >= row
        {
            return Err(bad(format!(
                "raw frame size {}x{} (stride {}) is too large (more than {MAX_FRAME_BYTES} bytes)",
                options.width,
                options.height,
                options.stride()
            )));
        }
        if options.stride() < row {
            return Err(bad(format!(
                "stride {} is shorter than one row ({row} bytes)",
                options.stride()
            )));
        }
        let mut warnings = Vec::new();
        let layout = if path.is_dir() {
            let list = list_files_noting(path, &["raw"], &mut warnings)?;
            if list.is_empty() {
                return Err(bad("folder holds no .raw files".into()));
            }
            let (files, mut naming) = number_frames(list);
            warnings.append(&mut naming);
            let sidecar = path.join(TIMESTAMPS_FILE);
            let timestamps = if sidecar.symlink_metadata().is_ok() {
                Some(read_timestamps_csv_noting(&sidecar, &mut warnings)?)
            } else {
                None
            };
            Layout::Folder { files, timestamps }
        } else {
            if let Some(kind) = super::naming::not_a_regular_file(path) {
                return Err(IoError::NotAFile {
                    path: path.to_path_buf(),
                    kind,
                });
            }
            let mut file = File::open(path).map_err(|e| IoError::file(path, "cannot open", e))?;
            let len = file
                .metadata()
                .map_err(|e| IoError::file(path, "cannot read", e))?
                .len();
            let body = len.saturating_sub(options.header_bytes);
            let fb = options.frame_bytes() as u64;
            file.seek(SeekFrom::Start(options.header_bytes.min(len)))
                .map_err(|e| IoError::file(path, "cannot read", e))?;
            Layout::File {
                path: path.to_path_buf(),
                file,
                count: body / fb,
                tail: body % fb,
            }
        };
        Ok(RawSource {
            name: path.display().to_string(),
            options,
            layout,
            pos: 0,
            done: false,
            warnings,
        })
    }

    fn fps(&self) -> f64 {
        self.options
            .fps
            .filter(|f| *f > 0.0 && f.is_finite())
            .unwrap_or(DEFAULT_FPS)
    }
}

impl FrameSource for RawSource {
    fn info(&self) -> SourceInfo {
        let frame_count = match &self.layout {
            Layout::File { count, .. } => *count,
            Layout::Folder { files, .. } => files.len() as u64,
        };
        SourceInfo {
            name: self.name.clone(),
            width: self.options.width,
            height: self.options.height,
            format: self.options.format,
            fps: Some(self.fps()),
            frame_count: Some(frame_count),
            live: false,
        }
    }

    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        if self.done {
            return Ok(None);
        }
        let fps = self.fps();
        let o = self.options;
        let fb = o.frame_bytes() as u64;
        let i = self.pos;
        match &mut self.layout {
            Layout::File {
                path,
                file,
                count,
                tail,
            } => {
                buf.meta.frame_id = i;
                buf.meta.timestamp_ns = Timestamp::from_frame(i, fps);
                if i >= *count {
                    self.done = true;
                    if *tail > 0 {
                        return Err(IoError::TruncatedRaw {
                            path: path.clone(),
                            frame: i,
                            expected: fb,
                            got: *tail,
                        });
                    }
                    return Ok(None);
                }
                self.pos += 1;
                buf.try_reshape(o.width, o.height, o.stride(), o.format, MAX_FRAME_BYTES)?;
                let at = o.header_bytes + i * fb;
                file.seek(SeekFrom::Start(at))
                    .and_then(|_| file.read_exact(&mut buf.data))
                    .map_err(|e| IoError::file(path.clone(), "cannot read", e))?;
                Ok(Some(()))
            }
            Layout::Folder { files, timestamps } => {
                let Some((id, path)) = files.get(i as usize) else {
                    self.done = true;
                    return Ok(None);
                };
                self.pos += 1;
                buf.meta.frame_id = *id;
                buf.meta.timestamp_ns = match timestamps.as_ref().and_then(|t| t.get(id)) {
                    Some(s) => Timestamp::from_secs_f64(*s),
                    None => Timestamp::from_frame(*id, fps),
                };
                if let Some(kind) = super::naming::not_a_regular_file(path) {
                    return Err(IoError::NotAFile {
                        path: path.clone(),
                        kind,
                    });
                }
                let mut f =
                    File::open(path).map_err(|e| IoError::file(path.clone(), "cannot open", e))?;
                let len = f
                    .metadata()
                    .map_err(|e| IoError::file(path.clone(), "cannot read", e))?
                    .len();
                if len < fb {
                    return Err(IoError::TruncatedRaw {
                        path: path.clone(),
                        frame: *id,
                        expected: fb,
                        got: len,
                    });
                }
                if len > fb {
                    return Err(IoError::RawLength {
                        path: path.clone(),
                        expected: fb,
                        got: len,
                    });
                }
                buf.try_reshape(o.width, o.height, o.stride(), o.format, MAX_FRAME_BYTES)?;
                f.read_exact(&mut buf.data)
                    .map_err(|e| IoError::file(path.clone(), "cannot read", e))?;
                Ok(Some(()))
            }
        }
    }
}
