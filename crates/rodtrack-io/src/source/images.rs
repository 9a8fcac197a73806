//! Image sequences: a folder (or pattern) of PNG, PGM/PPM or TIFF files.

use super::naming::{list_image_files_noting, number_frames, TIMESTAMPS_FILE};
use super::timestamps::{read_capped_into, read_timestamps_csv_noting};
use super::{FrameSource, SourceInfo, DEFAULT_FPS};
use crate::frame::{FrameBuffer, Timestamp};
use crate::{IoError, SourceError};
use image::{ColorType, ImageDecoder, ImageFormat, ImageReader};
use rodtrack_core::{LumaKind, PixelFormat};
use std::collections::HashMap;
use std::io::Cursor;
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

/// The most pixels an image file may claim when no frame size is expected (8 Mpx: 3840x2160
/// fits; cameras here have 1.6 Mpx). With an expected size, exactly that size is read.
pub const DEFAULT_MAX_PIXELS: usize = 8 << 20;

/// The most bytes per pixel any accepted file layout decodes to (RGBA 16-bit).
const MAX_DECODED_BYTES_PER_PIXEL: usize = 8;

/// Slack over the decoded size for a file's headers, metadata and compression overhead.
const FILE_MARGIN_BYTES: u64 = 1 << 20;

/// The longest image file read for a frame of `pixels` pixels: its largest uncompressed
/// layout (RGBA 16-bit) plus `FILE_MARGIN_BYTES` (1 MiB). Longer files are refused unread.
pub fn max_image_file_bytes(pixels: usize) -> u64 {
    (pixels as u64)
        .saturating_mul(MAX_DECODED_BYTES_PER_PIXEL as u64)
        .saturating_add(FILE_MARGIN_BYTES)
}

/// Reusable memory for decoding image files (file bytes and a conversion buffer), and the
/// frame size expected, which bounds every allocation: a file longer than
/// [`max_image_file_bytes`] is not read, and a header claiming another size is refused before
/// any pixel is decoded.
#[derive(Debug, Default)]
pub struct ImageDecoderScratch {
    file: Vec<u8>,
    pixels: Vec<u8>,
    expect: Option<(usize, usize)>,
}

fn decode_err(path: &Path, e: impl std::fmt::Display) -> IoError {
    IoError::Decode {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

impl ImageDecoderScratch {
    /// Scratch memory for frames of `size` (`None`: any size up to [`DEFAULT_MAX_PIXELS`]).
    pub fn expecting(size: Option<(usize, usize)>) -> Self {
        ImageDecoderScratch {
            expect: size,
            ..Default::default()
        }
    }

    /// The most pixels a file may hold.
    fn max_pixels(&self) -> usize {
        match self.expect {
            Some((w, h)) => w.saturating_mul(h),
            None => DEFAULT_MAX_PIXELS,
        }
    }

    fn load(&mut self, path: &Path) -> Result<(), IoError> {
        let max = max_image_file_bytes(self.max_pixels());
        read_capped_into(path, max, &mut self.file)
    }

    /// Reads only the header: `(width, height, format the file would be read as)`.
    fn probe(
        &mut self,
        path: &Path,
        want: Option<PixelFormat>,
    ) -> Result<(usize, usize, PixelFormat), IoError> {
        self.load(path)?;
        let decoder = make_reader(path, &self.file, self.max_pixels())?
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
        let result = self.decode_bytes(path, &file, want, buf);
        self.file = file;
        result
    }

    /// Like [`ImageDecoderScratch::decode`] for a file already in memory (`path` names it in
    /// errors and gives its format when the bytes do not). The header is read first: a size
    /// other than the expected one (or over [`DEFAULT_MAX_PIXELS`]) is refused before any
    /// allocation sized by it.
    pub fn decode_bytes(
        &mut self,
        path: &Path,
        file: &[u8],
        want: Option<PixelFormat>,
        buf: &mut FrameBuffer,
    ) -> Result<(), IoError> {
        let max_pixels = self.max_pixels();
        let decoder = make_reader(path, file, max_pixels)?
            .into_decoder()
            .map_err(|e| decode_err(path, e))?;
        let (w, h) = decoder.dimensions();
        let (w, h) = (w as usize, h as usize);
        if w == 0 || h == 0 {
            return Err(decode_err(path, format!("empty image ({w}x{h})")));
        }
        match self.expect {
            Some((ew, eh)) if (w, h) != (ew, eh) => {
                return Err(IoError::WrongSize {
                    path: path.to_path_buf(),
                    expected_width: ew,
                    expected_height: eh,
                    width: w,
                    height: h,
                })
            }
            None if w.saturating_mul(h) > max_pixels => {
                return Err(decode_err(
                    path,
                    format!("image size {w}x{h} is over the limit of {max_pixels} pixels"),
                ))
            }
            _ => {}
        }
        let layout = layout_of(path, decoder.color_type())?;
        let format = target_format(path, layout, want)?;
        let direct = layout.channels == if format == PixelFormat::Rgb8 { 3 } else { 1 }
            && layout.bits16 == format.is_16bit();
        let max_bytes = max_pixels.saturating_mul(MAX_DECODED_BYTES_PER_PIXEL);
        let total = usize::try_from(decoder.total_bytes())
            .ok()
            .filter(|t| *t <= max_bytes)
            .ok_or_else(|| decode_err(path, "image too large"))?;
        if direct {
            buf.try_reshape_packed(w, h, format, max_bytes)?;
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
        buf.try_reshape_packed(w, h, format, max_bytes)?;
        convert(&self.pixels, layout, &mut buf.data, format);
        Ok(())
    }
}

/// A reader whose decoder may allocate at most what a frame of `max_pixels` needs (plus the
/// file's length, for decoders that buffer compressed data).
fn make_reader<'a>(
    path: &Path,
    bytes: &'a [u8],
    max_pixels: usize,
) -> Result<ImageReader<Cursor<&'a [u8]>>, IoError> {
    let mut reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| decode_err(path, e))?;
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(
        (max_pixels as u64)
            .saturating_mul(MAX_DECODED_BYTES_PER_PIXEL as u64)
            .saturating_add(bytes.len() as u64)
            .saturating_add(FILE_MARGIN_BYTES),
    );
    reader.limits(limits);
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
/// Frame ids: the number in each file name (files are then read in id order; files without a
/// number beside numbered ones are left out with a warning), else the index in name order
/// (see [`number_frames`]). Paths that are not regular files are left out with a warning. Timestamps: from `timestamps.csv` in the
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
    warnings: Vec<String>,
}

impl ImageSequence {
    /// Opens a folder or a pattern (`dir/cam0_*.png`). Fails on a missing folder, a folder
    /// without images, a bad sidecar, or when no file's header can be read.
    pub fn open(input: &Path, options: &ImageSequenceOptions) -> Result<Self, IoError> {
        let mut warnings = Vec::new();
        let files = list_image_files_noting(input, &mut warnings)?;
        let folder = if input.is_dir() {
            input.to_path_buf()
        } else {
            input.parent().map(Path::to_path_buf).unwrap_or_default()
        };
        let sidecar = folder.join(TIMESTAMPS_FILE);
        let timestamps = if !options.ignore_sidecar && sidecar.symlink_metadata().is_ok() {
            Some(read_timestamps_csv_noting(&sidecar, &mut warnings)?)
        } else {
            None
        };
        let mut seq = Self::from_files(
            input.display().to_string(),
            files,
            options,
            timestamps.map(|t| (sidecar, t)),
        )?;
        warnings.append(&mut seq.warnings);
        seq.warnings = warnings;
        Ok(seq)
    }

    /// A sequence from an explicit list of files (read in the order given, ids by the naming
    /// rule, see [`number_frames`]), with optional capture times `(sidecar path, frame id ->
    /// seconds)`.
    pub fn from_files(
        name: String,
        files: Vec<PathBuf>,
        options: &ImageSequenceOptions,
        timestamps: Option<(PathBuf, HashMap<u64, f64>)>,
    ) -> Result<Self, IoError> {
        if files.is_empty() {
            return Err(IoError::NoImages { path: name.into() });
        }
        let (files, warnings) = number_frames(files);
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
        let mut scratch = ImageDecoderScratch::expecting(options.size);
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
        scratch.expect = Some((width, height));
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
            warnings,
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

    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
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
