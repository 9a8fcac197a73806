//! The console's publish calls in isolation (warm caches, so a lower bound of their cost in the
//! pipeline): the live view's frame copy of a 1440x1080 Bayer8 frame, full
//! ([`OwnedFrame::copy_from`]) against decimated as
//! [`rodtrack_console::ConsoleHandle::publish_frame`] makes it
//! ([`OwnedFrame::copy_decimated`]); `publish_rows` of one frame set (2 cameras x 8 rods + 8
//! fused rows); a frame offered when no live frame is due. Their share of the pipeline's time
//! is the `overhead` bench.
//!
//! ```sh
//! cargo bench -p rodtrack-console --bench publish
//! ```
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_console::{live_decimation, Console, OwnedFrame};
use rodtrack_core::{CameraId, FrameView, Measurement, PixelFormat, Status};
use std::hint::black_box;
use std::time::Instant;

/// Median time per call over `batches` batches of `per_batch` calls, ns.
fn time(batches: usize, per_batch: usize, mut f: impl FnMut()) -> f64 {
    for _ in 0..per_batch {
        f();
    }
    let mut t: Vec<f64> = (0..batches)
        .map(|_| {
            let t0 = Instant::now();
            for _ in 0..per_batch {
                f();
            }
            t0.elapsed().as_nanos() as f64 / per_batch as f64
        })
        .collect();
    t.sort_by(|a, b| a.total_cmp(b));
    t[t.len() / 2]
}

fn main() {
    let (w, h) = (1440, 1080);
    let data: Vec<u8> = (0..w * h).map(|i| (i * 7 + i / w) as u8).collect();
    let view = FrameView::packed(&data, w, h, PixelFormat::BayerRggb8).unwrap();
    let d = live_decimation(w, PixelFormat::BayerRggb8);
    let mut full = OwnedFrame::default();
    let t_full = time(50, 20, || full.copy_from(black_box(&view), 1, 0.0));
    let mut dec = OwnedFrame::default();
    let t_dec = time(50, 20, || dec.copy_decimated(black_box(&view), d, 1, 0.0));
    println!("live frame copy, 1440x1080 Bayer8 (median per call):");
    println!("  full:            {:8.1} us", t_full / 1e3);
    println!(
        "  decimated by {d}:  {:8.1} us ({}x{})",
        t_dec / 1e3,
        dec.width(),
        dec.height()
    );

    let console = Console::start("127.0.0.1:0".parse().unwrap(), None).unwrap();
    let mut rows = Vec::new();
    for cam in [CameraId::Camera(0), CameraId::Camera(1), CameraId::Fused] {
        for rod in 0..8 {
            rows.push(Measurement::empty(
                1,
                rodtrack_core::Timestamp::from_secs_f64(0.005),
                cam,
                rod,
                Status::Ok,
            ));
        }
    }
    let t_rows = time(200, 500, || console.publish_rows(black_box(&rows)));
    let t_skip = time(200, 5000, || {
        console.publish_frame(0, black_box(&view), 1, 0.0, &[]);
    });
    println!("publish calls (median per call):");
    println!("  publish_rows, 24 rows:       {t_rows:8.0} ns");
    println!("  publish_frame, not wanted:   {t_skip:8.1} ns");
}
