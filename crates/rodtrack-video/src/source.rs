//! [`VideoSource`]: one video stream of a file, decoded frame by frame.

use crate::convert::{self, ChromaLayout, PackedRgb, Plane};
use ff::format::Pixel;
use ffmpeg_next as ff;
use rodtrack_core::{LumaKind, PixelFormat};
use rodtrack_io::{
    FrameBuffer, FrameSource, InputSpec, IoError, OpenOptions, SourceError, SourceFactory,
    SourceInfo, Timestamp,
};
use std::path::{Path, PathBuf};
use std::sync::Once;

/// After this many decoder errors in a row without a good frame, a source gives up.
const MAX_ERRORS_IN_A_ROW: u32 = 64;

/// How to open a [`VideoSource`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VideoOptions {
    /// How to deliver the frames: for a grey stream `mono8` or a Bayer format stored as grey
    /// (`bayer_rggb8`, ...); for a YUV stream its luma as `mono8` (or a Bayer format, when a
    /// mosaic was encoded as grey) or `rgb8`; for an RGB stream `rgb8` or `mono8` luminance.
    /// `None`: the stream's natural format (grey -> `mono8`, 16-bit grey -> `mono16`, Bayer ->
    /// its Bayer format, YUV -> `mono8`, RGB -> `rgb8`).
    pub format: Option<PixelFormat>,
    /// Frame rate when the stream has none (for frames without a presentation time), or
    /// the rate that [`VideoOptions::retime`] uses (then it wins over the stream's).
    pub fps: Option<f64>,
    /// Ignore the file's presentation times: timestamp = frame id / fps. For a recording whose
    /// file rate is not the capture rate (FFmpeg writes 25 fps unless told otherwise).
    pub retime: bool,
    /// Decoder threads; 0 lets FFmpeg choose (one per core).
    pub threads: usize,
}

/// How the decoded frames are laid out (from the first frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Layout {
    /// One 8-bit plane of samples (grey or a Bayer mosaic).
    Plane8,
    /// One 16-bit plane; true when big-endian.
    Plane16 { big_endian: bool },
    /// 8-bit YUV; `limited`: luma in 16..=235.
    Yuv { chroma: ChromaLayout, limited: bool },
    /// Packed 8-bit RGB family.
    Packed(PackedRgb),
    /// Planar G, B, R.
    Gbrp,
}

/// What a decoded pixel format holds: its layout and its natural rodtrack format.
fn classify(pix: Pixel, range: ff::color::Range) -> Option<(Layout, PixelFormat)> {
    use Pixel as P;
    let planar = |sx, sy| ChromaLayout {
        shift: (sx, sy),
        u: (1, 0, 1),
        v: (2, 0, 1),
    };
    let semi = |u_first: bool| ChromaLayout {
        shift: (1, 1),
        u: (1, usize::from(!u_first), 2),
        v: (1, usize::from(u_first), 2),
    };
    let jpeg = range == ff::color::Range::JPEG;
    let yuv = |chroma, full: bool| {
        Some((
            Layout::Yuv {
                chroma,
                limited: !(full || jpeg),
            },
            PixelFormat::Mono8,
        ))
    };
    let packed = |r, g, b, bytes| {
        Some((
            Layout::Packed(PackedRgb {
                rgb: [r, g, b],
                bytes,
            }),
            PixelFormat::Rgb8,
        ))
    };
    match pix {
        P::GRAY8 => Some((Layout::Plane8, PixelFormat::Mono8)),
        P::BAYER_RGGB8 => Some((Layout::Plane8, PixelFormat::BayerRggb8)),
        P::BAYER_BGGR8 => Some((Layout::Plane8, PixelFormat::BayerBggr8)),
        P::BAYER_GRBG8 => Some((Layout::Plane8, PixelFormat::BayerGrbg8)),
        P::BAYER_GBRG8 => Some((Layout::Plane8, PixelFormat::BayerGbrg8)),
        P::GRAY16LE => Some((Layout::Plane16 { big_endian: false }, PixelFormat::Mono16)),
        P::GRAY16BE => Some((Layout::Plane16 { big_endian: true }, PixelFormat::Mono16)),
        P::BAYER_RGGB16LE => Some((
            Layout::Plane16 { big_endian: false },
            PixelFormat::BayerRggb16,
        )),
        P::BAYER_BGGR16LE => Some((
            Layout::Plane16 { big_endian: false },
            PixelFormat::BayerBggr16,
        )),
        P::BAYER_GRBG16LE => Some((
            Layout::Plane16 { big_endian: false },
            PixelFormat::BayerGrbg16,
        )),
        P::BAYER_GBRG16LE => Some((
            Layout::Plane16 { big_endian: false },
            PixelFormat::BayerGbrg16,
        )),
        P::YUV420P => yuv(planar(1, 1), false),
        P::YUVJ420P => yuv(planar(1, 1), true),
        P::YUV422P => yuv(planar(1, 0), false),
        P::YUVJ422P => yuv(planar(1, 0), true),
        P::YUV444P => yuv(planar(0, 0), false),
        P::YUVJ444P => yuv(planar(0, 0), true),
        P::YUV440P => yuv(planar(0, 1), false),
        P::YUVJ440P => yuv(planar(0, 1), true),
        P::YUV411P => yuv(planar(2, 0), false),
        P::YUVJ411P => yuv(planar(2, 0), true),
        P::YUV410P => yuv(planar(2, 2), false),
        P::YUVA420P => yuv(planar(1, 1), false),
        P::NV12 => yuv(semi(true), false),
        P::NV21 => yuv(semi(false), false),
        P::RGB24 => packed(0, 1, 2, 3),
        P::BGR24 => packed(2, 1, 0, 3),
        P::RGBA | P::RGBZ => packed(0, 1, 2, 4),
        P::BGRA | P::BGRZ => packed(2, 1, 0, 4),
        P::ARGB | P::ZRGB => packed(1, 2, 3, 4),
        P::ABGR | P::ZBGR => packed(3, 2, 1, 4),
        P::GBRP => Some((Layout::Gbrp, PixelFormat::Rgb8)),
        _ => None,
    }
}

/// Whether a stream of `layout` can be delivered as `want`.
fn can_deliver(layout: Layout, want: PixelFormat) -> bool {
    let single8 = want.bytes_per_pixel() == 1 && want.luma_kind() != LumaKind::Rgb;
    match layout {
        Layout::Plane8 => single8,
        Layout::Plane16 { .. } => want.is_16bit(),
        Layout::Yuv { .. } => single8 || want == PixelFormat::Rgb8,
        Layout::Packed(_) | Layout::Gbrp => matches!(want, PixelFormat::Rgb8 | PixelFormat::Mono8),
    }
}

static FFMPEG_INIT: Once = Once::new();

fn init_ffmpeg() {
    FFMPEG_INIT.call_once(|| {
        // Nothing in `init` can fail with FFmpeg >= 5; errors of later calls name the file.
        let _ = ff::init();
        ff::util::log::set_level(ff::util::log::Level::Error);
    });
}

/// One video stream of a file, decoded frame by frame into the caller's buffers.
///
/// - Frame ids count the frames in decoder output order from 0; a packet that fails to decode
///   uses up an id too (it is reported as a bad frame with that id).
/// - Timestamps are the frames' presentation times (`pts * time_base`, ns; negative -> 0),
///   or `frame id / fps` for frames without one or with [`VideoOptions::retime`].
/// - Frames are delivered packed (`stride = width * bytes_per_pixel`): the decoder's padded
///   rows are copied row by row, one copy per frame, allocation-free once `buf` has grown.
/// - A corrupt packet gives a non-fatal error naming the file and frame; the stream goes on.
///   A read error (truncated file) ends the input: the frames still inside the decoder are
///   delivered, then `Ok(None)`.
pub struct VideoSource {
    path: PathBuf,
    input: ff::format::context::Input,
    stream_index: usize,
    decoder: ff::decoder::Video,
    frame: ff::frame::Video,
    packet: ff::Packet,
    time_base: (i64, i64),
    pix: Pixel,
    layout: Layout,
    format: PixelFormat,
    width: usize,
    height: usize,
    fps: Option<f64>,
    frame_count: Option<u64>,
    retime: bool,
    lut: [u8; 256],
    /// `frame` holds a decoded frame not yet delivered (the one decoded at open).
    pending: bool,
    /// End of input sent to the decoder.
    input_done: bool,
    /// Nothing more will come.
    finished: bool,
    next_id: u64,
    errors_in_a_row: u32,
}

impl std::fmt::Debug for VideoSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VideoSource")
            .field("path", &self.path)
            .field("pix", &self.pix)
            .field("format", &self.format)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("next_id", &self.next_id)
            .finish_non_exhaustive()
    }
}

fn decode_err(path: &Path, reason: impl Into<String>) -> IoError {
    IoError::Decode {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

fn valid_rate(r: ff::Rational) -> Option<f64> {
    (r.numerator() > 0 && r.denominator() > 0).then(|| f64::from(r))
}

impl VideoSource {
    /// Opens `path`'s best video stream and decodes its first frame (so that an unreadable
    /// video fails here, with an error naming the file).
    pub fn open(path: &Path, options: &VideoOptions) -> Result<Self, IoError> {
        init_ffmpeg();
        if let Err(e) = std::fs::metadata(path) {
            return Err(IoError::File {
                path: path.to_path_buf(),
                action: "cannot open video",
                source: e,
            });
        }
        let input = ff::format::input(path)
            .map_err(|e| decode_err(path, format!("not a readable video file: {e}")))?;
        let stream = input
            .streams()
            .best(ff::media::Type::Video)
            .ok_or_else(|| decode_err(path, "no video stream"))?;
        let stream_index = stream.index();
        let tb = stream.time_base();
        let given = options.fps.filter(|f| f.is_finite() && *f > 0.0);
        let stream_fps = valid_rate(stream.avg_frame_rate()).or_else(|| valid_rate(stream.rate()));
        let fps = if options.retime {
            given.or(stream_fps)
        } else {
            stream_fps.or(given)
        };
        let frame_count = u64::try_from(stream.frames()).ok().filter(|&n| n > 0);
        let ctx = ff::codec::context::Context::from_parameters(stream.parameters())
            .map_err(|e| decode_err(path, format!("cannot read codec parameters: {e}")))?;
        // Report damaged frames (slice CRCs, bitstream errors) instead of concealing them.
        let mut decoder_options = ff::Dictionary::new();
        decoder_options.set("err_detect", "crccheck+bitstream+buffer+explode");
        // Frame and slice threads (FFmpeg's default kinds), `threads` of them or one per core.
        let threads = match options.threads {
            0 => "auto".to_string(),
            n => n.to_string(),
        };
        decoder_options.set("threads", &threads);
        let codec = ff::decoder::find(ctx.id()).ok_or_else(|| {
            decode_err(
                path,
                format!("no decoder for {:?} in this FFmpeg", ctx.id()),
            )
        })?;
        let decoder = ctx
            .decoder()
            .open_as_with(codec, decoder_options)
            .and_then(|d| d.video())
            .map_err(|e| decode_err(path, format!("no decoder for this video: {e}")))?;
        let mut src = VideoSource {
            path: path.to_path_buf(),
            input,
            stream_index,
            decoder,
            frame: ff::frame::Video::empty(),
            packet: ff::Packet::empty(),
            time_base: (i64::from(tb.numerator()), i64::from(tb.denominator())),
            pix: Pixel::None,
            layout: Layout::Plane8,
            format: PixelFormat::Mono8,
            width: 0,
            height: 0,
            fps,
            frame_count,
            retime: options.retime,
            lut: convert::limited_to_full_lut(),
            pending: false,
            input_done: false,
            finished: false,
            next_id: 0,
            errors_in_a_row: 0,
        };
        match src.decode_next() {
            Ok(true) => {}
            Ok(false) => return Err(decode_err(path, "no frame could be decoded")),
            Err(reason) => return Err(decode_err(path, format!("first frame: {reason}"))),
        }
        src.pix = src.frame.format();
        let (layout, natural) =
            classify(src.pix, src.frame.color_range()).ok_or_else(|| IoError::WrongFormat {
                path: path.to_path_buf(),
                expected: "an 8-bit grey, Bayer, YUV or RGB video (or 16-bit grey/Bayer)".into(),
                got: format!("{:?} video", src.pix),
            })?;
        let format = options.format.unwrap_or(natural);
        if !can_deliver(layout, format) {
            return Err(IoError::WrongFormat {
                path: path.to_path_buf(),
                expected: format.name().to_string(),
                got: format!("{:?} video", src.pix),
            });
        }
        src.layout = layout;
        src.format = format;
        src.width = src.frame.width() as usize;
        src.height = src.frame.height() as usize;
        src.pending = true;
        Ok(src)
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The decoder's pixel format (FFmpeg's name), for messages.
    pub fn stream_pixel_format(&self) -> String {
        format!("{:?}", self.pix)
    }

    /// Decodes the next frame into `self.frame`: `Ok(true)` a frame, `Ok(false)` the end,
    /// `Err(reason)` a packet or frame that did not decode (the stream goes on).
    fn decode_next(&mut self) -> Result<bool, String> {
        loop {
            match self.decoder.receive_frame(&mut self.frame) {
                Ok(()) => return Ok(true),
                Err(ff::Error::Eof) => return Ok(false),
                Err(ff::Error::Other { errno }) if errno == ff::util::error::EAGAIN => {}
                Err(e) => return Err(format!("decoder: {e}")),
            }
            if self.input_done {
                // The decoder wants input it will never get: nothing more will come.
                return Ok(false);
            }
            match self.packet.read(&mut self.input) {
                Ok(()) => {
                    if self.packet.stream() != self.stream_index {
                        continue;
                    }
                    if let Err(e) = self.decoder.send_packet(&self.packet) {
                        return Err(format!("corrupt packet: {e}"));
                    }
                }
                Err(ff::Error::Eof) => {
                    self.input_done = true;
                    let _ = self.decoder.send_eof();
                }
                Err(e) => {
                    // A read error (truncated or damaged file): stop reading, flush the
                    // decoder, report it once.
                    self.input_done = true;
                    let _ = self.decoder.send_eof();
                    return Err(format!("read error (truncated file?): {e}"));
                }
            }
        }
    }

    fn timestamp(&self, id: u64, pts: Option<i64>) -> Timestamp {
        let from_fps = || Timestamp::from_frame(id, self.fps.unwrap_or(0.0));
        if self.retime {
            return from_fps();
        }
        match pts {
            Some(p) if self.time_base.1 > 0 => {
                let ns = i128::from(p.max(0)) * i128::from(self.time_base.0) * 1_000_000_000
                    / i128::from(self.time_base.1);
                Timestamp::from_nanos(u64::try_from(ns).unwrap_or(u64::MAX))
            }
            _ => from_fps(),
        }
    }

    /// Converts `self.frame` into `buf` (packed rows).
    fn convert_into(&self, buf: &mut FrameBuffer) -> Result<(), IoError> {
        let f = &self.frame;
        let (w, h) = (f.width() as usize, f.height() as usize);
        if (w, h) != (self.width, self.height) {
            return Err(IoError::WrongSize {
                path: self.path.clone(),
                expected_width: self.width,
                expected_height: self.height,
                width: w,
                height: h,
            });
        }
        if f.format() != self.pix {
            return Err(IoError::WrongFormat {
                path: self.path.clone(),
                expected: format!("{:?} video", self.pix),
                got: format!("a {:?} frame", f.format()),
            });
        }
        let planes: Vec<Plane<'_>> = (0..f.planes())
            .map(|i| Plane {
                data: f.data(i),
                stride: f.stride(i),
            })
            .collect();
        let plane0 = *planes
            .first()
            .ok_or_else(|| decode_err(&self.path, "decoded frame has no planes"))?;
        buf.reshape_packed(w, h, self.format);
        let mono = self.format.luma_kind() != LumaKind::Rgb;
        let row_bytes = w * self.format.bytes_per_pixel();
        let result = match self.layout {
            Layout::Plane8 => convert::copy_rows(plane0, row_bytes, &mut buf.data),
            Layout::Plane16 { big_endian: false } => {
                convert::copy_rows(plane0, row_bytes, &mut buf.data)
            }
            Layout::Plane16 { big_endian: true } => {
                convert::copy_rows_swap16(plane0, row_bytes, &mut buf.data)
            }
            Layout::Yuv { chroma, limited } => {
                if mono {
                    let lut = limited.then_some(&self.lut);
                    convert::luma_rows(plane0, w, lut, &mut buf.data)
                } else {
                    let bt709 = f.color_space() == ff::color::Space::BT709;
                    convert::yuv_to_rgb_rows(&planes, w, chroma, limited, bt709, &mut buf.data)
                }
            }
            Layout::Packed(p) => convert::packed_rgb_rows(plane0, w, p, mono, &mut buf.data),
            Layout::Gbrp => match planes.as_slice() {
                [g, b, r, ..] => convert::gbrp_rows(*g, *b, *r, w, mono, &mut buf.data),
                _ => Err("gbrp frame without three planes".to_string()),
            },
        };
        result.map_err(|reason| decode_err(&self.path, reason))
    }
}

impl FrameSource for VideoSource {
    fn info(&self) -> SourceInfo {
        SourceInfo {
            name: self.path.display().to_string(),
            width: self.width,
            height: self.height,
            format: self.format,
            fps: self.fps,
            frame_count: self.frame_count,
            live: false,
        }
    }

    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        if self.finished {
            return Ok(None);
        }
        let id = self.next_id;
        let got = if std::mem::take(&mut self.pending) {
            Ok(true)
        } else {
            self.decode_next()
        };
        match got {
            Ok(false) => {
                self.finished = true;
                Ok(None)
            }
            Ok(true) => {
                self.next_id += 1;
                buf.meta.frame_id = id;
                buf.meta.timestamp_ns = self.timestamp(id, self.frame.timestamp());
                if self.frame.is_corrupt() {
                    return Err(decode_err(
                        &self.path,
                        format!("frame {id} decoded with errors (corrupt data)"),
                    ));
                }
                self.convert_into(buf)?;
                self.errors_in_a_row = 0;
                Ok(Some(()))
            }
            Err(reason) => {
                self.next_id += 1;
                self.errors_in_a_row += 1;
                buf.meta.frame_id = id;
                buf.meta.timestamp_ns = self.timestamp(id, None);
                if self.errors_in_a_row > MAX_ERRORS_IN_A_ROW {
                    self.finished = true;
                    return Err(IoError::SourceFailed {
                        name: self.path.display().to_string(),
                        reason: format!(
                            "{MAX_ERRORS_IN_A_ROW} frames in a row did not decode; last: {reason}"
                        ),
                    });
                }
                Err(decode_err(&self.path, format!("frame {id}: {reason}")))
            }
        }
    }
}

/// Opens a parsed `video:FILE?format=..&fps=..&threads=..&timestamps=pts|fps` input; the
/// input's parameters override `options` (format, fps).
pub fn open_input(
    spec: &InputSpec,
    options: &OpenOptions,
) -> Result<Box<dyn FrameSource>, IoError> {
    spec.check_params(&["format", "fps", "threads", "timestamps"])?;
    let retime = match spec.param("timestamps") {
        None | Some("pts") => false,
        Some("fps") => true,
        Some(other) => {
            return Err(IoError::BadInput {
                input: spec.input.clone(),
                reason: format!("parameter `timestamps`: `{other}` is not `pts` or `fps`"),
            })
        }
    };
    let fps: Option<f64> = spec.param_parse("fps")?.or(options.fps);
    if retime && fps.is_none() {
        return Err(IoError::BadInput {
            input: spec.input.clone(),
            reason: "`timestamps=fps` needs `fps`".into(),
        });
    }
    let opts = VideoOptions {
        format: spec.param_format()?.or(options.format),
        fps,
        retime,
        threads: spec.param_parse("threads")?.unwrap_or(0),
    };
    Ok(Box::new(VideoSource::open(Path::new(&spec.target), &opts)?))
}

/// Registers the `video` scheme (`video:FILE?...`, see [`open_input`]).
pub fn register(factory: &mut SourceFactory) {
    factory.register("video", Box::new(open_input));
}
