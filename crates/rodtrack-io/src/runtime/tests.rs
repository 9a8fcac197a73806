//! The hand-off, output and write modes: same rows whatever the threads, per-camera writes in
//! order, gaps counted, clean stops. (The default mode is tested in `tests/runtime.rs`.)
#![allow(clippy::unwrap_used)]

#[path = "../../tests/common/runtime_fakes.rs"]
mod runtime_fakes;

use super::*;
use crate::CsvSink;
use rodtrack_core::{CameraId, Status};
use runtime_fakes::{tracker, Fake, Writes};

/// A camera filter that writes positions times 10 (so that written and measured rows differ).
fn times_ten() -> CameraFilterFn {
    Box::new(|_meta, rows, out| {
        out.extend(rows.iter().map(|m| Measurement {
            position_mm: m.position_mm * 10.0,
            ..*m
        }))
    })
}

/// One fused row per set: the sum of the measured positions, and the number of cameras.
fn fusion() -> FusionFn {
    Box::new(|set, rows, out| {
        let mut m = Measurement::empty(
            set.frame_id,
            set.timestamp_ns,
            CameraId::Fused,
            0,
            Status::Ok,
        );
        m.position_mm = rows.iter().map(|r| r.position_mm).sum();
        m.quality = set.frames.iter().flatten().count() as f64;
        out.push(m);
    })
}

/// Two cameras of 60 frames (camera 1 misses frame 7, camera 0's frame 11 is bad), camera 0
/// with the filter, the fusion.
fn two_camera_pipeline(config: PipelineConfig) -> Pipeline {
    let mut p = Pipeline::new(config);
    let mut a = Fake::new(0..60);
    a.bad.insert(11);
    p.add_camera(Box::new(a), tracker(Duration::ZERO));
    p.add_camera(
        Box::new(Fake::new((0..60).filter(|i| *i != 7))),
        tracker(Duration::ZERO),
    );
    p.set_camera_filter(0, times_ten()).unwrap();
    p.set_fusion(fusion());
    p
}

/// [`two_camera_pipeline`] run by the calling thread or directly.
fn two_cameras(config: PipelineConfig, direct: bool) -> (PipelineReport, Vec<Vec<Measurement>>) {
    let p = two_camera_pipeline(config);
    if direct {
        let (r, sink) = p.run_direct(Writes::default()).unwrap();
        (r, sink.0)
    } else {
        let mut sink = Writes::default();
        let r = p.run(&mut sink).unwrap();
        (r, sink.0)
    }
}

#[test]
fn every_handoff_output_and_spin_writes_the_same_sets() {
    let (reference, ref_writes) = two_cameras(PipelineConfig::default(), false);
    assert_eq!(ref_writes.len(), 60);
    assert_eq!(
        (reference.sets_complete, reference.sets_incomplete),
        (59, 1)
    );
    // Frame 3: camera 0's rows filtered (x10), camera 1's measured, the fusion of the measured.
    let set3: Vec<(CameraId, f64)> = ref_writes[3]
        .iter()
        .map(|m| (m.camera, m.position_mm))
        .collect();
    let (c0, c1) = (CameraId::Camera(0), CameraId::Camera(1));
    assert_eq!(
        set3,
        [
            (c0, 30.0),
            (c0, 40.0),
            (c1, 3.0),
            (c1, 4.0),
            (CameraId::Fused, 14.0)
        ]
    );
    // Frame 7 without camera 1, frame 11 with camera 0's bad-frame row.
    assert_eq!(ref_writes[7].len(), 3);
    assert_eq!(ref_writes[7][2].quality, 1.0);
    assert_eq!(ref_writes[11][0].status, Status::BadFrame);
    for handoff in [Handoff::Queue, Handoff::Inline] {
        for spin in [Duration::ZERO, Duration::from_micros(50)] {
            for direct in [false, true] {
                let config = PipelineConfig {
                    handoff,
                    spin,
                    ..Default::default()
                };
                let (r, writes) = two_cameras(config, direct);
                let what = format!("{handoff:?}, spin {spin:?}, direct {direct}");
                assert!(writes == ref_writes, "{what}: other writes");
                assert_eq!(r.rows_written, reference.rows_written, "{what}");
                assert_eq!(r.cameras[1].missing_in_sets, 1, "{what}");
                assert_eq!(r.cameras[0].bad_frames, 1, "{what}");
                assert_eq!(r.latency.count, 119, "{what}");
                assert_eq!(r.set_last_latency.count, 60, "{what}");
            }
        }
    }
}

#[test]
fn per_camera_writes_come_first_and_the_fusion_after_the_set() {
    for handoff in [Handoff::Queue, Handoff::Inline] {
        let config = PipelineConfig {
            handoff,
            write: WriteMode::PerCamera,
            ..Default::default()
        };
        let (r, writes) = two_cameras(config, true);
        let what = format!("{handoff:?}");
        // 60 + 59 camera frames, 60 fused rows, each in its own write.
        assert_eq!(writes.len(), 60 + 59 + 60, "{what}");
        let mut seen: Vec<Vec<u64>> = vec![Vec::new(); 2];
        for w in &writes {
            let first = w[0];
            assert!(w
                .iter()
                .all(|m| m.frame == first.frame && m.camera == first.camera));
            match first.camera {
                CameraId::Camera(c) => {
                    // Camera 0's rows are the filter's.
                    if c == 0 && first.status == Status::Ok {
                        assert_eq!(first.position_mm, 10.0 * (first.frame % 256) as f64);
                    }
                    seen[c as usize].push(first.frame);
                }
                CameraId::Fused => {
                    // After the rows of every camera present, and the fusion of measured rows.
                    let f = first.frame;
                    assert!(seen[0].contains(&f), "{what}: fused {f} before camera 0");
                    if f != 7 {
                        assert!(seen[1].contains(&f), "{what}: fused {f} before camera 1");
                    }
                    let expect = if f == 7 {
                        15.0
                    } else if f == 11 {
                        // Camera 0's bad-frame row has position 0.
                        23.0
                    } else {
                        (4 * f + 2) as f64
                    };
                    assert_eq!(first.position_mm, expect, "{what}: frame {f}");
                }
            }
        }
        let want: Vec<u64> = (0..60).collect();
        assert_eq!(seen[0], want, "{what}: camera 0 in frame order");
        let want: Vec<u64> = (0..60).filter(|i| *i != 7).collect();
        assert_eq!(seen[1], want, "{what}: camera 1 in frame order");
        assert_eq!((r.sets_complete, r.sets_incomplete), (59, 1), "{what}");
        assert_eq!(r.rows_written, 2 * 119 - 1 + 60, "{what}");
        assert_eq!(r.latency.count, 119, "{what}");
        assert_eq!(r.set_latency.count, 119, "{what}");
        assert_eq!(r.set_last_latency.count, 60, "{what}");
        assert_eq!(r.stages.process.count, 119, "{what}");
    }
}

#[test]
fn inline_live_counts_what_the_source_skipped_and_drops_nothing() {
    let config = PipelineConfig {
        mode: RunMode::Live,
        handoff: Handoff::Inline,
        write: WriteMode::PerCamera,
        ..Default::default()
    };
    let mut p = Pipeline::new(config);
    let ids = (0..50).filter(|i| !(10..14).contains(i) && *i != 30);
    p.add_camera(Box::new(Fake::new(ids)), tracker(Duration::ZERO));
    let (r, sink) = p.run_direct(Writes::default()).unwrap();
    let c = &r.cameras[0];
    assert_eq!(
        (
            c.frames_read,
            c.frames_processed,
            c.frames_dropped,
            c.frames_skipped
        ),
        (45, 45, 0, 5)
    );
    assert_eq!(sink.0.len(), 45);
    assert!(r.to_string().contains("5 skipped by the source"), "{r}");
}

#[test]
fn a_stalled_camera_does_not_hold_back_the_others_rows() {
    let config = PipelineConfig {
        mode: RunMode::Live,
        handoff: Handoff::Inline,
        write: WriteMode::PerCamera,
        group_timeout: Duration::from_millis(30),
        ..Default::default()
    };
    let mut p = Pipeline::new(config);
    let mut a = Fake::new(0..30);
    a.delay = Duration::from_millis(2);
    let mut b = Fake::new(0..30);
    b.delay = Duration::from_millis(2);
    b.stall = Some((10, Duration::from_millis(300)));
    p.add_camera(Box::new(a), tracker(Duration::ZERO));
    p.add_camera(Box::new(b), tracker(Duration::ZERO));
    p.set_fusion(fusion());
    let (r, sink) = p.run_direct(Writes::default()).unwrap();
    let rows: Vec<&Measurement> = sink.0.iter().flatten().collect();
    for cam in [0, 1] {
        let ids: Vec<u64> = rows
            .iter()
            .filter(|m| m.camera == CameraId::Camera(cam) && m.rod == 0)
            .map(|m| m.frame)
            .collect();
        assert_eq!(ids, (0..30).collect::<Vec<_>>(), "camera {cam}");
    }
    // Camera 0 ran ahead: its sets were emitted without camera 1, whose late frames then went
    // out on their own, not fused again; every set's fusion was written, once per frame.
    assert!(r.sets_incomplete >= 2, "{r}");
    assert!(r.cameras[1].missing_in_sets >= 1, "{r}");
    assert!(r.cameras[1].frames_late >= 1, "{r}");
    assert_eq!(r.cameras[0].frames_late, 0, "{r}");
    let fused: Vec<u64> = rows
        .iter()
        .filter(|m| m.camera == CameraId::Fused)
        .map(|m| m.frame)
        .collect();
    assert_eq!(
        fused,
        (0..30).collect::<Vec<_>>(),
        "one fused row per frame"
    );
    assert_eq!(fused.len() as u64, r.sets_complete + r.sets_incomplete);
    assert_eq!(r.rows_written, rows.len() as u64);
}

#[test]
fn run_direct_stops_cleanly_and_returns_the_flushed_sink() {
    for handoff in [Handoff::Queue, Handoff::Inline] {
        let config = PipelineConfig {
            mode: RunMode::Live,
            handoff,
            ..Default::default()
        };
        let mut p = Pipeline::new(config);
        for _ in 0..2 {
            let mut src = Fake::new(0..);
            src.delay = Duration::from_millis(1);
            p.add_camera(Box::new(src), tracker(Duration::ZERO));
        }
        let stop = p.stop_flag();
        let live = p.counters();
        let watcher = std::thread::spawn(move || {
            while live.cameras[0].frames_processed.load(Ordering::Relaxed) < 20 {
                std::thread::sleep(Duration::from_millis(5));
            }
            stop.store(true, Ordering::Relaxed);
        });
        let mut csv = CsvSink::new(Vec::new(), "memory").unwrap();
        csv.set_flush_each_write(false);
        let (r, csv) = p.run_direct(csv).unwrap();
        watcher.join().unwrap();
        assert!(r.stopped);
        for c in &r.cameras {
            assert_eq!(
                c.frames_read,
                c.frames_processed + c.frames_dropped,
                "{c:?}"
            );
        }
        let text = String::from_utf8(csv.into_inner().unwrap()).unwrap();
        let rows = crate::sink::parse_measurements_csv(&text, "memory".as_ref()).unwrap();
        let processed: u64 = r.cameras.iter().map(|c| c.frames_processed).sum();
        assert_eq!(rows.len() as u64, r.rows_written, "{handoff:?}");
        assert_eq!(r.rows_written, 2 * processed, "{handoff:?}");
    }
}

#[test]
fn a_filter_for_a_camera_not_added_is_an_error() {
    let mut p = Pipeline::new(PipelineConfig::default());
    p.add_camera(Box::new(Fake::new(0..1)), tracker(Duration::ZERO));
    assert!(p.set_camera_filter(1, times_ten()).is_err());
    assert!(p.set_camera_filter(0, times_ten()).is_ok());
}

/// The frame hook sees every frame that was read whole (not the bad one), after it was
/// measured, and may keep its pixels: it swaps the buffer's bytes with a vector of its own, as
/// the console's live view does. The rows are those of a run without the hook, and every frame
/// the hook kept holds that frame's pixels.
#[test]
fn a_frame_hook_may_keep_the_frames_pixels() {
    let (_, plain) = two_cameras(PipelineConfig::default(), false);
    let kept = Arc::new(Mutex::new(Vec::<(u64, u8)>::new()));
    let mut p = two_camera_pipeline(PipelineConfig::default());
    let log = kept.clone();
    let mut mine: Vec<u8> = Vec::new();
    p.set_frame_hook(
        0,
        Box::new(move |buf| {
            std::mem::swap(&mut mine, &mut buf.data);
            // What a live view would hold: this frame's pixels.
            log.lock().unwrap().push((buf.meta.frame_id, mine[0]));
        }),
    )
    .unwrap();
    assert!(p.set_frame_hook(2, Box::new(|_| {})).is_err());
    let mut sink = Writes::default();
    p.run(&mut sink).unwrap();
    assert_eq!(sink.0, plain, "the hook changed the rows");
    let kept = kept.lock().unwrap();
    let ids: Vec<u64> = kept.iter().map(|k| k.0).collect();
    assert_eq!(ids, (0..60).filter(|i| *i != 11).collect::<Vec<_>>());
    assert!(kept.iter().all(|&(id, px)| px == (id % 256) as u8));
}
