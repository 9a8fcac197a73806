//! Decode speed of 1440x1080 grey videos (a simulated Bayer mosaic stored as grey, as a
//! recorder would write it): FFV1 and H.264, with FFmpeg's automatic threads and with one.
//!
//! `cargo run --release -p rodtrack-video --features video --example decode_speed -- [FRAMES]`
//!
//! Needs the `ffmpeg` tool to encode the test videos. Prints frames/s per codec and setting.

#[path = "../tests/common/mod.rs"]
mod common;

use rodtrack_core::PixelFormat;
use rodtrack_io::{FrameBuffer, FrameSource};
use rodtrack_sim::{default_cameras, RenderMode, Scenario, SceneConfig, Simulation};
use rodtrack_video::{VideoOptions, VideoSource};
use std::path::Path;
use std::time::Instant;

fn decode_fps(path: &Path, threads: usize) -> Result<(usize, f64), Box<dyn std::error::Error>> {
    let options = VideoOptions {
        format: Some(PixelFormat::BayerRggb8),
        threads,
        ..VideoOptions::default()
    };
    let t = Instant::now();
    let mut src = VideoSource::open(path, &options)?;
    let mut buf = FrameBuffer::new();
    let mut n = 0;
    while src.next_frame(&mut buf)?.is_some() {
        n += 1;
    }
    Ok((n, n as f64 / t.elapsed().as_secs_f64()))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    common::require_ffmpeg();
    let frames: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(100);
    let scene = SceneConfig::default();
    let mut cams = default_cameras();
    for c in &mut cams {
        c.pixel_format = PixelFormat::BayerRggb8;
    }
    let scenario = Scenario::by_name("gameplay", &scene, 1)?;
    let mut sim = Simulation::new(scene, cams, scenario, RenderMode::Fast)?;
    let mut images = Vec::with_capacity(frames);
    for k in 0..frames {
        let mut buf = vec![0u8; sim.frame_bytes(0)?];
        let m = sim.render(k, 0, &mut buf)?;
        assert_eq!((m.width, m.height), (1440, 1080));
        images.push(buf);
    }
    let dir = common::TempDir::new("speed");
    let cases: [(&str, &str, &[&str]); 4] = [
        ("FFV1 (defaults)", "ffv1.mkv", &["-c:v", "ffv1"]),
        (
            "FFV1 level 3, 4 slices",
            "ffv1-sliced.mkv",
            &[
                "-c:v",
                "ffv1",
                "-level",
                "3",
                "-slices",
                "4",
                "-slicecrc",
                "1",
            ],
        ),
        (
            "H.264 qp 0 (lossless luma)",
            "h264-qp0.mkv",
            &[
                "-c:v", "libx264", "-qp", "0", "-preset", "veryfast", "-pix_fmt", "yuv420p",
            ],
        ),
        (
            "H.264 crf 18",
            "h264-crf18.mkv",
            &[
                "-c:v", "libx264", "-crf", "18", "-preset", "veryfast", "-pix_fmt", "yuv420p",
            ],
        ),
    ];
    println!(
        "decode speed, 1440x1080 grey (simulated Bayer mosaic), {frames} frames, {} cores",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    for (name, file, args) in cases {
        let path = dir.join(file);
        common::encode(&images, 1440, 1080, "gray", 200, args, &path);
        let size_mb = std::fs::metadata(&path)?.len() as f64 / 1e6;
        let (n, auto) = decode_fps(&path, 0)?;
        let (_, one) = decode_fps(&path, 1)?;
        println!(
            "{name:28} {size_mb:7.1} MB  {n} frames  auto threads {auto:7.1} frames/s  1 thread {one:7.1} frames/s"
        );
    }
    Ok(())
}
