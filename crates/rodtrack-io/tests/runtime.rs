//! The pipeline with in-test frame sources.
#![allow(clippy::unwrap_used, missing_docs)]

#[path = "common/runtime_fakes.rs"]
mod runtime_fakes;

use rodtrack_core::{CameraId, PixelFormat, Status};
use rodtrack_io::runtime::{Grouping, Handoff, Pipeline, PipelineConfig, RunMode};
use rodtrack_io::{read_measurements_csv, CsvSink, FrameSource};
use runtime_fakes::{tracker, Fake, Writes};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

fn config(mode: RunMode) -> PipelineConfig {
    PipelineConfig {
        mode,
        ..Default::default()
    }
}

#[test]
fn groups_two_cameras_by_frame_id() {
    let mut p = Pipeline::new(config(RunMode::Batch));
    p.add_camera(Box::new(Fake::new(0..300)), tracker(Duration::ZERO));
    p.add_camera(Box::new(Fake::new(0..300)), tracker(Duration::ZERO));
    p.set_fusion(Box::new(|set, rows, out| {
        assert!(set.complete);
        assert_eq!(rows.len(), 4);
        let mut m = rows[0];
        m.camera = CameraId::Fused;
        out.push(m);
    }));
    let mut sink = Writes::default();
    let r = p.run(&mut sink).unwrap();
    assert_eq!(
        (r.sets_complete, r.sets_incomplete, r.rows_written),
        (300, 0, 1500)
    );
    assert_eq!(sink.0.len(), 300);
    for (i, set) in sink.0.iter().enumerate() {
        assert_eq!(set.len(), 5);
        let cams: Vec<CameraId> = set.iter().map(|m| m.camera).collect();
        assert_eq!(
            cams,
            [0, 0, 1, 1]
                .map(CameraId::Camera)
                .into_iter()
                .chain([CameraId::Fused])
                .collect::<Vec<_>>()
        );
        for m in set {
            assert_eq!(
                m.frame, i as u64,
                "sets in frame order, rows of their own frame"
            );
            assert_eq!(
                m.position_mm,
                (i % 256) as f64 + f64::from(m.rod),
                "the view holds that frame's pixels"
            );
        }
    }
    for c in &r.cameras {
        assert_eq!(
            (
                c.frames_read,
                c.frames_processed,
                c.frames_dropped,
                c.bad_frames
            ),
            (300, 300, 0, 0)
        );
        assert!(
            c.buffers_allocated <= PipelineConfig::default().queue_depth + 3,
            "{c:?}"
        );
    }
    assert_eq!(r.latency.count, 600);
    assert!(r.latency.p50 <= r.latency.p99 && r.latency.p99 <= r.latency.max);
}

#[test]
fn a_missing_frame_is_reported_without_waiting() {
    let mut cfg = config(RunMode::Batch);
    cfg.group_timeout = Duration::from_secs(60);
    let mut p = Pipeline::new(cfg);
    p.add_camera(Box::new(Fake::new(0..20)), tracker(Duration::ZERO));
    p.add_camera(
        Box::new(Fake::new((0..20).filter(|i| *i != 5))),
        tracker(Duration::ZERO),
    );
    let mut sink = Writes::default();
    let t = Instant::now();
    let r = p.run(&mut sink).unwrap();
    assert!(
        t.elapsed() < Duration::from_secs(5),
        "waited for the group timeout"
    );
    assert_eq!((r.sets_complete, r.sets_incomplete), (19, 1));
    assert_eq!(
        (r.cameras[0].missing_in_sets, r.cameras[1].missing_in_sets),
        (0, 1)
    );
    assert_eq!(sink.0.len(), 20);
    let set5 = &sink.0[5];
    assert!(set5
        .iter()
        .all(|m| m.frame == 5 && m.camera == CameraId::Camera(0)));
    assert_eq!(set5.len(), 2);
    let text = r.to_string();
    assert!(
        text.contains("1 incomplete") && text.contains("camera 1 (fake)"),
        "{text}"
    );
}

#[test]
fn a_stalled_camera_is_not_waited_for_beyond_the_timeout() {
    let mut cfg = config(RunMode::Live);
    cfg.group_timeout = Duration::from_millis(50);
    let mut p = Pipeline::new(cfg);
    let mut a = Fake::new(0..40);
    a.delay = Duration::from_millis(2);
    let mut b = Fake::new(0..40);
    b.delay = Duration::from_millis(2);
    b.stall = Some((10, Duration::from_millis(700)));
    p.add_camera(Box::new(a), tracker(Duration::ZERO));
    p.add_camera(Box::new(b), tracker(Duration::ZERO));
    let mut sink = Writes::default();
    let r = p.run(&mut sink).unwrap();
    // Camera 0's frames 10..39 went out after about the timeout, not after the stall.
    let cam0_frames: usize = sink
        .0
        .iter()
        .flatten()
        .filter(|m| m.camera == CameraId::Camera(0))
        .count();
    assert_eq!(cam0_frames, 80);
    assert!(r.sets_incomplete >= 1, "{r:?}");
    assert!(r.cameras[1].missing_in_sets >= 1);
    // Late frames of camera 1 are still written (on their own), nothing is lost.
    let cam1: usize = sink
        .0
        .iter()
        .flatten()
        .filter(|m| m.camera == CameraId::Camera(1))
        .count();
    assert_eq!(cam1 as u64, 2 * r.cameras[1].frames_processed);
    assert_eq!(
        r.rows_written,
        2 * (r.cameras[0].frames_processed + r.cameras[1].frames_processed)
    );
    // Frame ids never go backwards within a camera.
    for cam in [0, 1] {
        let ids: Vec<u64> = sink
            .0
            .iter()
            .flatten()
            .filter(|m| m.camera == CameraId::Camera(cam) && m.rod == 0)
            .map(|m| m.frame)
            .collect();
        assert!(ids.windows(2).all(|w| w[0] < w[1]), "camera {cam}: {ids:?}");
    }
    // The stall lasted 700 ms; no frame waited that long (timeout 50 ms).
    assert!(r.latency.max < Duration::from_millis(400), "{}", r.latency);
}

#[test]
fn a_slow_consumer_makes_live_capture_drop_and_batch_block() {
    for mode in [RunMode::Live, RunMode::Batch] {
        let mut cfg = config(mode);
        cfg.queue_depth = 2;
        let mut p = Pipeline::new(cfg);
        let mut src = Fake::new(0..100);
        src.delay = Duration::from_micros(200);
        p.add_camera(Box::new(src), tracker(Duration::from_millis(3)));
        let mut sink = Writes::default();
        let r = p.run(&mut sink).unwrap();
        let c = &r.cameras[0];
        assert_eq!(c.frames_read, 100);
        assert_eq!(
            c.frames_processed + c.frames_dropped,
            100,
            "{mode:?}: {c:?}"
        );
        assert_eq!(r.rows_written, 2 * c.frames_processed);
        assert_eq!(sink.0.len() as u64, c.frames_processed);
        match mode {
            RunMode::Batch => assert_eq!(c.frames_dropped, 0),
            _ => assert!(c.frames_dropped > 20, "{c:?}"),
        }
        assert_eq!(r.sets_incomplete, 0, "one camera: every set is complete");
    }
}

#[test]
fn bad_frames_reach_the_tracker_and_the_stream_goes_on() {
    let mut p = Pipeline::new(config(RunMode::Batch));
    let mut src = Fake::new(0..10);
    src.bad = [3, 4].into_iter().collect();
    p.add_camera(Box::new(src), tracker(Duration::ZERO));
    let mut sink = Writes::default();
    let r = p.run(&mut sink).unwrap();
    let c = &r.cameras[0];
    assert_eq!(
        (c.frames_read, c.frames_processed, c.bad_frames),
        (10, 10, 2)
    );
    assert!(c.errors[0].contains("fake3.png"), "{:?}", c.errors);
    assert_eq!(sink.0[3][0].status, Status::BadFrame);
    assert_eq!(sink.0[3][0].frame, 3);
    assert_eq!(sink.0[9].len(), 2);

    // A source that cannot tell a bad frame's id: the pipeline numbers it after the last one.
    let mut p = Pipeline::new(config(RunMode::Batch));
    let mut src = Fake::new(0..10);
    src.bad = [0, 6].into_iter().collect();
    src.hide_bad_ids = true;
    p.add_camera(Box::new(src), tracker(Duration::ZERO));
    let mut sink = Writes::default();
    let r = p.run(&mut sink).unwrap();
    assert_eq!(r.cameras[0].bad_frames, 2);
    let ids: Vec<u64> = sink.0.iter().map(|s| s[0].frame).collect();
    assert_eq!(ids, (0..10).collect::<Vec<_>>());
    assert_eq!(
        (sink.0[0][0].status, sink.0[6][0].status),
        (Status::BadFrame, Status::BadFrame)
    );
}

#[test]
fn stop_ends_cleanly_and_loses_no_rows() {
    let dir = std::env::temp_dir().join(format!("rodtrack-io-runtime-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("stop.csv");
    let mut p = Pipeline::new(config(RunMode::Batch));
    let mut a = Fake::new(0..);
    a.delay = Duration::from_millis(1);
    let mut b = Fake::new(0..);
    b.delay = Duration::from_millis(1);
    p.add_camera(Box::new(a), tracker(Duration::from_micros(500)));
    p.add_camera(Box::new(b), tracker(Duration::from_micros(500)));
    let stop = p.stop_flag();
    let live = p.counters();
    let watcher = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(300));
        let seen = live.cameras[0].frames_read.load(Ordering::Relaxed);
        stop.store(true, Ordering::Relaxed);
        seen
    });
    let mut sink = CsvSink::create(&path).unwrap();
    sink.set_flush_each_write(false);
    let t = Instant::now();
    let r = p.run(&mut sink).unwrap();
    assert!(t.elapsed() < Duration::from_secs(3));
    assert!(r.stopped);
    let seen_live = watcher.join().unwrap();
    assert!(seen_live > 0 && seen_live <= r.cameras[0].frames_read);
    let processed: u64 = r.cameras.iter().map(|c| c.frames_processed).sum();
    assert!(processed > 20, "{r:?}");
    for c in &r.cameras {
        assert_eq!(
            c.frames_read,
            c.frames_processed + c.frames_dropped,
            "{c:?}"
        );
    }
    assert_eq!(r.rows_written, 2 * processed);
    // Flushed by the pipeline, before the sink is dropped.
    let on_disk = read_measurements_csv(&path).unwrap();
    assert_eq!(on_disk.len() as u64, r.rows_written);
    drop(sink);
}

#[test]
fn paced_mode_follows_the_timestamps() {
    for (speed, min_ms) in [(1.0, 90u64), (2.0, 45)] {
        let mut p = Pipeline::new(config(RunMode::Paced { speed }));
        p.add_camera(Box::new(Fake::new(0..20)), tracker(Duration::ZERO));
        let mut sink = Writes::default();
        let r = p.run(&mut sink).unwrap();
        // 20 frames 5 ms apart: the last is released 95 ms (at 1x) after the first.
        assert!(
            r.elapsed >= Duration::from_millis(min_ms),
            "{speed}: {:?}",
            r.elapsed
        );
        assert!(r.elapsed < Duration::from_millis(min_ms * 4 + 200));
        // Paced replays as a live camera: a frame that finds the queue full is dropped (and
        // counted), as when the machine is busy with other work; none is lost uncounted.
        let c = &r.cameras[0];
        assert_eq!(c.frames_read, 20, "{c:?}");
        assert_eq!(c.frames_processed + c.frames_dropped, 20, "{c:?}");
        assert!(c.frames_processed > 0, "{c:?}");
    }
    let bad = Pipeline::new(config(RunMode::Paced { speed: 0.0 }));
    assert!(
        bad.run(&mut Writes::default()).is_err(),
        "no cameras / bad speed"
    );
}

#[test]
fn groups_by_timestamp_window() {
    let mut cfg = config(RunMode::Batch);
    cfg.grouping = Grouping::Timestamp {
        window_ns: 1_000_000,
    };
    let mut p = Pipeline::new(cfg);
    p.add_camera(Box::new(Fake::new(0..30)), tracker(Duration::ZERO));
    // Other counter, clock 0.3 ms later.
    let mut b = Fake::new(0..30);
    b.ts_offset_ns = 300_000;
    p.add_camera(Box::new(b), tracker(Duration::ZERO));
    let mut sink = Writes::default();
    let r = p.run(&mut sink).unwrap();
    assert_eq!((r.sets_complete, r.sets_incomplete), (30, 0));
    for set in &sink.0 {
        assert_eq!(set.len(), 4);
        assert!(set.iter().all(|m| m.frame == set[0].frame));
    }
}

/// A tracker that panics ends its camera only, run on the camera's own thread (`run`) or on
/// the capture thread (`Handoff::Inline`, `run_direct`); the rows before are kept.
#[test]
fn a_panicking_tracker_ends_its_camera_but_rows_are_kept() {
    for (handoff, direct) in [(Handoff::Queue, false), (Handoff::Inline, true)] {
        let mut p = Pipeline::new(PipelineConfig {
            mode: RunMode::Batch,
            handoff,
            ..Default::default()
        });
        p.add_camera(Box::new(Fake::new(0..50)), tracker(Duration::ZERO));
        let mut inner = tracker(Duration::ZERO);
        p.add_camera(
            Box::new(Fake::new(0..50)),
            Box::new(move |meta, view, out| {
                if meta.frame_id == 20 {
                    panic!("tracker bug");
                }
                inner(meta, view, out)
            }),
        );
        let (r, sink) = if direct {
            p.run_direct(Writes::default()).unwrap()
        } else {
            let mut sink = Writes::default();
            (p.run(&mut sink).unwrap(), sink)
        };
        assert_eq!(r.cameras[0].frames_processed, 50, "{handoff:?}");
        assert!(
            r.cameras[1].errors.iter().any(|e| e.contains("panicked")),
            "{handoff:?}: {r:?}"
        );
        assert_eq!(sink.0.len(), 50, "{handoff:?}");
        assert_eq!(r.rows_written, 100 + 40, "{handoff:?}");
    }
}

#[test]
fn two_image_folders_through_the_pipeline_to_csv() {
    use rodtrack_io::{OpenOptions, SourceFactory};
    let dir = std::env::temp_dir().join(format!("rodtrack-io-e2e-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for cam in ["cam0", "cam1"] {
        std::fs::create_dir_all(dir.join(cam)).unwrap();
        for id in 100..110u32 {
            if cam == "cam1" && id == 104 {
                continue; // camera 1 missed frame 104
            }
            let img = image::GrayImage::from_pixel(8, 6, image::Luma([id as u8]));
            img.save(dir.join(cam).join(format!("{id:06}.pgm")))
                .unwrap();
        }
    }
    std::fs::write(dir.join("cam0").join("000107.pgm"), b"P5 8 6 255 broken").unwrap();
    let factory = SourceFactory::new();
    let opts = OpenOptions {
        format: Some(PixelFormat::BayerRggb8),
        fps: Some(100.0),
        size: None,
    };
    let mut p = Pipeline::new(config(RunMode::Batch));
    for cam in ["cam0", "cam1"] {
        let src = factory
            .open(&dir.join(cam).display().to_string(), &opts)
            .unwrap();
        assert_eq!(src.info().format, PixelFormat::BayerRggb8);
        p.add_camera(src, tracker(Duration::ZERO));
    }
    let csv = dir.join("out.csv");
    let mut sink = CsvSink::create(&csv).unwrap();
    let r = p.run(&mut sink).unwrap();
    drop(sink);
    assert_eq!((r.sets_complete, r.sets_incomplete), (9, 1));
    assert_eq!(r.cameras[0].bad_frames, 1);
    assert!(
        r.cameras[0].errors[0].contains("000107.pgm"),
        "{:?}",
        r.cameras[0].errors
    );
    let rows = read_measurements_csv(&csv).unwrap();
    // 10 + 9 frames, 2 rows each, except one bad frame with 1 row.
    assert_eq!(rows.len(), 2 * 19 - 1);
    let bad: Vec<_> = rows
        .iter()
        .filter(|(m, _)| m.status == Status::BadFrame)
        .collect();
    assert_eq!(
        (bad.len(), bad[0].0.frame, bad[0].0.timestamp_s()),
        (1, 107, 1.07)
    );
    let ok = rows
        .iter()
        .find(|(m, _)| m.frame == 103 && m.camera == CameraId::Camera(1))
        .unwrap();
    assert_eq!(ok.0.position_mm, 103.0);
}
