//! The session's run loop: every camera through the runtime pipeline, the filters and the
//! fusion, the ball trackers, and the monitor thread for progress and the stop flag.

use super::{pipeline_config, RunReport, Session, SessionCamera};
use crate::health::{CameraHealth, CountingSink};
use crate::hooks::{Hooks, Progress};
use crate::SdkError;
use rodtrack_core::{CameraFilter, CameraId, Measurement, SetFusion};
use rodtrack_io::runtime::{LatencyHistogram, Pipeline, PipelineCounters};
use rodtrack_io::source::SourceInfo;
use rodtrack_io::{FrameBuffer, FrameSource, MeasurementSink, SourceError};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Time spent in one camera's tracker, per frame.
#[derive(Default)]
struct ProcessTimes {
    total_ns: AtomicU64,
    frames: AtomicU64,
    bad: AtomicU64,
    histogram: Mutex<LatencyHistogram>,
}

/// A source that ends after `left` frames.
struct Limit {
    inner: Box<dyn FrameSource>,
    left: u64,
}

impl FrameSource for Limit {
    fn info(&self) -> SourceInfo {
        let mut i = self.inner.info();
        i.frame_count = Some(i.frame_count.map_or(self.left, |n| n.min(self.left)));
        i
    }
    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        self.inner.next_frame(buf)
    }
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings()
    }
}

/// The run loop of the whole project: every camera through the runtime pipeline.
pub(super) fn run_cameras<S: MeasurementSink + 'static>(
    session: Session,
    sink: S,
) -> Result<(RunReport, S), SdkError> {
    let Session {
        cameras,
        options,
        hooks,
        stop,
        control,
        mut ball,
    } = session;
    let live = cameras.iter().any(|c| c.source.info().live);
    let mut config = options.config.unwrap_or_else(|| pipeline_config(live));
    if let Some(write) = options.write {
        config.write = write;
    }
    let ncam = cameras.len();
    let max_frames = options.max_frames;
    let total = if live {
        None
    } else {
        cameras
            .iter()
            .map(|c| c.source.info().frame_count)
            .min()
            .flatten()
            .map(|n| max_frames.map_or(n, |m| n.min(m)))
    };
    let uses_frames = hooks.uses_frames();
    let mut pipeline = Pipeline::new(config);
    let mut times = Vec::new();
    let mut health = Vec::new();
    // The rows' counters: every camera's rods, then the fused ones.
    let mut keys: Vec<(CameraId, u32)> = Vec::new();
    let mut all_rods: Vec<u32> = Vec::new();
    for cam in &cameras {
        for r in cam.pipe.rods() {
            keys.push((CameraId::Camera(cam.pipe.index()), r.rod()));
            if !all_rods.contains(&r.rod()) {
                all_rods.push(r.rod());
            }
        }
    }
    let fused = options.filter && ncam > 1;
    if fused {
        keys.extend(all_rods.iter().map(|&r| (CameraId::Fused, r)));
    }
    for cam in cameras {
        let SessionCamera {
            label,
            source,
            mut pipe,
        } = cam;
        let cam_index = pipe.index();
        let source: Box<dyn FrameSource> = match max_frames {
            Some(left) => Box::new(Limit {
                inner: source,
                left,
            }),
            None => source,
        };
        let t = Arc::new(ProcessTimes::default());
        times.push(t.clone());
        let rods_health = Arc::new(CameraHealth::new(
            CameraId::Camera(cam_index),
            pipe.rods().iter().map(|r| r.rod()),
        ));
        health.push(rods_health.clone());
        let tracker_health = rods_health.clone();
        let h = hooks.clone();
        let mut ball_cam = ball.as_mut().and_then(|b| b.take(cam_index));
        let index = pipeline.add_camera(
            source,
            Box::new(move |meta, frame, rows| {
                let ts = meta.timestamp_ns;
                let start = Instant::now();
                let view = frame.as_ref().ok();
                // Every frame gets a ball row; one that could not be read, a prediction.
                let ball_row = ball_cam.as_mut().map(|b| {
                    let row = match view {
                        Some(v) => b.tracker.process(v, meta.frame_id, ts),
                        None => b.tracker.missed(meta.frame_id, ts),
                    };
                    (row, b.tracker.row_sigma_mm())
                });
                let result = match frame {
                    Ok(view) => pipe
                        .process(&view, meta.frame_id, ts, rows)
                        .map_err(|e| e.to_string()),
                    Err(e) => Err(e.to_string()),
                };
                let measured = result.is_ok();
                match result {
                    Ok(()) => {
                        let d = start.elapsed();
                        t.total_ns.fetch_add(d.as_nanos() as u64, Ordering::Relaxed);
                        t.frames.fetch_add(1, Ordering::Relaxed);
                        if let Ok(mut hist) = t.histogram.lock() {
                            hist.record(d);
                        }
                        tracker_health.record_tracker(&pipe);
                        h.measured(cam_index, meta, rows, &pipe);
                    }
                    Err(msg) => {
                        // Rows of a half-measured frame go; every rod is marked instead.
                        rows.clear();
                        pipe.bad_frame(meta.frame_id, ts, rows);
                        let n = t.bad.fetch_add(1, Ordering::Relaxed) + 1;
                        h.bad_frame(&label, meta.frame_id, &msg, n);
                    }
                }
                h.camera_rows(cam_index, meta, rows);
                // After the rods' rows, here and on a camera node's link: the events see a
                // frame's rod angles with its ball, in a session and at a fusion node alike.
                if let (Some(b), Some((row, sigma_mm))) = (ball_cam.as_ref(), ball_row) {
                    b.feed.push(row, sigma_mm, measured.then_some(&rows[..]));
                }
            }),
        );
        if uses_frames {
            let h = hooks.clone();
            pipeline
                .set_frame_hook(index, Box::new(move |buf| h.frame(cam_index, buf)))
                .map_err(|e| SdkError::Io {
                    context: "setting the frame hook".into(),
                    source: e,
                })?;
        }
        if options.filter {
            let mut f = if fused {
                CameraFilter::new(options.mode)
            } else {
                CameraFilter::alone(options.mode)
            };
            f.set_turn_anchors(&options.turn_anchors);
            let mut commands = control.follower(CameraId::Camera(cam_index), &options.turn_anchors);
            pipeline
                .set_camera_filter(
                    index,
                    Box::new(move |meta, rows, out| {
                        if let Some(anchors) = commands.poll(meta.frame_id) {
                            f.set_turn_anchors(anchors);
                        }
                        f.process(rows, out);
                        rods_health.record_turns(|rod| f.rod_turn_stats(rod));
                    }),
                )
                .map_err(|e| SdkError::Io {
                    context: "setting the camera filter".into(),
                    source: e,
                })?;
        }
    }
    if let Some(b) = ball.as_mut() {
        // From recordings the ball rows and events do not depend on the threads' timing: a
        // camera far ahead waits for the others (as long as a frame set would).
        b.start((!live).then_some(config.group_timeout));
    }
    let warnings = Arc::new(AtomicU64::new(0));
    if fused {
        let mut fusion = SetFusion::new(options.mode);
        fusion.set_turn_anchors(&options.turn_anchors);
        let mut commands = control.follower(CameraId::Fused, &options.turn_anchors);
        let fused_health = Arc::new(CameraHealth::new(CameraId::Fused, all_rods.clone()));
        health.push(fused_health.clone());
        let (h, count) = (hooks.clone(), warnings.clone());
        // The camera rows the fusion overruled, for the stage after it (same thread).
        let overruled = Arc::new(std::sync::Mutex::new(Vec::with_capacity(64)));
        let flags = overruled.clone();
        pipeline.set_camera_rows_after_fusion(Box::new(move |rows: &mut [Measurement]| {
            if let Ok(list) = flags.lock() {
                rodtrack_core::fusion::flag_overruled_rows(&list, rows);
            }
        }));
        pipeline.set_fusion(Box::new(move |set, raw, out| {
            if let Some(anchors) = commands.poll(set.frame_id) {
                fusion.set_turn_anchors(anchors);
            }
            fusion.process(raw, out);
            fused_health.record_turns(|rod| fusion.rod_turn_stats(rod));
            if let Ok(mut list) = overruled.lock() {
                list.clear();
                list.extend_from_slice(fusion.overruled());
            }
            let warn = |msg: String| h.warning(&msg, count.fetch_add(1, Ordering::Relaxed) + 1);
            for d in fusion.disagreements() {
                warn(format!(
                    "frame {}: rod {}: cameras {} and {} disagree by {:.2} mm / {:.3} rad",
                    d.frame,
                    d.rod,
                    d.cameras[0],
                    d.cameras[1],
                    d.position_diff_mm,
                    d.angle_diff_rad
                ));
            }
            for o in fusion.out_of_sync() {
                warn(format!(
                    "frame {}: camera {} out of sync by {:.2} ms",
                    o.frame,
                    o.camera,
                    o.offset_s * 1e3
                ));
            }
        }));
    }
    // The caller's stop flag is forwarded to the pipeline's by the monitor thread.
    let pipeline_stop = pipeline.stop_flag();
    let counters = pipeline.counters();
    let done = Arc::new(AtomicBool::new(false));
    let period = options.progress_period.unwrap_or(if total.is_some() {
        Duration::from_millis(250)
    } else {
        Duration::from_secs(1)
    });
    let monitor = {
        let (done, stop, times, hooks) = (done.clone(), stop.clone(), times.clone(), hooks);
        std::thread::Builder::new()
            .name("rodtrack-monitor".into())
            .spawn(move || {
                monitor(&Monitor {
                    done: &done,
                    stop: &stop,
                    pipeline_stop: &pipeline_stop,
                    counters: &counters,
                    times: &times,
                    total,
                    period,
                    hooks: &*hooks,
                })
            })
            .map_err(|e| SdkError::Runtime(format!("cannot start the monitor thread: {e}")))?
    };
    let result = pipeline.run_direct(CountingSink::new(sink, keys));
    done.store(true, Ordering::SeqCst);
    let _ = monitor.join();
    let (report, sink) = result.map_err(|e| SdkError::Io {
        context: "running the pipeline".into(),
        source: e,
    })?;
    let tracker = times
        .iter()
        .map(|t| t.histogram.lock().map(|h| h.summary()).unwrap_or_default())
        .collect();
    let rods = crate::health::merge(&health, &sink);
    let ball_counts = ball.as_ref().map(|b| b.finish()).transpose()?;
    let events = match ball.as_ref() {
        Some(b) => b.finish_events()?,
        None => None,
    };
    Ok((
        RunReport {
            pipeline: report,
            tracker,
            config,
            warnings: warnings.load(Ordering::Relaxed),
            rods,
            ball: ball_counts,
            events,
        },
        sink.inner,
    ))
}

/// What the monitor thread watches.
struct Monitor<'a> {
    done: &'a AtomicBool,
    stop: &'a AtomicBool,
    pipeline_stop: &'a AtomicBool,
    counters: &'a PipelineCounters,
    times: &'a [Arc<ProcessTimes>],
    total: Option<u64>,
    period: Duration,
    hooks: &'a dyn Hooks,
}

/// Forwards the stop flag to the pipeline and calls the progress hook until `done`.
fn monitor(m: &Monitor<'_>) {
    let tick = Duration::from_millis(20);
    let started = Instant::now();
    let mut last = Instant::now();
    let sum = |f: &dyn Fn(&ProcessTimes) -> u64| m.times.iter().map(|t| f(t)).sum::<u64>();
    while !m.done.load(Ordering::SeqCst) {
        std::thread::sleep(tick);
        if m.stop.load(Ordering::SeqCst) {
            m.pipeline_stop.store(true, Ordering::SeqCst);
        }
        if last.elapsed() < m.period {
            continue;
        }
        last = Instant::now();
        let c = m.counters;
        let progress = Progress {
            sets: c.sets_complete.load(Ordering::Relaxed)
                + c.sets_incomplete.load(Ordering::Relaxed),
            total: m.total,
            frames: c
                .cameras
                .iter()
                .map(|c| c.frames_processed.load(Ordering::Relaxed))
                .sum(),
            measured: sum(&|t| t.frames.load(Ordering::Relaxed)),
            tracker_time: Duration::from_nanos(sum(&|t| t.total_ns.load(Ordering::Relaxed))),
            dropped: c
                .cameras
                .iter()
                .map(|c| c.frames_dropped.load(Ordering::Relaxed))
                .sum(),
            bad: sum(&|t| t.bad.load(Ordering::Relaxed)),
            cameras: m.times.len(),
            elapsed: started.elapsed(),
        };
        m.hooks.progress(&progress);
    }
}
