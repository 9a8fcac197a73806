//! Frame sources on real files written to a temporary folder.
#![allow(clippy::unwrap_used, missing_docs)]

use image::{ImageBuffer, Luma, Rgb};
use rodtrack_core::PixelFormat;
use rodtrack_io::source::{list_image_files, ImageSequenceOptions, RawOptions};
use rodtrack_io::{
    FrameBuffer, FrameSource, ImageSequence, IoError, OpenOptions, RawSource, SourceFactory,
};
use std::path::{Path, PathBuf};

/// A fresh, empty temporary folder for one test.
fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rodtrack-io-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn pix8(x: u32, y: u32, k: u32) -> u8 {
    ((x * 7 + y * 13 + k * 31) % 251) as u8
}
fn pix16(x: u32, y: u32, k: u32) -> u16 {
    ((x * 1009 + y * 9973 + k * 333) % 65521) as u16
}

fn write_gray8(path: &Path, w: u32, h: u32, k: u32) {
    ImageBuffer::<Luma<u8>, Vec<u8>>::from_fn(w, h, |x, y| Luma([pix8(x, y, k)]))
        .save(path)
        .unwrap();
}
fn write_gray16(path: &Path, w: u32, h: u32, k: u32) {
    ImageBuffer::<Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| Luma([pix16(x, y, k)]))
        .save(path)
        .unwrap();
}
fn write_rgb8(path: &Path, w: u32, h: u32) {
    ImageBuffer::<Rgb<u8>, Vec<u8>>::from_fn(w, h, |x, y| Rgb([x as u8, y as u8, 77]))
        .save(path)
        .unwrap();
}

fn open(dir: &Path, format: Option<PixelFormat>) -> ImageSequence {
    let opts = ImageSequenceOptions {
        format,
        fps: Some(100.0),
        ..Default::default()
    };
    ImageSequence::open(dir, &opts).unwrap()
}

#[test]
fn round_trips_8_and_16_bit_png_pgm_tiff() {
    for ext in ["png", "pgm", "tiff"] {
        for bits in [8, 16] {
            let dir = tmpdir(&format!("rt-{ext}-{bits}"));
            let (w, h) = (13u32, 7u32);
            for k in 0..3 {
                let p = dir.join(format!("{:06}.{ext}", 40 + k));
                if bits == 8 {
                    write_gray8(&p, w, h, k);
                } else {
                    write_gray16(&p, w, h, k);
                }
            }
            let mut seq = open(&dir, None);
            let info = seq.info();
            let fmt = if bits == 8 {
                PixelFormat::Mono8
            } else {
                PixelFormat::Mono16
            };
            assert_eq!(
                (info.width, info.height, info.format),
                (13, 7, fmt),
                "{ext} {bits}"
            );
            assert_eq!(info.frame_count, Some(3));
            let mut buf = FrameBuffer::new();
            for k in 0..3u32 {
                seq.next_frame(&mut buf).unwrap().unwrap();
                assert_eq!(buf.meta.frame_id, 40 + u64::from(k));
                assert_eq!(
                    buf.meta.timestamp_ns.as_nanos(),
                    (40 + u64::from(k)) * 10_000_000
                );
                assert_eq!(buf.meta.format, fmt);
                for (x, y) in [(0u32, 0u32), (12, 6), (5, 3)] {
                    let v = buf.view().unwrap();
                    let off = y as usize * buf.meta.stride + x as usize * fmt.bytes_per_pixel();
                    if bits == 8 {
                        assert_eq!(buf.data[off], pix8(x, y, k), "{ext}");
                        assert_eq!(
                            v.luma_node(x as isize, y as isize),
                            f32::from(pix8(x, y, k))
                        );
                    } else {
                        let got = u16::from_le_bytes([buf.data[off], buf.data[off + 1]]);
                        assert_eq!(got, pix16(x, y, k), "{ext}");
                    }
                }
            }
            assert!(seq.next_frame(&mut buf).unwrap().is_none());
            assert!(seq.next_frame(&mut buf).unwrap().is_none());
        }
    }
}

#[test]
fn sixteen_bit_converts_to_eight_and_bayer_is_kept_as_given() {
    let dir = tmpdir("conv");
    write_gray16(&dir.join("000001.png"), 8, 6, 0);
    write_gray8(&dir.join("000002.png"), 8, 6, 1);
    let mut seq = open(&dir, Some(PixelFormat::BayerRggb8));
    assert_eq!(seq.info().format, PixelFormat::BayerRggb8);
    let mut buf = FrameBuffer::new();
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.format, PixelFormat::BayerRggb8);
    let want = ((u32::from(pix16(3, 2, 0)) * 255 + 32767) / 65535) as u8;
    assert_eq!(buf.data[2 * 8 + 3], want);
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.data[2 * 8 + 3], pix8(3, 2, 1));

    // An 8-bit file in a mono16 sequence is widened.
    let mut seq = open(&dir, Some(PixelFormat::Mono16));
    seq.next_frame(&mut buf).unwrap().unwrap();
    seq.next_frame(&mut buf).unwrap().unwrap();
    let off = 2 * 16 + 3 * 2;
    assert_eq!(
        u16::from_le_bytes([buf.data[off], buf.data[off + 1]]),
        u16::from(pix8(3, 2, 1)) * 257
    );
}

#[test]
fn rgb_images_read_as_rgb8() {
    let dir = tmpdir("rgb");
    write_rgb8(&dir.join("a.png"), 5, 4);
    ImageBuffer::<Rgb<u16>, Vec<u16>>::from_fn(5, 4, |x, _| Rgb([x as u16 * 257, 0, 65535]))
        .save(dir.join("b.png"))
        .unwrap();
    let mut seq = open(&dir, None);
    assert_eq!(seq.info().format, PixelFormat::Rgb8);
    let mut buf = FrameBuffer::new();
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.frame_id, 0, "names without numbers: index order");
    assert_eq!(&buf.data[(3 * 5 + 2) * 3..][..3], &[2, 3, 77]);
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.frame_id, 1);
    assert_eq!(&buf.data[4 * 3..][..3], &[4, 0, 255]);
}

#[test]
fn frame_ids_from_names_or_index_and_numeric_order() {
    let dir = tmpdir("ids");
    for n in [2, 10, 1] {
        write_gray8(&dir.join(format!("f{n}.pgm")), 4, 4, n);
    }
    let mut seq = open(&dir, None);
    let mut buf = FrameBuffer::new();
    let mut ids = Vec::new();
    while seq.next_frame(&mut buf).unwrap().is_some() {
        ids.push(buf.meta.frame_id);
        assert_eq!(buf.data[0], pix8(0, 0, buf.meta.frame_id as u32));
    }
    assert_eq!(ids, [1, 2, 10]);

    // One stray file without a number does not renumber the others: it is left out, with a
    // warning naming it.
    write_gray8(&dir.join("extra.pgm"), 4, 4, 0);
    let seq = open(&dir, None);
    let ids: Vec<u64> = seq.files().iter().map(|(id, _)| *id).collect();
    assert_eq!(ids, [1, 2, 10]);
    let w = seq.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("extra.pgm") && w[0].contains("left out"),
        "{w:?}"
    );

    // Two files sharing a number: every file by its index in name order, with a warning.
    write_gray8(&dir.join("g2.pgm"), 4, 4, 0);
    std::fs::remove_file(dir.join("extra.pgm")).unwrap();
    let seq = open(&dir, None);
    let ids: Vec<u64> = seq.files().iter().map(|(id, _)| *id).collect();
    assert_eq!(ids, [0, 1, 2, 3]);
    // Name order: f1, f10, f2, g2.
    assert!(seq.files()[1].1.ends_with("f10.pgm"));
    assert!(
        seq.warnings()[0].contains("share a frame number"),
        "{:?}",
        seq.warnings()
    );
}

#[test]
fn sidecar_timestamps_are_used() {
    let dir = tmpdir("sidecar");
    write_gray8(&dir.join("000005.png"), 4, 4, 0);
    write_gray8(&dir.join("000006.png"), 4, 4, 1);
    std::fs::write(
        dir.join("timestamps.csv"),
        "frame,timestamp_s\n5,1.25\n6,1.2551\n",
    )
    .unwrap();
    let mut seq = open(&dir, None);
    let mut buf = FrameBuffer::new();
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.timestamp_ns.as_nanos(), 1_250_000_000);
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.timestamp_ns.as_nanos(), 1_255_100_000);

    std::fs::write(dir.join("timestamps.csv"), "frame,timestamp_s\n5,1.25\n").unwrap();
    let e = ImageSequence::open(&dir, &ImageSequenceOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("timestamps.csv") && e.to_string().contains("frame 6"),
        "{e}"
    );
}

fn expect_err_naming(r: Result<Option<()>, IoError>, file: &str, what: &str) {
    let e = r.unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains(file), "`{msg}` should name {file}");
    assert!(msg.contains(what), "`{msg}` should say {what}");
    assert!(!e.is_fatal());
}

#[test]
fn bad_frames_are_reported_and_the_sequence_continues() {
    let dir = tmpdir("bad");
    let (w, h) = (16, 12);
    write_gray8(&dir.join("000000.png"), w, h, 0);
    std::fs::write(
        dir.join("000001.png"),
        b"\x89PNG\r\n\x1a\nthis is not a png at all",
    )
    .unwrap();
    write_gray8(&dir.join("000002.png"), w, h, 2);
    // Truncated: the first half of a valid PNG.
    let good = std::fs::read(dir.join("000002.png")).unwrap();
    std::fs::write(dir.join("000003.png"), &good[..good.len() / 2]).unwrap();
    write_gray8(&dir.join("000004.png"), w + 2, h, 4); // wrong size
    write_rgb8(&dir.join("000005.png"), w, h); // RGB in a mono sequence
    std::fs::write(dir.join("000006.pgm"), b"P5\n16 12\n255\nshort").unwrap(); // truncated PGM
    write_gray8(&dir.join("000007.png"), w, h, 7);

    let mut seq = open(&dir, Some(PixelFormat::Mono8));
    let mut buf = FrameBuffer::new();
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.frame_id, 0);
    expect_err_naming(seq.next_frame(&mut buf), "000001.png", "cannot decode");
    assert_eq!(buf.meta.frame_id, 1, "a bad frame still reports its id");
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!((buf.meta.frame_id, buf.data[5]), (2, pix8(5, 0, 2)));
    expect_err_naming(seq.next_frame(&mut buf), "000003.png", "cannot decode");
    expect_err_naming(
        seq.next_frame(&mut buf),
        "000004.png",
        "expected 16x12, got 18x12",
    );
    expect_err_naming(
        seq.next_frame(&mut buf),
        "000005.png",
        "expected mono8, got RGB 8-bit",
    );
    expect_err_naming(seq.next_frame(&mut buf), "000006.pgm", "cannot decode");
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.frame_id, 7);
    assert!(seq.next_frame(&mut buf).unwrap().is_none());
}

#[test]
fn a_bad_first_frame_does_not_prevent_opening() {
    let dir = tmpdir("badfirst");
    std::fs::write(dir.join("000000.png"), b"garbage").unwrap();
    write_gray8(&dir.join("000001.png"), 6, 5, 1);
    let mut seq = open(&dir, None);
    assert_eq!((seq.info().width, seq.info().height), (6, 5));
    let mut buf = FrameBuffer::new();
    assert!(seq.next_frame(&mut buf).is_err());
    assert!(seq.next_frame(&mut buf).unwrap().is_some());
}

#[test]
fn missing_and_empty_folders() {
    let dir = tmpdir("missing");
    let gone = dir.join("nope");
    let e = ImageSequence::open(&gone, &ImageSequenceOptions::default()).unwrap_err();
    assert!(matches!(e, IoError::MissingFolder { .. }) && e.is_fatal());
    assert!(e.to_string().contains("nope"), "{e}");
    std::fs::write(dir.join("notes.txt"), "x").unwrap();
    let e = ImageSequence::open(&dir, &ImageSequenceOptions::default()).unwrap_err();
    assert!(matches!(e, IoError::NoImages { .. }), "{e}");
    assert!(e.to_string().contains("no image files"), "{e}");
}

#[test]
fn glob_patterns_select_files() {
    let dir = tmpdir("glob");
    write_gray8(&dir.join("cam0_000001.png"), 4, 4, 0);
    write_gray8(&dir.join("cam0_000002.png"), 4, 4, 0);
    write_gray8(&dir.join("cam1_000001.png"), 4, 4, 0);
    let files = list_image_files(&dir.join("cam0_*.png")).unwrap();
    assert_eq!(files.len(), 2);
    let src = SourceFactory::new()
        .open(
            &format!("{}/cam1_*.png", dir.display()),
            &OpenOptions::default(),
        )
        .unwrap();
    assert_eq!(src.info().frame_count, Some(1));
}

#[test]
fn decoding_reuses_the_buffer() {
    let dir = tmpdir("reuse");
    for k in 0..5 {
        write_gray8(&dir.join(format!("{k:03}.pgm")), 32, 24, k);
    }
    let mut seq = open(&dir, None);
    let mut buf = FrameBuffer::new();
    seq.next_frame(&mut buf).unwrap().unwrap();
    let ptr = buf.data.as_ptr();
    while seq.next_frame(&mut buf).unwrap().is_some() {
        assert_eq!(buf.data.as_ptr(), ptr);
    }
}

fn raw_frames(w: usize, h: usize, stride: usize, n: usize) -> Vec<u8> {
    let mut v = Vec::new();
    for k in 0..n {
        for y in 0..h {
            for x in 0..stride {
                v.push(if x < w {
                    (k * 50 + y * 10 + x) as u8
                } else {
                    0xEE
                });
            }
        }
    }
    v
}

#[test]
fn raw_file_with_padded_stride_and_truncated_tail() {
    let dir = tmpdir("raw");
    let (w, h, stride) = (6usize, 4usize, 9usize);
    let mut bytes = raw_frames(w, h, stride, 3);
    bytes.extend_from_slice(&[1, 2, 3, 4, 5]); // 5 bytes of a 4th frame
    let path = dir.join("cam0.raw");
    std::fs::write(&path, &bytes).unwrap();
    let src = SourceFactory::new()
        .open(
            &format!(
                "raw:{}?width=6&height=4&stride=9&format=bayer_rggb8&fps=50",
                path.display()
            ),
            &OpenOptions::default(),
        )
        .unwrap();
    let mut src = src;
    let info = src.info();
    assert_eq!(
        (info.width, info.height, info.format),
        (6, 4, PixelFormat::BayerRggb8)
    );
    assert_eq!(info.frame_count, Some(3));
    let mut buf = FrameBuffer::new();
    for k in 0..3u64 {
        src.next_frame(&mut buf).unwrap().unwrap();
        assert_eq!(buf.meta.frame_id, k);
        assert_eq!(buf.meta.timestamp_ns.as_nanos(), k * 20_000_000);
        assert_eq!(buf.meta.stride, 9);
        assert_eq!(
            buf.row(3).unwrap(),
            &[
                k as u8 * 50 + 30,
                k as u8 * 50 + 31,
                k as u8 * 50 + 32,
                k as u8 * 50 + 33,
                k as u8 * 50 + 34,
                k as u8 * 50 + 35
            ]
        );
        // The view skips the padding: the 2x2 block at (4, 2) holds 24, 25, 34, 35 (+ 50k).
        let v = buf.view().unwrap();
        let want = (24.0 + 25.0 + 34.0 + 35.0) / 4.0 + 50.0 * k as f32;
        assert_eq!(v.luma_node(4, 2), want);
    }
    let e = src.next_frame(&mut buf).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("cam0.raw") && msg.contains("expected 36 bytes, got 5"),
        "{msg}"
    );
    assert!(src.next_frame(&mut buf).unwrap().is_none());
}

#[test]
fn raw_folder_with_a_short_file() {
    let dir = tmpdir("rawdir");
    let one = raw_frames(4, 4, 4, 1);
    std::fs::write(dir.join("000010.raw"), &one).unwrap();
    std::fs::write(dir.join("000011.raw"), &one[..10]).unwrap();
    std::fs::write(dir.join("000012.raw"), &one).unwrap();
    let mut src = RawSource::open(&dir, RawOptions::new(4, 4, PixelFormat::Mono8)).unwrap();
    let mut buf = FrameBuffer::new();
    src.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.frame_id, 10);
    let e = src.next_frame(&mut buf).unwrap_err().to_string();
    assert!(
        e.contains("000011.raw") && e.contains("expected 16 bytes, got 10"),
        "{e}"
    );
    src.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.frame_id, 12);
    assert!(src.next_frame(&mut buf).unwrap().is_none());
}

#[test]
fn raw_input_errors() {
    let f = SourceFactory::new();
    let o = OpenOptions::default();
    let e = f
        .open("raw:/nonexistent/x.raw?width=4&height=4&format=mono8", &o)
        .unwrap_err();
    assert!(e.to_string().contains("/nonexistent/x.raw"), "{e}");
    let e = f.open("raw:x.raw?width=4&height=4", &o).unwrap_err();
    assert!(e.to_string().contains("format"), "{e}");
    // Defaults from the command line fill in.
    let dir = tmpdir("rawdefaults");
    let p = dir.join("a.raw");
    std::fs::write(&p, raw_frames(4, 4, 4, 2)).unwrap();
    let o = OpenOptions {
        format: Some(PixelFormat::Mono8),
        fps: None,
        size: Some((4, 4)),
    };
    let s = f.open(&format!("raw:{}", p.display()), &o).unwrap();
    assert_eq!(s.info().frame_count, Some(2));
}

#[cfg(unix)]
#[test]
fn an_unreadable_file_is_named_and_skipped() {
    let dir = tmpdir("unreadable");
    write_gray8(&dir.join("000000.png"), 4, 4, 0);
    std::os::unix::fs::symlink("/nonexistent/target.png", dir.join("000001.png")).unwrap();
    write_gray8(&dir.join("000002.png"), 4, 4, 2);
    let mut seq = open(&dir, None);
    let mut buf = FrameBuffer::new();
    seq.next_frame(&mut buf).unwrap().unwrap();
    expect_err_naming(seq.next_frame(&mut buf), "000001.png", "cannot open");
    seq.next_frame(&mut buf).unwrap().unwrap();
    assert_eq!(buf.meta.frame_id, 2);
}
