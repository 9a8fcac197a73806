//! Per-frame processing time: every rod one camera sees in a 1440x1080 Bayer8 frame of the
//! simulated table, in enhanced and paper mode (criterion), and the enhanced mode on a camera
//! above the middle of the table that sees all 8 rods. The frames are a sequence of
//! gameplay (rods moving and turning at 200 fps), played forward and backward (see
//! [`ping_pong`]), so that what a tracker learns or reuses from frame to frame is exercised
//! as in a real run; the per-stage benchmarks run one
//! stage on one frame. The `ball` group measures the ball on frames of the `ball` scenario (a
//! ball rolling among the figures): the tracker while it follows the ball (a window around
//! the prediction), a full re-detection (the coarse scan of the whole field), and the whole
//! table state, every rod the camera sees plus the ball, per camera frame.
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rodtrack_core::ball::{BallStatus, BallTracker};
use rodtrack_core::calib::CameraCalibration;
use rodtrack_core::{CameraPipeline, FrameView, Mode, RodTracker, Stage};
use rodtrack_sim::{
    build_simulation, default_cameras, frame_time, RenderMode, Scenario, SceneConfig, SimCamera,
    Simulation,
};
use std::time::Duration;

/// Consecutive frames of the sequence.
const FRAMES: usize = 100;

/// The frame of iteration `i` over a sequence of `len` frames played forward, then backward,
/// then forward again (0, 1, .., len - 1, len - 2, .., 1, 0, 1, ..): every step is one frame's
/// motion (a rod or the ball reverses as in a bounce), never the jump from the last frame back
/// to the first, which would time a fresh search for a rod or the ball once per pass.
fn ping_pong(i: usize, len: usize) -> usize {
    let period = 2 * len.saturating_sub(1);
    if period == 0 {
        return 0;
    }
    let p = i % period;
    if p < len {
        p
    } else {
        period - p
    }
}

/// Frame width, height, stride and pixel format.
type Geometry = (usize, usize, usize, rodtrack_core::PixelFormat);

fn setup() -> (Vec<Vec<u8>>, CameraCalibration, Geometry) {
    setup_with(default_cameras())
}

/// One camera above the middle of the table, higher than the two reference cameras, that sees
/// all 8 rods (the "8-rod frame").
fn all_rods_camera() -> Vec<SimCamera> {
    vec![SimCamera::reference(
        "all",
        [600.0, 340.0, 1150.0],
        0.0,
        0.0,
        [-0.25, 0.08, 0.0, 0.0, 0.0],
    )]
}

fn setup_with(cameras: Vec<SimCamera>) -> (Vec<Vec<u8>>, CameraCalibration, Geometry) {
    let scene = SceneConfig::default();
    let sc = Scenario::by_name("gameplay", &scene, 7)
        .unwrap()
        .with_frames(25 + FRAMES);
    let mut sim = Simulation::new(scene, cameras, sc, RenderMode::Fast).unwrap();
    let cal = sim.calibrated_camera(0, 7).unwrap();
    let mut buf = vec![0u8; sim.frame_bytes(0).unwrap()];
    let mut frames = Vec::new();
    let mut meta = sim.render(25, 0, &mut buf).unwrap();
    for f in 25..25 + FRAMES {
        meta = sim.render(f, 0, &mut buf).unwrap();
        frames.push(buf.clone());
    }
    (
        frames,
        cal,
        (meta.width, meta.height, meta.stride, meta.format),
    )
}

/// The benchmark thread's CPU time: on a shared machine, unlike the wall time, it leaves out
/// the time the thread waited for a core.
struct CpuTime;

impl Measurement for CpuTime {
    type Intermediate = cpu_time::ThreadTime;
    type Value = Duration;
    fn start(&self) -> Self::Intermediate {
        cpu_time::ThreadTime::now()
    }
    fn end(&self, i: Self::Intermediate) -> Self::Value {
        i.elapsed()
    }
    fn add(&self, v1: &Self::Value, v2: &Self::Value) -> Self::Value {
        *v1 + *v2
    }
    fn zero(&self) -> Self::Value {
        Duration::ZERO
    }
    fn to_f64(&self, value: &Self::Value) -> f64 {
        value.as_nanos() as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &CpuFormatter
    }
}

struct CpuFormatter;

impl ValueFormatter for CpuFormatter {
    fn scale_values(&self, typical_ns: f64, values: &mut [f64]) -> &'static str {
        let (div, unit) = match typical_ns {
            t if t < 1e3 => (1.0, "ns cpu"),
            t if t < 1e6 => (1e3, "µs cpu"),
            _ => (1e6, "ms cpu"),
        };
        values.iter_mut().for_each(|v| *v /= div);
        unit
    }
    fn scale_throughputs(&self, _: f64, _: &Throughput, _: &mut [f64]) -> &'static str {
        "ns cpu"
    }
    fn scale_for_machines(&self, _: &mut [f64]) -> &'static str {
        "ns"
    }
}

fn per_frame(c: &mut Criterion) {
    per_frame_in(c, "per_frame");
}

fn per_frame_cpu(c: &mut Criterion<CpuTime>) {
    per_frame_in(c, "per_frame_cpu");
}

fn per_frame_in<M: Measurement>(c: &mut Criterion<M>, group: &str) {
    let mut g = c.benchmark_group(group);
    per_frame_cases(
        &mut g,
        setup(),
        &[("enhanced", Mode::Enhanced), ("paper", Mode::Paper)],
    );
    per_frame_cases(
        &mut g,
        setup_with(all_rods_camera()),
        &[("enhanced", Mode::Enhanced)],
    );
    g.finish();
}

fn per_frame_cases<M: Measurement>(
    g: &mut criterion::BenchmarkGroup<'_, M>,
    (frames, cal, (w, h, stride, fmt)): (Vec<Vec<u8>>, CameraCalibration, Geometry),
    modes: &[(&str, Mode)],
) {
    let views: Vec<FrameView> = frames
        .iter()
        .map(|b| FrameView::new(b, w, h, stride, fmt).unwrap())
        .collect();
    for &(name, mode) in modes {
        // What is timed must be measurements: the share of rows `ok` over one pass.
        let mut pipe = CameraPipeline::new(&cal, mode).unwrap();
        let (mut ok, mut all) = (0usize, 0usize);
        for (i, v) in views.iter().enumerate() {
            let mut rows = Vec::new();
            pipe.process(v, i as u64, rodtrack_core::Timestamp(0), &mut rows)
                .unwrap();
            ok += rows
                .iter()
                .filter(|r| r.status == rodtrack_core::Status::Ok)
                .count();
            all += rows.len();
        }
        eprintln!(
            "{name}, {} rods: {ok} of {all} rows ok over one pass",
            cal.rods.len()
        );
        let mut pipe = CameraPipeline::new(&cal, mode).unwrap();
        let mut rows = Vec::with_capacity(16);
        let mut i = 0;
        g.bench_function(format!("{name}_{}_rods", cal.rods.len()), |b| {
            b.iter(|| {
                rows.clear();
                pipe.process(
                    &views[ping_pong(i, FRAMES)],
                    i as u64,
                    rodtrack_core::Timestamp(0),
                    &mut rows,
                )
                .unwrap();
                i += 1;
                std::hint::black_box(&rows);
            })
        });
    }
}

/// Each stage of the enhanced mode alone, over every rod of the frame (on the intermediate
/// results of a full pass over the same frame).
fn per_stage(c: &mut Criterion) {
    let (frames, cal, (w, h, stride, fmt)) = setup();
    let views: Vec<FrameView> = frames
        .iter()
        .map(|b| FrameView::new(b, w, h, stride, fmt).unwrap())
        .collect();
    let mut rods: Vec<RodTracker> = cal
        .rods
        .iter()
        .map(|r| RodTracker::new(r, w, h, Mode::Enhanced).unwrap())
        .collect();
    for view in &views {
        for r in &mut rods {
            r.process(view).unwrap();
        }
    }
    let view = views[FRAMES - 1];
    let mut g = c.benchmark_group("per_stage");
    // Asking for every rod's strips of a new (cold) frame: what issuing the prefetches costs
    // (the lines then arrive while the rods are measured, so the memory's own cost shows in
    // `per_frame` only).
    let mut i = 0;
    g.bench_function(format!("prefetch_{}_rods", rods.len()), |b| {
        b.iter(|| {
            let v = &views[i % FRAMES];
            i += 1;
            let mut t = 0u8;
            for r in &rods {
                t ^= r.prefetch(v);
            }
            std::hint::black_box(t)
        })
    });
    for stage in Stage::ALL {
        g.bench_function(format!("{}_{}_rods", stage.name(), rods.len()), |b| {
            b.iter(|| {
                for r in &mut rods {
                    assert!(r.run_stage(&view, stage));
                }
            })
        });
    }
    g.finish();
}

/// Frames of the `ball` scenario (the first of `cameras`, or camera 0 of the reference table)
/// and that camera's calibration with the table frame and the ball's colour, from the
/// simulated clicks.
fn ball_setup(cameras: Option<Vec<SimCamera>>) -> (Vec<Vec<u8>>, CameraCalibration, Geometry) {
    let seed = 3;
    let mut sim = match cameras {
        None => build_simulation("ball", Some(FRAMES), seed, false, "default").unwrap(),
        Some(cameras) => {
            let scene = SceneConfig::default();
            let sc = Scenario::by_name("ball", &scene, seed)
                .unwrap()
                .with_frames(FRAMES);
            Simulation::new(scene, cameras, sc, RenderMode::Fast)
                .unwrap()
                .with_seed(seed)
        }
    };
    let cal = sim.calibrated_camera_with_ball(0, seed).unwrap();
    let mut buf = vec![0u8; sim.frame_bytes(0).unwrap()];
    let mut frames = Vec::new();
    let mut meta = sim.render(0, 0, &mut buf).unwrap();
    for f in 0..FRAMES {
        meta = sim.render(f, 0, &mut buf).unwrap();
        frames.push(buf.clone());
    }
    (
        frames,
        cal,
        (meta.width, meta.height, meta.stride, meta.format),
    )
}

/// The ball alone (following it, and a full re-detection) and the whole table state (the rods
/// and the ball) per camera frame.
fn ball(c: &mut Criterion) {
    ball_in(c, "ball");
}

fn ball_cpu(c: &mut Criterion<CpuTime>) {
    ball_in(c, "ball_cpu");
}

fn ball_in<M: Measurement>(c: &mut Criterion<M>, group: &str) {
    let (frames, cal, (w, h, stride, fmt)) = ball_setup(None);
    let views: Vec<FrameView> = frames
        .iter()
        .map(|b| FrameView::new(b, w, h, stride, fmt).unwrap())
        .collect();
    let mut tracker = BallTracker::new(&cal)
        .unwrap()
        .expect("the ball is calibrated");
    // The frames the tracker follows the ball in (status ok after a first pass over them):
    // the window search is what these time.
    let ok: Vec<usize> = (0..2 * FRAMES as u64)
        .map(|n| {
            let i = n as usize % FRAMES;
            (i, tracker.process(&views[i], n, frame_time(n, 200.0)))
        })
        .skip(FRAMES)
        .filter(|(_, row)| row.status == BallStatus::Ok)
        .map(|(i, _)| i)
        .collect();
    assert!(
        ok.len() > FRAMES / 2,
        "the ball is followed on {} of {FRAMES} frames",
        ok.len()
    );
    let mut g = c.benchmark_group(group);
    let mut i = 0;
    let mut frame = 2 * FRAMES as u64;
    // The `ok` frames are consecutive here (the tracker follows the ball on all 100): played
    // back and forth, each step is one frame's motion.
    g.bench_function("ball_tracking", |b| {
        b.iter(|| {
            let k = ok[ping_pong(i, ok.len())];
            i += 1;
            frame += 1;
            std::hint::black_box(tracker.process(&views[k], frame, frame_time(frame, 200.0)))
        })
    });
    let mut detector = tracker.detector().clone();
    let mut i = 0;
    g.bench_function("ball_redetection", |b| {
        b.iter(|| {
            let k = ok[i % ok.len()];
            i += 1;
            std::hint::black_box(detector.detect(&views[k], None))
        })
    });
    table_state(&mut g, &views, &cal);
    g.finish();
    // The whole table: the camera above the middle that sees all 8 rods, and the ball.
    let (frames, cal, (w, h, stride, fmt)) = ball_setup(Some(all_rods_camera()));
    let views: Vec<FrameView> = frames
        .iter()
        .map(|b| FrameView::new(b, w, h, stride, fmt).unwrap())
        .collect();
    let mut g = c.benchmark_group(group);
    table_state(&mut g, &views, &cal);
    g.finish();
}

/// Every rod the camera sees plus the ball, per camera frame, over `views` played back and
/// forth.
fn table_state<M: Measurement>(
    g: &mut criterion::BenchmarkGroup<'_, M>,
    views: &[FrameView],
    cal: &CameraCalibration,
) {
    let mut pipe = CameraPipeline::new(cal, Mode::Enhanced).unwrap();
    let mut tracker = BallTracker::new(cal)
        .unwrap()
        .expect("the ball is calibrated");
    let followed = (0..views.len())
        .filter(|&i| {
            tracker
                .process(&views[i], i as u64, frame_time(i as u64, 200.0))
                .status
                == BallStatus::Ok
        })
        .count();
    assert!(
        followed > views.len() / 2,
        "the ball is followed on {followed} of {} frames",
        views.len()
    );
    let mut rows = Vec::with_capacity(16);
    let mut i = views.len() as u64;
    g.bench_function(format!("table_{}_rods_and_ball", cal.rods.len()), |b| {
        b.iter(|| {
            let view = &views[ping_pong(i as usize, views.len())];
            rows.clear();
            pipe.process(view, i, rodtrack_core::Timestamp(0), &mut rows)
                .unwrap();
            let ball = tracker.process(view, i, frame_time(i, 200.0));
            i += 1;
            std::hint::black_box(rows.len());
            std::hint::black_box(ball)
        })
    });
}

criterion_group!(benches, per_frame, per_stage, ball);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = per_frame_cpu, ball_cpu
}
criterion_main!(benches, cpu);
