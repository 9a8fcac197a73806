//! Video files made by the `ffmpeg` tool from frames written here, read back through the
//! `video:` scheme.

#![cfg(feature = "video")]
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{encode, noisy_frames, require_ffmpeg, smooth_frames, TempDir};
use rodtrack_core::PixelFormat;
use rodtrack_io::{FrameBuffer, FrameSource, IoError, OpenOptions, SourceFactory};
use rodtrack_video::{VideoOptions, VideoSource};
use std::path::Path;

fn factory() -> SourceFactory {
    let mut f = SourceFactory::new();
    rodtrack_video::register(&mut f);
    f
}

fn open(input: &str) -> Result<Box<dyn FrameSource>, IoError> {
    factory().open(input, &OpenOptions::default())
}

fn video_input(path: &Path, params: &str) -> String {
    format!("video:{}{params}", path.display())
}

/// Reads every frame (at most `limit` calls): the good frames and the errors.
fn read_all(src: &mut dyn FrameSource, limit: usize) -> (Vec<FrameBuffer>, Vec<IoError>) {
    let mut frames = Vec::new();
    let mut errors = Vec::new();
    for _ in 0..limit {
        let mut buf = FrameBuffer::new();
        match src.next_frame(&mut buf) {
            Ok(Some(())) => frames.push(buf),
            Ok(None) => {
                let mut again = FrameBuffer::new();
                assert!(
                    matches!(src.next_frame(&mut again), Ok(None)),
                    "end is sticky"
                );
                return (frames, errors);
            }
            Err(e) => {
                let fatal = e.is_fatal();
                errors.push(e);
                if fatal {
                    let mut again = FrameBuffer::new();
                    assert!(matches!(src.next_frame(&mut again), Ok(None)));
                    return (frames, errors);
                }
            }
        }
    }
    panic!("no end of stream after {limit} calls");
}

fn max_abs_diff(a: &[u8], b: &[u8]) -> u8 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0)
}

#[test]
fn ffv1_gray8_round_trip_is_bit_exact() {
    require_ffmpeg();
    let dir = TempDir::new("ffv1");
    let (w, h, n) = (64, 48, 12);
    let frames = noisy_frames(w, h, n);
    let path = dir.join("gray.mkv");
    encode(
        &frames,
        w,
        h,
        "gray",
        200,
        &["-c:v", "ffv1", "-level", "3"],
        &path,
    );

    let mut src = open(&video_input(&path, "")).unwrap();
    let info = src.info();
    assert_eq!((info.width, info.height), (w, h));
    assert_eq!(info.format, PixelFormat::Mono8);
    assert_eq!(info.fps, Some(200.0));
    assert!(!info.live);
    let (got, errors) = read_all(&mut *src, 100);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(got.len(), n);
    for (k, (buf, want)) in got.iter().zip(&frames).enumerate() {
        assert_eq!(buf.meta.frame_id, k as u64);
        assert_eq!(buf.meta.timestamp_ns.as_nanos(), k as u64 * 5_000_000);
        assert_eq!(
            (buf.meta.width, buf.meta.height, buf.meta.stride),
            (w, h, w)
        );
        assert_eq!(buf.meta.format, PixelFormat::Mono8);
        assert!(buf.data == *want, "frame {k} differs");
        buf.view().unwrap();
    }
}

#[test]
fn gray8_video_as_bayer_and_retimed() {
    require_ffmpeg();
    let dir = TempDir::new("bayer-gray");
    let (w, h, n) = (64, 48, 4);
    let frames = noisy_frames(w, h, n);
    let path = dir.join("mosaic.nut");
    // FFmpeg's default 25 fps: the real capture rate comes from the input string.
    encode(&frames, w, h, "gray", 25, &["-c:v", "ffv1"], &path);
    let mut src = open(&video_input(
        &path,
        "?format=bayer_rggb8&fps=200&timestamps=fps",
    ))
    .unwrap();
    assert_eq!(src.info().format, PixelFormat::BayerRggb8);
    assert_eq!(src.info().fps, Some(200.0));
    let (got, errors) = read_all(&mut *src, 100);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(got.len(), n);
    for (k, (buf, want)) in got.iter().zip(&frames).enumerate() {
        assert_eq!(buf.meta.format, PixelFormat::BayerRggb8);
        assert_eq!(buf.meta.timestamp_ns.as_nanos(), k as u64 * 5_000_000);
        assert!(buf.data == *want, "frame {k} differs");
    }
    // Without retiming, the file's 25 fps times.
    let mut src = open(&video_input(&path, "?format=bayer_rggb8")).unwrap();
    let (got, _) = read_all(&mut *src, 100);
    assert_eq!(got[1].meta.timestamp_ns.as_nanos(), 40_000_000);
    // A colour format for a grey stream is refused, naming the file.
    let e = open(&video_input(&path, "?format=rgb8")).unwrap_err();
    assert!(matches!(e, IoError::WrongFormat { .. }), "{e}");
    assert!(e.to_string().contains("mosaic.nut"), "{e}");
}

#[test]
fn rawvideo_bayer_in_nut_is_bit_exact() {
    require_ffmpeg();
    let dir = TempDir::new("nut");
    let (w, h, n) = (64, 48, 6);
    let frames = noisy_frames(w, h, n);
    let path = dir.join("bayer.nut");
    encode(
        &frames,
        w,
        h,
        "bayer_rggb8",
        200,
        &["-c:v", "rawvideo", "-pix_fmt", "bayer_rggb8"],
        &path,
    );
    let mut src = open(&video_input(&path, "")).unwrap();
    assert_eq!(src.info().format, PixelFormat::BayerRggb8);
    let (got, errors) = read_all(&mut *src, 100);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(got.len(), n);
    for (k, (buf, want)) in got.iter().zip(&frames).enumerate() {
        assert_eq!(buf.meta.frame_id, k as u64);
        assert!(buf.data == *want, "frame {k} differs");
    }
}

#[test]
fn h264_decodes_with_small_error() {
    require_ffmpeg();
    let dir = TempDir::new("h264");
    let (w, h, n) = (64, 48, 10);
    let frames = smooth_frames(w, h, n);
    // yuv420p (what most H.264 files hold): luma in limited range, expanded back to 0..=255.
    let path = dir.join("x264.mp4");
    encode(
        &frames,
        w,
        h,
        "gray",
        200,
        &[
            "-c:v",
            "libx264",
            "-qp",
            "0",
            "-pix_fmt",
            "yuv420p",
            "-preset",
            "ultrafast",
        ],
        &path,
    );
    let mut src = open(&video_input(&path, "")).unwrap();
    assert_eq!(src.info().format, PixelFormat::Mono8);
    let (got, errors) = read_all(&mut *src, 100);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(got.len(), n);
    for (k, (buf, want)) in got.iter().zip(&frames).enumerate() {
        assert_eq!(buf.meta.frame_id, k as u64);
        let d = max_abs_diff(&buf.data, want);
        assert!(d <= 1, "frame {k}: max error {d}");
    }
    // Monotonic timestamps 5 ms apart.
    for pair in got.windows(2) {
        let dt = pair[1].meta.timestamp_ns.as_nanos() - pair[0].meta.timestamp_ns.as_nanos();
        assert_eq!(dt, 5_000_000);
    }
    // The same as rgb8: grey pixels.
    let mut src = open(&video_input(&path, "?format=rgb8")).unwrap();
    let (got, _) = read_all(&mut *src, 100);
    let buf = &got[3];
    assert_eq!(buf.meta.format, PixelFormat::Rgb8);
    assert_eq!(buf.data.len(), w * h * 3);
    for (px, &want) in buf.data.chunks_exact(3).zip(&frames[3]) {
        for &c in px {
            assert!(c.abs_diff(want) <= 2, "{px:?} vs {want}");
        }
    }

    // Lossy (qp 20, B-frames): small error, and parity with FFmpeg's own grey conversion.
    let path = dir.join("x264-q20.mkv");
    encode(
        &frames,
        w,
        h,
        "gray",
        200,
        &["-c:v", "libx264", "-qp", "20", "-pix_fmt", "yuv420p"],
        &path,
    );
    let mut src = open(&video_input(&path, "")).unwrap();
    let (got, errors) = read_all(&mut *src, 100);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(got.len(), n);
    let reference = dir.join("reference.gray");
    let status = std::process::Command::new("ffmpeg")
        .args(["-y", "-hide_banner", "-loglevel", "error", "-i"])
        .arg(&path)
        .args(["-f", "rawvideo", "-pix_fmt", "gray"])
        .arg(&reference)
        .status()
        .unwrap();
    assert!(status.success());
    let reference = std::fs::read(&reference).unwrap();
    for (k, (buf, want)) in got.iter().zip(&frames).enumerate() {
        let sum: u64 = buf
            .data
            .iter()
            .zip(want)
            .map(|(a, b)| u64::from(a.abs_diff(*b)))
            .sum();
        let mean = sum as f64 / want.len() as f64;
        assert!(mean < 1.0, "frame {k}: mean error {mean}");
        assert!(max_abs_diff(&buf.data, want) <= 6, "frame {k}");
        // swscale's limited -> full range rounds slightly differently: within 1.
        let ffmpeg_frame = &reference[k * w * h..(k + 1) * w * h];
        assert!(
            max_abs_diff(&buf.data, ffmpeg_frame) <= 1,
            "frame {k}: parity"
        );
    }
}

#[test]
fn rgb_video_as_rgb8_and_luminance() {
    require_ffmpeg();
    let dir = TempDir::new("rgb");
    let (w, h, n) = (32, 16, 3);
    let frames = noisy_frames(w * 3, h, n);
    let path = dir.join("rgb.mkv");
    // FFV1 stores rgb24 as bgr0: lossless.
    encode(&frames, w, h, "rgb24", 200, &["-c:v", "ffv1"], &path);
    let mut src = open(&video_input(&path, "")).unwrap();
    assert_eq!(src.info().format, PixelFormat::Rgb8);
    let (got, errors) = read_all(&mut *src, 100);
    assert!(errors.is_empty(), "{errors:?}");
    for (buf, want) in got.iter().zip(&frames) {
        assert!(buf.data == *want);
    }
    let mut src = open(&video_input(&path, "?format=mono8")).unwrap();
    let (got, _) = read_all(&mut *src, 100);
    for (buf, want) in got.iter().zip(&frames) {
        for (&l, p) in buf.data.iter().zip(want.chunks_exact(3)) {
            let exact = (f64::from(p[0]) + 2.0 * f64::from(p[1]) + f64::from(p[2])) / 4.0;
            assert!((f64::from(l) - exact).abs() <= 0.5);
        }
    }
    let e = open(&video_input(&path, "?format=bayer_rggb8")).unwrap_err();
    assert!(matches!(e, IoError::WrongFormat { .. }), "{e}");
}

#[test]
fn full_size_ffv1_with_padded_rows_is_bit_exact() {
    require_ffmpeg();
    let dir = TempDir::new("fullsize");
    let (w, h, n) = (1440, 1080, 3);
    let frames = noisy_frames(w, h, n);
    let path = dir.join("full.mkv");
    encode(
        &frames,
        w,
        h,
        "gray",
        200,
        &["-c:v", "ffv1", "-level", "3", "-slices", "4"],
        &path,
    );
    let mut src = VideoSource::open(&path, &VideoOptions::default()).unwrap();
    let mut buf = FrameBuffer::new();
    for (k, want) in frames.iter().enumerate() {
        src.next_frame(&mut buf).unwrap().unwrap();
        assert_eq!(buf.meta.stride, w, "delivered packed");
        assert_eq!(buf.data.len(), w * h);
        assert!(buf.data == *want, "frame {k} differs");
        assert_eq!(buf.row(h - 1).unwrap(), &want[(h - 1) * w..]);
    }
    assert!(src.next_frame(&mut buf).unwrap().is_none());
}

#[test]
fn truncated_video_gives_its_frames_then_ends() {
    require_ffmpeg();
    let dir = TempDir::new("truncated");
    let (w, h, n) = (64, 48, 20);
    let frames = noisy_frames(w, h, n);
    for ext in ["nut", "mkv"] {
        let full = dir.join(&format!("full.{ext}"));
        encode(
            &frames,
            w,
            h,
            "gray",
            200,
            &["-c:v", "ffv1", "-level", "3", "-slicecrc", "1"],
            &full,
        );
        let bytes = std::fs::read(&full).unwrap();
        let cut = dir.join(&format!("cut.{ext}"));
        std::fs::write(&cut, &bytes[..bytes.len() * 55 / 100]).unwrap();

        let mut src = open(&video_input(&cut, "")).unwrap();
        let (got, errors) = read_all(&mut *src, 200);
        assert!(
            got.len() >= 5 && got.len() < n,
            "{ext}: {} frames",
            got.len()
        );
        for buf in &got {
            let k = buf.meta.frame_id as usize;
            assert!(buf.data == frames[k], "{ext}: frame {k} differs");
        }
        for e in &errors {
            assert!(
                e.to_string().contains("cut."),
                "{ext}: error without the file: {e}"
            );
        }
        eprintln!("{ext}: {} of {n} frames, errors: {errors:?}", got.len());

        // Cut inside the header: an error at open that names the file.
        let head = dir.join(&format!("head.{ext}"));
        std::fs::write(&head, &bytes[..40.min(bytes.len())]).unwrap();
        let e = open(&video_input(&head, "")).unwrap_err();
        assert!(e.to_string().contains("head."), "{e}");
    }
}

#[test]
fn corrupt_data_does_not_end_the_stream() {
    // FFmpeg 5.1's FFV1 decoder conceals a slice whose CRC fails (it logs "slice CRC
    // mismatch" and copies the previous frame's slice) without flagging the frame, so the
    // damaged frames cannot all be reported; what must hold: the stream goes on to its end,
    // errors are not fatal and name the file, and the undamaged frames are exact.
    require_ffmpeg();
    let dir = TempDir::new("corrupt");
    let (w, h, n) = (64, 48, 20);
    let frames = noisy_frames(w, h, n);
    let full = dir.join("full.nut");
    encode(
        &frames,
        w,
        h,
        "gray",
        200,
        &["-c:v", "ffv1", "-level", "3", "-slicecrc", "1"],
        &full,
    );
    let mut bytes = std::fs::read(&full).unwrap();
    // Damage bytes in the middle of the file (inside frame data).
    let mid = bytes.len() / 2;
    for b in &mut bytes[mid..mid + 64] {
        *b ^= 0x5a;
    }
    let bad = dir.join("bad.nut");
    std::fs::write(&bad, &bytes).unwrap();
    let mut src = open(&video_input(&bad, "")).unwrap();
    let (got, errors) = read_all(&mut *src, 200);
    let mut exact = 0;
    for buf in &got {
        let k = buf.meta.frame_id as usize;
        if k < n && buf.data == frames[k] {
            exact += 1;
        }
    }
    assert!(exact >= n - 4, "{exact} exact frames of {n}");
    for e in &errors {
        assert!(!e.is_fatal(), "{e}");
        assert!(e.to_string().contains("bad.nut"), "{e}");
    }
    let ids: Vec<u64> = got.iter().map(|b| b.meta.frame_id).collect();
    eprintln!(
        "{} frames, {exact} exact, ids {ids:?}, errors: {errors:?}",
        got.len()
    );
}

#[test]
fn non_video_files_fail_at_open_naming_the_file() {
    let dir = TempDir::new("notvideo");
    // Bytes that no demuxer recognises.
    let junk = dir.join("junk.mkv");
    let bytes: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 7) as u8)
        .collect();
    std::fs::write(&junk, bytes).unwrap();
    let e = open(&video_input(&junk, "")).unwrap_err();
    assert!(matches!(e, IoError::Decode { .. }), "{e}");
    assert!(e.to_string().contains("junk.mkv"), "{e}");
    // FFmpeg reads a text file as ANSI art (a pal8 "video"): refused, naming the file.
    let text = dir.join("notes.txt");
    std::fs::write(&text, "this is not a video\n".repeat(100)).unwrap();
    let e = open(&video_input(&text, "")).unwrap_err();
    assert!(e.to_string().contains("notes.txt"), "{e}");

    let missing = dir.join("missing.mkv");
    let e = open(&video_input(&missing, "")).unwrap_err();
    assert!(matches!(e, IoError::File { .. }), "{e}");
    assert!(e.to_string().contains("missing.mkv"), "{e}");

    let e = open(&format!("video:{}?bogus=1", text.display())).unwrap_err();
    assert!(matches!(e, IoError::BadInput { .. }), "{e}");
    let e = open(&format!("video:{}?timestamps=fps", text.display())).unwrap_err();
    assert!(e.to_string().contains("needs `fps`"), "{e}");
}

#[test]
fn audio_only_file_has_no_video_stream() {
    require_ffmpeg();
    let dir = TempDir::new("audio");
    let path = dir.join("tone.wav");
    let status = std::process::Command::new("ffmpeg")
        .args([
            "-y",
            "-hide_banner",
            "-loglevel",
            "error",
            "-f",
            "lavfi",
            "-i",
        ])
        .arg("sine=frequency=440:duration=0.1")
        .arg(&path)
        .status()
        .unwrap();
    assert!(status.success());
    let e = open(&video_input(&path, "")).unwrap_err();
    assert!(e.to_string().contains("no video stream"), "{e}");
    assert!(e.to_string().contains("tone.wav"), "{e}");
}
