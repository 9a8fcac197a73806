//! Fuzzing of every parser of outside data, without nightly: random byte strings and mutations
//! of valid seeds (flipped bytes, cut, repeated or inserted runs, numbers replaced by huge,
//! negative or non-finite ones), generated from proptest's RNG. Each target runs for
//! `RODTRACK_FUZZ_SECS` seconds (default 2; CI runs 6), seeded by `RODTRACK_FUZZ_SEED`
//! (default fixed, so a failure reproduces). A case fails on a panic, and on an allocation
//! over [`CAP`] or a total live over [`CAP`] (a counting global allocator; one allocation
//! above the cap is refused, which aborts the test binary with the allocation size).
//!
//! Targets: calibration inputs (JSON), calibration file (TOML), OpenCV camera model (YAML and
//! JSON), `timestamps.csv`, input strings (URIs), image files (PNG, PGM, TIFF headers and
//! data), the UDP layout (decode, and encode/decode round trip), measurement files (CSV and
//! JSON Lines), MCAP recordings (the reader `rodtrack replay` uses, and the rows' messages in
//! them), the ball's event lines.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use proptest::prelude::Rng;
use proptest::test_runner::{RngAlgorithm, TestRng};
use rodtrack_core::calib::validate::{validate_inputs, MAX_ROD_ID};
use rodtrack_core::calib::{CalibrationFile, CalibrationInputs};
use rodtrack_core::{CameraId, Measurement, PixelFormat, Status};
use rodtrack_io::source::{parse_timestamps_csv, ImageDecoderScratch};
use rodtrack_io::{decode_udp_packet, FrameBuffer, InputSpec};
use std::path::Path;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The most one allocation, or all live allocations of a case, may take.
const CAP: usize = 256 << 20;

#[allow(unsafe_code)]
mod capped {
    use super::CAP;
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

    /// Counts live bytes; refuses one allocation over [`CAP`].
    pub struct Capped;
    pub static LIVE: AtomicUsize = AtomicUsize::new(0);
    pub static PEAK: AtomicUsize = AtomicUsize::new(0);
    pub static LARGEST: AtomicUsize = AtomicUsize::new(0);
    pub static OVER: AtomicBool = AtomicBool::new(false);

    fn note(size: usize) {
        let live = LIVE.fetch_add(size, Ordering::Relaxed) + size;
        PEAK.fetch_max(live, Ordering::Relaxed);
        LARGEST.fetch_max(size, Ordering::Relaxed);
    }

    // SAFETY: every method forwards to the system allocator with the caller's layout and
    // pointer unchanged; the counters are atomics and never allocate. Refusing an allocation
    // (null) is allowed by the `GlobalAlloc` contract.
    unsafe impl GlobalAlloc for Capped {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            if layout.size() > CAP {
                OVER.store(true, Ordering::Relaxed);
                return std::ptr::null_mut();
            }
            note(layout.size());
            // SAFETY: same layout as given to us.
            unsafe { System.alloc(layout) }
        }
        unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
            if layout.size() > CAP {
                OVER.store(true, Ordering::Relaxed);
                return std::ptr::null_mut();
            }
            note(layout.size());
            // SAFETY: same layout as given to us.
            unsafe { System.alloc_zeroed(layout) }
        }
        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            // SAFETY: `ptr` was allocated by `System` with this layout.
            unsafe { System.dealloc(ptr, layout) }
        }
        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            if new_size > CAP {
                OVER.store(true, Ordering::Relaxed);
                return std::ptr::null_mut();
            }
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            note(new_size);
            // SAFETY: `ptr` was allocated by `System` with `layout`; the new size is non-zero
            // as the caller guarantees.
            unsafe { System.realloc(ptr, layout, new_size) }
        }
    }
}

#[global_allocator]
static ALLOC: capped::Capped = capped::Capped;

/// One target at a time: the allocation counters are global.
static SERIAL: Mutex<()> = Mutex::new(());

fn budget() -> Duration {
    let secs = std::env::var("RODTRACK_FUZZ_SECS")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 0.0)
        .unwrap_or(2.0);
    Duration::from_secs_f64(secs)
}

fn rng(target: &str) -> TestRng {
    let seed: u64 = std::env::var("RODTRACK_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x5eed_0019);
    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&seed.to_le_bytes());
    for (i, b) in target.bytes().enumerate() {
        bytes[8 + i % 24] ^= b;
    }
    TestRng::from_seed(RngAlgorithm::ChaCha, &bytes)
}

fn below(rng: &mut TestRng, n: usize) -> usize {
    if n == 0 {
        0
    } else {
        (rng.next_u64() % n as u64) as usize
    }
}

/// Replacements for a number in a text seed.
const HOSTILE_NUMBERS: [&str; 14] = [
    "0",
    "-1",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "99999999999999999999999",
    "1e300",
    "-1e300",
    "1e20",
    "NaN",
    "inf",
    "-0",
    "2000000000",
    "65535",
];

/// A mutation of `seed`: a few random edits, or random bytes.
fn mutate(rng: &mut TestRng, seed: &[u8]) -> Vec<u8> {
    if below(rng, 16) == 0 {
        let n = below(rng, 256);
        return (0..n).map(|_| rng.next_u32() as u8).collect();
    }
    let mut v = seed.to_vec();
    for _ in 0..1 + below(rng, 4) {
        let len = v.len();
        match below(rng, 7) {
            0 if len > 0 => {
                let i = below(rng, len);
                v[i] ^= 1 << below(rng, 8);
            }
            1 if len > 0 => {
                let i = below(rng, len);
                v[i] = rng.next_u32() as u8;
            }
            2 => v.truncate(below(rng, len + 1)),
            3 if len > 0 => {
                // Repeat a run (up to 8 times).
                let a = below(rng, len);
                let b = (a + 1 + below(rng, 64)).min(len);
                let run = v[a..b].to_vec();
                for _ in 0..1 + below(rng, 8) {
                    v.splice(a..a, run.iter().copied());
                }
            }
            4 => {
                let i = below(rng, len + 1);
                let junk: Vec<u8> = (0..1 + below(rng, 16))
                    .map(|_| rng.next_u32() as u8)
                    .collect();
                v.splice(i..i, junk);
            }
            5 if len > 0 => {
                let a = below(rng, len);
                let b = (a + below(rng, 32)).min(len);
                v.drain(a..b);
            }
            _ => {
                // Replace the number at a random place with a hostile one.
                let digits: Vec<usize> = (0..len).filter(|&i| v[i].is_ascii_digit()).collect();
                if digits.is_empty() {
                    continue;
                }
                let mut a = digits[below(rng, digits.len())];
                while a > 0 && (v[a - 1].is_ascii_digit() || b".-eE+".contains(&v[a - 1])) {
                    a -= 1;
                }
                let mut b = a;
                while b < len && (v[b].is_ascii_digit() || b".-eE+".contains(&v[b])) {
                    b += 1;
                }
                let r = HOSTILE_NUMBERS[below(rng, HOSTILE_NUMBERS.len())];
                v.splice(a..b, r.bytes());
            }
        }
    }
    v
}

/// Runs `case` on generated inputs for the time budget; returns the number of cases.
fn fuzz(target: &str, seeds: &[&[u8]], mut case: impl FnMut(&[u8])) -> u64 {
    let _serial = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let mut rng = rng(target);
    let end = Instant::now() + budget();
    let mut n = 0u64;
    let mut peak_over_base = 0usize;
    // The seeds themselves first, then mutations, at least once each.
    loop {
        let input = if (n as usize) < seeds.len() {
            seeds[n as usize].to_vec()
        } else {
            let s = seeds[below(&mut rng, seeds.len())];
            mutate(&mut rng, s)
        };
        let base = capped::LIVE.load(std::sync::atomic::Ordering::Relaxed);
        capped::PEAK.store(base, std::sync::atomic::Ordering::Relaxed);
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| case(&input)));
        let peak = capped::PEAK.load(std::sync::atomic::Ordering::Relaxed);
        let shown = String::from_utf8_lossy(&input[..input.len().min(300)]).into_owned();
        assert!(r.is_ok(), "{target}: panic on input {shown:?}");
        assert!(
            !capped::OVER.load(std::sync::atomic::Ordering::Relaxed),
            "{target}: an allocation over the cap on input {shown:?}"
        );
        let used = peak.saturating_sub(base);
        assert!(
            used <= CAP,
            "{target}: {} MiB live on input {shown:?}",
            used >> 20
        );
        peak_over_base = peak_over_base.max(used);
        n += 1;
        if n as usize >= seeds.len() && Instant::now() >= end {
            break;
        }
    }
    eprintln!(
        "fuzz {target}: {n} cases in {:?}, peak {:.1} MiB over the harness",
        budget(),
        peak_over_base as f64 / 1048576.0
    );
    n
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

const INPUTS: &str = include_str!("data/fuzz/inputs.json");
const CALIB: &str = include_str!("data/fuzz/calib.toml");
const OPENCV_YAML: &str = include_str!("data/fuzz/opencv.yml");

#[test]
fn fuzz_calibration_inputs_json() {
    let n = fuzz("inputs_json", &[INPUTS.as_bytes()], |b| {
        if let Ok(inputs) = serde_json::from_str::<CalibrationInputs>(&text(b)) {
            if validate_inputs(&inputs, 0).is_ok() {
                // What validation lets through is bounded.
                assert!(inputs.rods.iter().all(|r| r.rod <= MAX_ROD_ID));
                assert!(inputs.rods.iter().all(|r| r.travel_mm[0] <= r.travel_mm[1]));
            }
        }
    });
    assert!(n > 1);
}

#[test]
fn fuzz_calibration_toml() {
    let n = fuzz("calib_toml", &[CALIB.as_bytes()], |b| {
        if let Ok(cal) = toml::from_str::<CalibrationFile>(&text(b)) {
            let _ = cal.validate();
        }
    });
    assert!(n > 1);
}

#[test]
fn fuzz_opencv_model_yaml_and_json() {
    let json = r#"{"camera_matrix":{"type_id":"opencv-matrix","rows":3,"cols":3,"dt":"d",
        "data":[1078.3,0,719.5,0,1078.3,539.5,0,0,1]},
        "distortion_coefficients":{"type_id":"opencv-matrix","rows":1,"cols":5,"dt":"d",
        "data":[-0.25,0.08,0.0004,-0.0003,0]}}"#;
    let n = fuzz("opencv", &[OPENCV_YAML.as_bytes(), json.as_bytes()], |b| {
        let _ = rodtrack_core::calib::opencv::parse_opencv_model(&text(b));
    });
    assert!(n > 2);
}

#[test]
fn fuzz_timestamps_csv() {
    let seed = b"frame,timestamp_s\n0,0.000\n1,0.005\n2,0.010\n3,0.015\n";
    let n = fuzz("timestamps_csv", &[seed, b"0,1.5\n1,1.6\n"], |b| {
        let mut w = Vec::new();
        if let Ok(map) = parse_timestamps_csv(Path::new("timestamps.csv"), &text(b), &mut w) {
            assert!(map.values().all(|t| t.is_finite() && *t >= 0.0));
        }
    });
    assert!(n > 2);
}

#[test]
fn fuzz_input_strings() {
    let seeds: [&[u8]; 5] = [
        b"raw:rec/cam0.raw?width=1440&height=1080&format=bayer_rggb8&stride=1440&header=0",
        b"rec/cam0?fps=200&format=mono8",
        b"video:cam0.mkv?timestamps=fps",
        b"genicam://Fake_1?format=BayerRG8&exposure_us=500&fps=200&trigger=software",
        b"sim://exp1?camera=1&frames=400&seed=3&realtime=1",
    ];
    let n = fuzz("input_strings", &seeds, |b| {
        if let Ok(spec) = InputSpec::parse(&text(b)) {
            let _ = spec.kind();
            let _ = spec.param_format();
            for k in ["width", "height", "stride", "header", "frames", "camera"] {
                let _ = spec.param_parse::<usize>(k);
            }
            let _ = spec.param_parse::<f64>("fps");
            let _ = spec.check_params(&["format", "fps", "width", "height"]);
        }
    });
    assert!(n > 5);
}

fn png_gray(w: u32, h: u32, sixteen: bool) -> Vec<u8> {
    let mut out = Vec::new();
    let enc = image::codecs::png::PngEncoder::new(&mut out);
    use image::ImageEncoder;
    let (color, bpp) = if sixteen {
        (image::ExtendedColorType::L16, 2)
    } else {
        (image::ExtendedColorType::L8, 1)
    };
    let px: Vec<u8> = (0..w * h * bpp).map(|i| (i * 7) as u8).collect();
    enc.write_image(&px, w, h, color).unwrap();
    out
}

fn tiff_gray(w: u32, h: u32) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    let enc = image::codecs::tiff::TiffEncoder::new(&mut out);
    use image::ImageEncoder;
    let px: Vec<u8> = (0..w * h).map(|i| (i * 3) as u8).collect();
    enc.write_image(&px, w, h, image::ExtendedColorType::L8)
        .unwrap();
    out.into_inner()
}

#[test]
fn fuzz_image_files() {
    let mut pgm = b"P5\n16 12\n255\n".to_vec();
    pgm.extend((0..16 * 12).map(|i| i as u8));
    let png8 = png_gray(16, 12, false);
    let png16 = png_gray(16, 12, true);
    let tif = tiff_gray(16, 12);
    let seeds: [&[u8]; 4] = [&pgm, &png8, &png16, &tif];
    let mut expecting = ImageDecoderScratch::expecting(Some((16, 12)));
    let mut any = ImageDecoderScratch::expecting(None);
    let mut buf = FrameBuffer::new();
    let mut i = 0u64;
    let n = fuzz("image_files", &seeds, |b| {
        // The name gives the format when the bytes do not.
        let name = ["f.pgm", "f.png", "f.tif"][(i % 3) as usize];
        i += 1;
        let path = Path::new(name);
        for want in [
            None,
            Some(PixelFormat::BayerRggb8),
            Some(PixelFormat::Mono16),
        ] {
            if expecting.decode_bytes(path, b, want, &mut buf).is_ok() {
                assert_eq!((buf.meta.width, buf.meta.height), (16, 12));
                assert!(buf.view().is_ok());
            }
        }
        if any.decode_bytes(path, b, None, &mut buf).is_ok() {
            // Any size up to the limit (the view may still refuse a tiny one).
            let m = buf.meta;
            assert_eq!(
                buf.data.len(),
                m.width * m.height * m.format.bytes_per_pixel()
            );
            assert!(m.width * m.height <= rodtrack_io::source::DEFAULT_MAX_PIXELS);
        }
    });
    assert!(n > 4);
}

fn sample_rows() -> Vec<Measurement> {
    let mut rows = Vec::new();
    for (i, cam) in [CameraId::Camera(0), CameraId::Camera(1), CameraId::Fused]
        .into_iter()
        .enumerate()
    {
        let mut m = Measurement::empty(
            12,
            rodtrack_core::Timestamp::from_secs_f64(0.06),
            cam,
            i as u32,
            Status::Ok,
        );
        m.position_mm = -12.5 + i as f64;
        m.angle_rad = 1.5;
        m.angle_unwrapped_rad = 7.8;
        m.quality = 0.9;
        rows.push(m);
    }
    rows
}

#[test]
fn fuzz_udp_layout() {
    let mut packet = Vec::new();
    rodtrack_io::sink::encode_udp_packet(7, &sample_rows(), &mut packet).unwrap();
    let decoded = decode_udp_packet(&packet).unwrap();
    assert_eq!(decoded.seq, 7);
    let n = fuzz("udp_layout", &[&packet], |b| {
        if let Ok(p) = decode_udp_packet(b) {
            // What decodes encodes again to a packet that decodes the same.
            let mut again = Vec::new();
            if rodtrack_io::sink::encode_udp_packet(p.seq, &p.rows, &mut again).is_ok() {
                let q = decode_udp_packet(&again).unwrap();
                assert_eq!(q.rows.len(), p.rows.len());
                assert_eq!(q.seq, p.seq);
            }
        }
    });
    assert!(n > 1);
}

#[test]
fn fuzz_measurement_files() {
    let csv = "frame,timestamp_s,camera,rod,position_mm,angle_rad,angle_unwrapped_rad,\
               velocity_mm_s,angular_velocity_rad_s,quality,status\n\
               12,0.060,0,3,-12.5,1.5,7.8,0,0,0.95,ok\n12,0.060,fused,3,-12.4,1.5,7.8,0,0,0.9,ok\n";
    let json = r#"{"frame":12,"timestamp_s":0.06,"camera":0,"rod":3,"position_mm":-12.5,"angle_rad":1.5,"angle_unwrapped_rad":7.8,"velocity_mm_s":0,"angular_velocity_rad_s":0,"quality":0.95,"status":"ok"}"#;
    let n = fuzz(
        "measurement_files",
        &[csv.as_bytes(), json.as_bytes()],
        |b| {
            let t = text(b);
            let _ = rodtrack_io::sink::parse_measurements_csv(&t, Path::new("m.csv"));
            let _ = rodtrack_io::sink::parse_measurement_json(&t, Path::new("m.jsonl"), 1);
        },
    );
    assert!(n > 2);
}

#[test]
fn fuzz_mcap_recordings() {
    use rodtrack_core::ball::{BallRow, BallStatus};
    use rodtrack_core::CameraId;
    use rodtrack_io::mcap::{
        parse_ball_message, parse_event_message, parse_mcap, parse_rows_message, ChunkLimits,
        Compression, JointState, McapRecorder, Profile, StampedXyz,
    };
    use rodtrack_io::{BallSink, EventSink, MeasurementSink};
    // Small real recordings (several chunks, two cameras and the fusion, rods, ball and events) as the
    // seeds: what `rodtrack replay` reads, uncompressed and in LZ4 chunks, and a ROS 2 bag of
    // joint states and the ball's stamped points in CDR (LZ4 chunks).
    let dir = std::env::temp_dir().join(format!("rodtrack-fuzz-mcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut seeds = Vec::new();
    for (k, (profile, compression)) in [
        (Profile::Rodtrack, Compression::None),
        (Profile::Rodtrack, Compression::Lz4),
        (Profile::Ros2, Compression::Lz4),
    ]
    .into_iter()
    .enumerate()
    {
        let path = dir.join(format!("seed{k}.mcap"));
        let rec = McapRecorder::create(
            &path,
            rodtrack_io::mcap::RecordOptions {
                table: "t".into(),
                cameras: vec![(0, "cam0".into()), (1, "cam1".into())],
                chunk: ChunkLimits {
                    span_ns: 10_000_000,
                    bytes: 1 << 20,
                },
                frames_per_s: 0.0,
                profile,
                compression,
            },
        )
        .unwrap();
        let mut sink = rec.sink();
        let mut ball = rec.ball_sink(35.0);
        let mut events = rec.event_sink();
        for f in 0..6u64 {
            let t = rodtrack_core::Timestamp(5_000_000 * f);
            let row = |camera, status| BallRow {
                x_mm: -120.5 + f as f64,
                y_mm: 33.25,
                vx_mm_s: 800.0,
                vy_mm_s: -150.0,
                quality: 0.9,
                status,
                ..BallRow::lost(f, t, camera)
            };
            ball.write_sigma(
                &[
                    row(CameraId::Camera(0), BallStatus::Ok),
                    row(CameraId::Camera(1), BallStatus::Lost),
                    row(CameraId::Fused, BallStatus::Predicted),
                ],
                &[0.4, f64::INFINITY, f64::NAN],
            )
            .unwrap();
            let rows: Vec<Measurement> = sample_rows()
                .into_iter()
                .map(|mut m| {
                    m.frame = f;
                    m.timestamp_ns = rodtrack_core::Timestamp(5_000_000 * f);
                    m
                })
                .collect();
            sink.write(&rows).unwrap();
            events
                .write(&[rodtrack_core::ball::events::BallEvent {
                    frame: f,
                    timestamp_ns: t,
                    kind: rodtrack_core::ball::events::EventKind::BallStopped {
                        x_mm: -120.5,
                        y_mm: 33.25,
                    },
                }])
                .unwrap();
        }
        sink.flush().unwrap();
        rec.finish().unwrap();
        let seed = std::fs::read(&path).unwrap();
        let file = parse_mcap(&seed, Path::new("seed.mcap")).unwrap();
        assert!(file.complete && !file.messages.is_empty());
        seeds.push(seed);
    }
    let _ = std::fs::remove_dir_all(&dir);
    let seeds: Vec<&[u8]> = seeds.iter().map(Vec::as_slice).collect();
    let n = fuzz("mcap", &seeds, |b| {
        if let Ok(file) = parse_mcap(b, Path::new("f.mcap")) {
            for m in &file.messages {
                let _ = parse_rows_message(&m.data);
                let _ = JointState::from_cdr(&m.data);
                let _ = parse_ball_message(&m.data);
                let _ = StampedXyz::from_cdr(&m.data);
                let _ = parse_event_message(&m.data);
            }
        }
    });
    assert!(n > 1);
}

#[test]
fn fuzz_event_lines() {
    let seeds: [&[u8]; 3] = [
        br#"{"frame":3,"timestamp_s":0.015000,"event":"ball_stopped","x_mm":10.0,"y_mm":-5.0}"#,
        br#"{"frame":120,"timestamp_s":0.6,"event":"goal","side":"a","score":[1,0]}"#,
        br#"{"frame":7,"timestamp_s":0.035,"event":"shot","speed_mm_s":4500.0,"rod":2}"#,
    ];
    let n = fuzz("event_lines", &seeds, |b| {
        let _ = rodtrack_io::sink::parse_event_json(&text(b), Path::new("e.jsonl"), 1);
    });
    assert!(n > 2);
}
