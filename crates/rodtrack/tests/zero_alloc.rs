//! The per-frame hot path allocates nothing: a counting global allocator watches both cameras'
//! pipelines (every rod, enhanced and paper mode), the filter + fusion and each camera's ball
//! tracker and the ball's event detector over simulated gameplay frames (the ball rolls and is
//! kicked among the figures), after a warm-up in which the output vectors reach their size.
//!
//! This file holds a single test, so no other test's allocations can be counted.
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_core::ball::events::{EventConfig, EventDetector, TableGeometry};
use rodtrack_core::ball::{BallStatus, BallTracker};
use rodtrack_core::calib::CameraCalibration;
use rodtrack_core::{CameraPipeline, FrameSetFilter, FrameView, Mode};
use rodtrack_sim::{default_cameras, RenderMode, Scenario, SceneConfig, Simulation};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

/// The system allocator, counting the allocations of threads that armed it.
struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
}

fn count() {
    // `try_with`: the thread-local may be gone while a thread shuts down.
    if ARMED.try_with(|a| a.get()).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

// SAFETY: every call is forwarded unchanged to the system allocator; the counting touches no
// allocation.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as ours.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as ours.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as ours.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as ours.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made by `f` on this thread.
fn allocations_in(f: impl FnOnce()) -> u64 {
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    ARMED.with(|a| a.set(true));
    f();
    ARMED.with(|a| a.set(false));
    ALLOCATIONS.load(Ordering::Relaxed) - before
}

struct Camera {
    frames: Vec<Vec<u8>>,
    geometry: (usize, usize, usize, rodtrack_core::PixelFormat),
    calibration: CameraCalibration,
    /// With the table frame and the ball's colour.
    ball_calibration: CameraCalibration,
}

fn cameras(frames: usize) -> Vec<Camera> {
    let scene = SceneConfig::default();
    let sc = Scenario::by_name("gameplay", &scene, 11)
        .unwrap()
        .with_frames(frames);
    let mut sim = Simulation::new(scene, default_cameras(), sc, RenderMode::Fast).unwrap();
    (0..sim.cameras().len())
        .map(|cam| {
            let calibration = sim.calibrated_camera(cam, 11).unwrap();
            let ball_calibration = sim.calibrated_camera_with_ball(cam, 11).unwrap();
            let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
            let meta = sim.render_reference(cam, &mut buf).unwrap();
            let frames = (0..frames)
                .map(|f| {
                    sim.render(f, cam, &mut buf).unwrap();
                    buf.clone()
                })
                .collect();
            Camera {
                frames,
                geometry: (meta.width, meta.height, meta.stride, meta.format),
                calibration,
                ball_calibration,
            }
        })
        .collect()
}

#[test]
fn per_frame_processing_allocates_nothing() {
    let n = 240;
    let warm_up = 40;
    let cams = cameras(n);
    for mode in [Mode::Enhanced, Mode::Paper] {
        let mut pipes: Vec<CameraPipeline> = cams
            .iter()
            .map(|c| CameraPipeline::new(&c.calibration, mode).unwrap())
            .collect();
        let mut balls: Vec<BallTracker> = cams
            .iter()
            .map(|c| BallTracker::new(&c.ball_calibration).unwrap().unwrap())
            .collect();
        let mut ball_ok = 0usize;
        let mut events =
            EventDetector::new(TableGeometry::reference(), EventConfig::default()).unwrap();
        let mut decided = Vec::with_capacity(16);
        let mut filter = FrameSetFilter::new(mode, true);
        let mut raw = Vec::with_capacity(64);
        let mut filtered = Vec::with_capacity(64);
        let mut ok_rows = 0usize;
        let mut step = |f: usize| {
            raw.clear();
            filtered.clear();
            decided.clear();
            for (i, ((pipe, ball), cam)) in pipes.iter_mut().zip(&mut balls).zip(&cams).enumerate()
            {
                let (w, h, stride, fmt) = cam.geometry;
                let view = FrameView::new(&cam.frames[f], w, h, stride, fmt).unwrap();
                let t = rodtrack_core::Timestamp::from_frame(f as u64, 200.0);
                pipe.process(&view, f as u64, t, &mut raw).unwrap();
                let row = ball.process(&view, f as u64, t);
                ball_ok += (row.status == BallStatus::Ok) as usize;
                if i == 0 {
                    events.push(&row, &mut decided);
                }
            }
            // The rods' angles for the shot's rod, as the session gives them.
            for m in raw.iter().filter(|m| m.status == rodtrack_core::Status::Ok) {
                events.push_rod_angle(m.rod, m.timestamp_ns, m.angle_rad);
            }
            filter.process(&raw, &mut filtered);
            ok_rows += raw
                .iter()
                .filter(|m| m.status == rodtrack_core::Status::Ok)
                .count();
        };
        for f in 0..warm_up {
            step(f);
        }
        let allocations = allocations_in(|| {
            for f in warm_up..n {
                step(f);
            }
        });
        // The rows were really measured (the pipelines did their work).
        assert!(
            ok_rows > (n * 12) * 9 / 10,
            "{mode:?}: only {ok_rows} ok rows"
        );
        // The ball was really followed (gameplay shows it on most frames).
        assert!(
            ball_ok > n / 2,
            "{mode:?}: ball ok on {ball_ok} camera frames"
        );
        assert_eq!(
            allocations,
            0,
            "{mode:?}: {allocations} allocations in {} frame sets",
            n - warm_up
        );
    }
}
