//! Per-frame I/O costs at the reference size (1440 x 1080 Bayer 8-bit): image decode into a
//! pooled buffer, raw read, CSV formatting and UDP encoding of one frame set (24 rows).
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{criterion_group, criterion_main, Criterion};
use rodtrack_core::{CameraId, Measurement, PixelFormat, Status};
use rodtrack_io::sink::encode_udp_packet;
use rodtrack_io::source::{ImageDecoderScratch, RawOptions};
use rodtrack_io::{CsvSink, FrameBuffer, FrameSource, MeasurementSink, RawSource};
use std::hint::black_box;
use std::path::PathBuf;

const W: u32 = 1440;
const H: u32 = 1080;

fn noisy(x: u32, y: u32) -> u8 {
    let mut v = x.wrapping_mul(0x9E37_79B9) ^ y.wrapping_mul(0x85EB_CA6B);
    v ^= v >> 13;
    (v.wrapping_mul(0xC2B2_AE35) >> 24) as u8 / 4 + ((x / 20 + y / 20) % 2 * 120) as u8
}

fn setup() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rodtrack-io-bench-{}", std::process::id()));
    for ext in ["pgm", "png"] {
        let d = dir.join(ext);
        std::fs::create_dir_all(&d).unwrap();
        let img = image::GrayImage::from_fn(W, H, |x, y| image::Luma([noisy(x, y)]));
        img.save(d.join(format!("000000.{ext}"))).unwrap();
    }
    let raw: Vec<u8> = (0..H)
        .flat_map(|y| (0..W).map(move |x| noisy(x, y)))
        .collect();
    std::fs::write(dir.join("frames.raw"), raw.repeat(4)).unwrap();
    dir
}

fn rows() -> Vec<Measurement> {
    (0..24)
        .map(|i| Measurement {
            frame: 123_456,
            timestamp_ns: rodtrack_io::Timestamp::from_secs_f64(617.28),
            camera: if i < 16 {
                CameraId::Camera(i / 8)
            } else {
                CameraId::Fused
            },
            rod: i % 8,
            position_mm: -12.345 + f64::from(i),
            angle_rad: 1.234_567,
            angle_unwrapped_rad: 101.234_567,
            velocity_mm_s: 250.0,
            angular_velocity_rad_s: -30.0,
            quality: 0.97,
            status: Status::Ok,
            turns_known: true,
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let dir = setup();
    let mut g = c.benchmark_group("decode_1440x1080_bayer8");
    for ext in ["pgm", "png"] {
        let path = dir.join(ext).join(format!("000000.{ext}"));
        let mut scratch = ImageDecoderScratch::default();
        let mut buf = FrameBuffer::new();
        g.bench_function(ext, |b| {
            b.iter(|| {
                scratch
                    .decode(&path, Some(PixelFormat::BayerRggb8), &mut buf)
                    .unwrap();
                black_box(buf.data[0]);
            })
        });
    }
    let mut buf = FrameBuffer::new();
    let ro = RawOptions::new(W as usize, H as usize, PixelFormat::BayerRggb8);
    let mut src = RawSource::open(&dir.join("frames.raw"), ro).unwrap();
    g.bench_function("raw", |b| {
        b.iter(|| {
            if src.next_frame(&mut buf).unwrap().is_none() {
                src = RawSource::open(&dir.join("frames.raw"), ro).unwrap();
                src.next_frame(&mut buf).unwrap().unwrap();
            }
            black_box(buf.data[0]);
        })
    });
    g.finish();

    let rows = rows();
    let mut g = c.benchmark_group("frame_set_24_rows");
    let mut sink = CsvSink::new(std::io::sink(), "null").unwrap();
    g.bench_function("csv_format", |b| {
        b.iter(|| sink.write(black_box(&rows)).unwrap())
    });
    let mut packet = Vec::new();
    g.bench_function("udp_encode", |b| {
        b.iter(|| encode_udp_packet(1, black_box(&rows), &mut packet).unwrap())
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
