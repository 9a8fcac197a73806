//! Image sequences: a folder (or pattern) of PNG, PGM/PPM or TIFF files.

use super::naming::{frame_ids_from_names, list_image_files, read_timestamps_csv, TIMESTAMPS_FILE};
use super::{FrameSource, SourceInfo, DEFAULT_FPS};
use crate::frame::{FrameBuffer, Timestamp};
use crate::{IoError, SourceError};
use image::{ColorType, ImageDecoder, ImageFormat, ImageReader};
use rodtrack_core::{LumaKind, PixelFormat};
use std::collections::HashMap;
use std::io::{Cursor, Read};
use std::path::{Path, PathBuf};

/// How to open an [`ImageSequence`].
#[derive(Debug, Clone, Default)]
pub struct ImageSequenceOptions {
    /// How to interpret the images: grey files as `mono8`/`mono16` or as a Bayer mosaic stored
    /// as grey (`bayer_rggb8`, ...); RGB files only as `rgb8`. `None`: from the first file
    /// (grey 8-bit -> mono8, grey 16-bit -> mono16, RGB -> rgb8).
    pub format: Option<PixelFormat>,
    /// Frame rate for timestamps (`frame id / fps`) when there is no sidecar. `None`:
    /// [`DEFAULT_FPS`].
    pub fps: Option<f64>,
    /// Required frame size `(width, height)`; `None`: the first file's size.
    pub size: Option<(usize, usize)>,
    /// Ignore a `timestamps.csv` sidecar even if present.
    pub ignore_sidecar: bool,
}

/// What the file holds, before conversion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FileLayout {
    channels: usize,
    bits16: bool,
    rgb: bool,
}

impl FileLayout {
    fn from_color(c: ColorType) -> Option<Self> {
        let (channels, bits16, rgb) = match c {
            ColorType::L8 => (1, false, false),
            ColorType::La8 => (2, false, false),
            ColorType::Rgb8 => (3, false, true),
            ColorType::Rgba8 => (4, false, true),
            ColorType::L16 => (1, true, false),
            ColorType::La16 => (2, true, false),
            ColorType::Rgb16 => (3, true, true),
            ColorType::Rgba16 => (4, true, true),
            _ => return None,
        };
        Some(FileLayout {
            channels,
            bits16,
            rgb,
        })
    }
    fn describe(self) -> String {
        let kind = match (self.rgb, self.channels) {
            (true, 4) => "RGBA",
            (true, _) => "RGB",
            (false, 2) => "grey+alpha",
            (false, _) => "grey",
        };
        format!("{kind} {}-bit", if self.bits16 { 16 } else { 8 })
    }
    fn default_format(self) -> PixelFormat {
        match (self.rgb, self.bits16) {
            (true, _) => PixelFormat::Rgb8,
            (false, false) => PixelFormat::Mono8,
            (false, true) => PixelFormat::Mono16,
        }
    }
}

/// Reusable memory for decoding image files (file bytes and a conversion buffer).
#[derive(Debug, Default)]
pub struct ImageDecoderScratch {
    file: Vec<u8>,
    pixels: Vec<u8>,
}

fn decode_err(path: &Path, e: impl std::fmt::Display) -> IoError {
    IoError::Decode {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

impl ImageDecoderScratch {
    fn load(&mut self, path: &Path) -> Result<(), IoError> {
        self.file.clear();
        let mut f = std::fs::File::open(path).map_err(|e| IoError::file(path, "cannot open", e))?;
        f.read_to_end(&mut self.file)
            .map_err(|e| IoError::file(path, "cannot read", e))?;
        Ok(())
    }

    /// Reads only the header: `(width, height, format the file would be read as)`.
    fn probe(
        &mut self,
        path: &Path,
        want: Option<PixelFormat>,
    ) -> Result<(usize, usize, PixelFormat), IoError> {
        self.load(path)?;
        let decoder = make_reader(path, &self.file)?
            .into_decoder()
            .map_err(|e| decode_err(path, e))?;
        let (w, h) = decoder.dimensions();
        let layout = layout_of(path, decoder.color_type())?;
        let format = target_format(path, layout, want)?;
        Ok((w as usize, h as usize, format))
    }

    /// Decodes `path` into `buf` (packed stride), as `want` or the file's natural format.
    /// Grey files convert between 8 and 16 bits as needed, 16-bit RGB becomes 8-bit, alpha is
    /// dropped; RGB where grey is wanted (or the reverse) is an error. Sets `buf.meta`'s size,
    /// stride and format; leaves its camera, frame id and timestamp alone.
    pub fn decode(
        &mut self,
        path: &Path,
        want: Option<PixelFormat>,
        buf: &mut FrameBuffer,
    ) -> Result<(), IoError> {
        self.load(path)?;
        let file = std::mem::take(&mut self.file);
        let result = self.decode_loaded(path, &file, want, buf);
        self.file = file;
        result
    }

    fn decode_loaded(
        &mut self,
        path: &Path,
        file: &[u8],
        want: Option<PixelFormat>,
        buf: &mut FrameBuffer,
    ) -> Result<(), IoError> {
        let decoder = make_reader(path, file)?
            .into_decoder()
            .map_err(|e| decode_err(path, e))?;
        let (w, h) = decoder.dimensions();
        let (w, h) = (w as usize, h as usize);
        let layout = layout_of(path, decoder.color_type())?;
        let format = target_format(path, layout, want)?;
        let direct = layout.channels == if format == PixelFormat::Rgb8 { 3 } else { 1 }
            && layout.bits16 == format.is_16bit();
        let total = usize::try_from(decoder.total_bytes())
            .map_err(|_| decode_err(path, "image too large"))?;
        if direct {
            buf.reshape_packed(w, h, format);
            if buf.data.len() != total {
                return Err(decode_err(path, "decoder size mismatch"));
            }
            decoder
                .read_image(&mut buf.data)
                .map_err(|e| decode_err(path, e))?;
            if format.is_16bit() {
                ne_to_le_16(&mut buf.data);
            }
            return Ok(());
        }
        self.pixels.resize(total, 0);
        decoder
            .read_image(&mut self.pixels)
            .map_err(|e| decode_err(path, e))?;
        buf.reshape_packed(w, h, format);
        convert(&self.pixels, layout, &mut buf.data, format);
        Ok(())
    }
}

fn make_reader<'a>(path: &Path, bytes: &'a [u8]) -> Result<ImageReader<Cursor<&'a [u8]>>, IoError> {
    let mut reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| decode_err(path, e))?;
    if reader.format().is_none() {
        match ImageFormat::from_path(path) {
            Ok(f) => reader.set_format(f),
            Err(_) => return Err(decode_err(path, "unknown image format")),
        }
    }
    Ok(reader)
}

fn layout_of(path: &Path, c: ColorType) -> Result<FileLayout, IoError> {
    FileLayout::from_color(c).ok_or_else(|| IoError::WrongFormat {
        path: path.to_path_buf(),
        expected: "grey or RGB, 8 or 16-bit".into(),
        got: format!("{c:?}"),
    })
}

fn target_format(
    path: &Path,
    layout: FileLayout,
    want: Option<PixelFormat>,
) -> Result<PixelFormat, IoError> {
    let Some(want) = want else {
        return Ok(layout.default_format());
    };
    let ok = match want.luma_kind() {
        LumaKind::Rgb => layout.rgb,
        LumaKind::Mono | LumaKind::Bayer => !layout.rgb,
    };
    if ok {
        Ok(want)
    } else {
        Err(IoError::WrongFormat {
            path: path.to_path_buf(),
            expected: want.name().to_string(),
            got: format!("{} image", layout.describe()),
        })
    }
}

#[cfg(target_endian = "little")]
fn ne_to_le_16(_data: &mut [u8]) {}

#[cfg(target_endian = "big")]
fn ne_to_le_16(data: &mut [u8]) {
    for px in data.chunks_exact_mut(2) {
        px.swap(0, 1);
    }
}

/// Converts decoded samples (native-endian 16-bit, interleaved channels) to `format`.
fn convert(src: &[u8], layout: FileLayout, dst: &mut [u8], format: PixelFormat) {
    let in_bps = if layout.bits16 { 2 } else { 1 };
    let in_px = layout.channels * in_bps;
    let out_channels = if format == PixelFormat::Rgb8 { 3 } else { 1 };
    let out_bps = format.bytes_per_pixel() / out_channels;
    let out_px = format.bytes_per_pixel();
    let sample16 = |s: &[u8], c: usize| -> u16 {
        if layout.bits16 {
            u16::from_ne_bytes([s[2 * c], s[2 * c + 1]])
        } else {
            u16::from(s[c]) * 257
        }
    };
    for (s, d) in src.chunks_exact(in_px).zip(dst.chunks_exact_mut(out_px)) {
        for c in 0..out_channels {
            let v = sample16(s, c);
            if out_bps == 2 {
                d[2 * c..2 * c + 2].copy_from_slice(&v.to_le_bytes());
            } else {
                d[c] = ((u32::from(v) * 255 + 32767) / 65535) as u8;
            }
        }
    }
}

/// Decodes one image file into `buf` (see [`ImageDecoderScratch::decode`]). Allocates its
/// scratch memory; for sequences use an [`ImageSequence`] or keep an [`ImageDecoderScratch`].
pub fn decode_image_file(
    path: &Path,
    format: Option<PixelFormat>,
    buf: &mut FrameBuffer,
) -> Result<(), IoError> {
    ImageDecoderScratch::default().decode(path, format, buf)
}

/// A folder (or pattern) of image files read in frame order.
///
/// Frame ids: the number in each file name when every name has a distinct one (files are then
/// read in id order), else the index in name order. Timestamps: from `timestamps.csv` in the
/// folder (columns `frame,timestamp_s`) when present, else `frame id / fps`. Every frame must
/// have the first readable frame's size (or the size given) and format.
#[derive(Debug)]
pub struct ImageSequence {
    name: String,
    files: Vec<(u64, PathBuf)>,
    pos: usize,
    width: usize,
    height: usize,
    format: PixelFormat,
    fps: f64,
    timestamps: Option<HashMap<u64, f64>>,
    scratch: ImageDecoderScratch,
}

impl ImageSequence {
    /// Opens a folder or a pattern (`dir/cam0_*.png`). Fails on a missing folder, a folder
    /// without images, a bad sidecar, or when no file's header can be read.
    pub fn open(input: &Path, options: &ImageSequenceOptions) -> Result<Self, IoError> {
        let files = list_image_files(input)?;
        let folder = if input.is_dir() {
            input.to_path_buf()
        } else {
            input.parent().map(Path::to_path_buf).unwrap_or_default()
        };
        let sidecar = folder.join(TIMESTAMPS_FILE);
        let timestamps = if !options.ignore_sidecar && sidecar.is_file() {
            Some(read_timestamps_csv(&sidecar)?)
        } else {
            None
        };
        Self::from_files(
            input.display().to_string(),
            files,
            options,
            timestamps.map(|t| (sidecar, t)),
        )
    }

    /// A sequence from an explicit list of files (read in the order given, ids by the naming
    /// rule), with optional capture times `(sidecar path, frame id -> seconds)`.
    pub fn from_files(
        name: String,
        files: Vec<PathBuf>,
        options: &ImageSequenceOptions,
        timestamps: Option<(PathBuf, HashMap<u64, f64>)>,
    ) -> Result<Self, IoError> {
        if files.is_empty() {
            return Err(IoError::NoImages { path: name.into() });
        }
        let (ids, from_names) = frame_ids_from_names(&files);
        let mut files: Vec<(u64, PathBuf)> = ids.into_iter().zip(files).collect();
        if from_names {
            files.sort_by_key(|(id, _)| *id);
        }
        let fps = options
            .fps
            .filter(|f| *f > 0.0 && f.is_finite())
            .unwrap_or(DEFAULT_FPS);
        let timestamps = match timestamps {
            Some((path, map)) => {
                if let Some((id, _)) = files.iter().find(|(id, _)| !map.contains_key(id)) {
                    return Err(IoError::Parse {
                        path,
                        line: 0,
                        column: "frame".into(),
                        reason: format!("no timestamp for frame {id}"),
                    });
                }
                Some(map)
            }
            None => None,
        };
        let mut scratch = ImageDecoderScratch::default();
        let mut first_err = None;
        let mut probed = None;
        for (_, path) in &files {
            match scratch.probe(path, options.format) {
                Ok(p) => {
                    probed = Some(p);
                    break;
                }
                Err(e) => {
                    if first_err.is_none() {
                        first_err = Some(e);
                    }
                }
            }
        }
        let (w, h, format) = match (probed, first_err) {
            (Some(p), _) => p,
            (None, Some(e)) => return Err(e),
            (None, None) => return Err(IoError::NoImages { path: name.into() }),
        };
        let (width, height) = options.size.unwrap_or((w, h));
        Ok(ImageSequence {
            name,
            files,
            pos: 0,
            width,
            height,
            format,
            fps,
            timestamps,
            scratch,
        })
    }

    /// The files in reading order with their frame ids.
    pub fn files(&self) -> &[(u64, PathBuf)] {
        &self.files
    }
}

impl FrameSource for ImageSequence {
    fn info(&self) -> SourceInfo {
        SourceInfo {
            name: self.name.clone(),
            width: self.width,
            height: self.height,
            format: self.format,
            fps: Some(self.fps),
            frame_count: Some(self.files.len() as u64),
            live: false,
        }
    }

    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        let Some((id, path)) = self.files.get(self.pos) else {
            return Ok(None);
        };
        self.pos += 1;
        buf.meta.frame_id = *id;
        buf.meta.timestamp_ns = match &self.timestamps {
            Some(map) => Timestamp::from_secs_f64(map.get(id).copied().unwrap_or(0.0)),
            None => Timestamp::from_frame(*id, self.fps),
        };
        self.scratch.decode(path, Some(self.format), buf)?;
        if buf.meta.width != self.width || buf.meta.height != self.height {
            return Err(IoError::WrongSize {
                path: path.clone(),
                expected_width: self.width,
                expected_height: self.height,
                width: buf.meta.width,
                height: buf.meta.height,
            });
        }
        Ok(Some(()))
    }
}
