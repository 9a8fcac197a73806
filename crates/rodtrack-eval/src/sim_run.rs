//! The built-in simulator's cameras through an SDK [`Session`], as `demo` and `evaluate` run
//! them: the rows sorted by kind (each camera's raw rows, filtered rows, fused rows), and the
//! paper's algorithm on the same frames alongside when asked.

use crate::{EvalError, Result};
use rodtrack_core::calib::{CalibrationFile, CameraCalibration};
use rodtrack_core::{CameraId, CameraPipeline, Measurement, Mode};
use rodtrack_io::{FrameBuffer, FrameMeta, IoError, MeasurementSink};
use rodtrack_sdk::{Hooks, Progress, RunReport, Session, SessionCamera, SessionOptions};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What to run.
pub struct SimRun<'a> {
    /// The simulation (its frames are rendered by the sources, in the session's threads).
    pub sim: &'a rodtrack_sim::Simulation,
    /// Every `every`-th frame only.
    pub every: usize,
    /// Also the paper's algorithm on the same frames.
    pub paper: bool,
    /// Makes extra hooks for the session's cameras (a web console, ...): [`Hooks::measured`],
    /// [`Hooks::frame`] (after the paper's tracker: the extra hooks may take the frame's
    /// buffer) and [`Hooks::progress`] are passed on to them.
    pub hooks: Option<HooksFactory>,
    /// Called with every write of filtered rows (each camera's, then the fused ones) and the
    /// latest progress.
    pub on_rows: Option<RowsCallback>,
    /// Also the ball and its events ([`Session::with_ball`], [`Session::with_events`]).
    pub ball: Option<BallRun<'a>>,
}

/// See [`SimRun::ball`].
pub struct BallRun<'a> {
    /// The calibration with the cameras' table frame and ball.
    pub cal: &'a CalibrationFile,
    /// Where the ball's rows go.
    pub rows: Box<dyn rodtrack_io::BallSink>,
    /// Where its events go (default rules).
    pub events: Box<dyn rodtrack_io::EventSink>,
}

/// See [`SimRun::hooks`]: given the session's cameras before it starts.
pub type HooksFactory = Box<dyn FnOnce(&[SessionCamera]) -> Arc<dyn Hooks>>;

/// See [`SimRun::on_rows`].
pub type RowsCallback = Box<dyn FnMut(&[Measurement], &Progress) + Send>;

/// The rows of a run, by kind.
#[derive(Debug, Default)]
pub struct SimRows {
    /// Each camera's raw rows (enhanced mode).
    pub raw: Vec<Measurement>,
    /// Each camera's rows through its temporal filter.
    pub filtered: Vec<Measurement>,
    /// The fused rows (several cameras).
    pub fused: Vec<Measurement>,
    /// The paper's algorithm's raw rows.
    pub paper: Vec<Measurement>,
    /// Time in the paper's tracker per camera frame, us.
    pub paper_us: Vec<f64>,
}

/// The paper's tracker of each camera, run by the frame hook.
struct Hooked {
    rows: Mutex<SimRows>,
    paper: Vec<Mutex<Option<CameraPipeline>>>,
    extra: Option<Arc<dyn Hooks>>,
    progress: Mutex<Progress>,
}

impl Hooks for Hooked {
    fn measured(&self, camera: u32, meta: &FrameMeta, rows: &[Measurement], pipe: &CameraPipeline) {
        if let Ok(mut r) = self.rows.lock() {
            r.raw.extend_from_slice(rows);
        }
        if let Some(h) = &self.extra {
            h.measured(camera, meta, rows, pipe);
        }
    }
    fn uses_frames(&self) -> bool {
        self.extra.as_ref().is_some_and(|h| h.uses_frames())
            || self
                .paper
                .iter()
                .any(|p| p.lock().is_ok_and(|p| p.is_some()))
    }
    fn frame(&self, camera: u32, buf: &mut FrameBuffer) {
        let paper = self.paper.get(camera as usize).and_then(|p| p.lock().ok());
        if let (Some(mut paper), Ok(view)) = (paper, buf.view()) {
            if let Some(p) = paper.as_mut() {
                let mut rows = Vec::new();
                let t = Instant::now();
                let ts = buf.meta.timestamp_ns;
                if p.process(&view, buf.meta.frame_id, ts, &mut rows).is_ok() {
                    let us = t.elapsed().as_secs_f64() * 1e6;
                    if let Ok(mut r) = self.rows.lock() {
                        r.paper.extend_from_slice(&rows);
                        r.paper_us.push(us);
                    }
                }
            }
        }
        // Last: the extra hooks may take the frame's buffer.
        if let Some(h) = &self.extra {
            h.frame(camera, buf);
        }
    }
    fn progress(&self, p: &Progress) {
        if let Some(h) = &self.extra {
            h.progress(p);
        }
        if let Ok(mut last) = self.progress.lock() {
            *last = p.clone();
        }
    }
}

/// The session's sink: the filtered and fused rows kept and passed on.
struct Collect {
    hooked: Arc<Hooked>,
    on_rows: Option<RowsCallback>,
}

impl MeasurementSink for Collect {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        if let Ok(mut r) = self.hooked.rows.lock() {
            for m in rows {
                if m.camera == CameraId::Fused {
                    r.fused.push(*m);
                } else {
                    r.filtered.push(*m);
                }
            }
        }
        if let Some(f) = self.on_rows.as_mut() {
            let p = self
                .hooked
                .progress
                .lock()
                .map(|p| p.clone())
                .unwrap_or_default();
            f(rows, &p);
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

/// The cameras of `sim`, calibrated as `cals`, as session cameras (enhanced mode) whose sources
/// deliver the frames as `playback` says.
pub fn sim_cameras(
    sim: &rodtrack_sim::Simulation,
    cals: &[CameraCalibration],
    playback: rodtrack_sim::Playback,
) -> Result<Vec<SessionCamera>> {
    let sources = rodtrack_sim::SimSource::for_simulation(sim, playback)?;
    let mut cameras = Vec::new();
    for (cal, source) in cals.iter().zip(sources) {
        cameras.push(SessionCamera {
            label: format!("camera {} ({})", cal.index, cal.name),
            source: Box::new(source),
            pipe: CameraPipeline::new(cal, Mode::Enhanced)?,
        });
    }
    Ok(cameras)
}

/// Runs the simulated cameras calibrated as `cals` through a session (enhanced mode, the
/// temporal filter and the fusion); returns the rows and the session's report.
pub fn run_sim(cals: &[CameraCalibration], run: SimRun<'_>) -> Result<(SimRows, RunReport)> {
    let playback = rodtrack_sim::Playback {
        every: run.every,
        ..Default::default()
    };
    let cameras = sim_cameras(run.sim, cals, playback)?;
    let hooked = Arc::new(Hooked {
        rows: Mutex::new(SimRows::default()),
        // The paper's mode needs its per-rod parameters; a camera without them gives no rows.
        paper: cals
            .iter()
            .map(|c| {
                Mutex::new(
                    run.paper
                        .then(|| CameraPipeline::new(c, Mode::Paper).ok())
                        .flatten(),
                )
            })
            .collect(),
        extra: run.hooks.map(|make| make(&cameras)),
        progress: Mutex::new(Progress::default()),
    });
    let options = SessionOptions {
        progress_period: Some(Duration::from_millis(100)),
        ..SessionOptions::default()
    };
    let sink = Collect {
        hooked: hooked.clone(),
        on_rows: run.on_rows,
    };
    let mut session = Session::from_cameras(cameras, options).with_hooks(hooked.clone());
    if let Some(b) = run.ball {
        session =
            session
                .with_ball(b.cal, b.rows)?
                .with_events(b.cal, Default::default(), b.events)?;
    }
    let (report, sink) = session.run(sink)?;
    drop(sink);
    let mut rows = match Arc::try_unwrap(hooked) {
        Ok(h) => h.rows.into_inner().unwrap_or_default(),
        Err(h) => std::mem::take(
            &mut *h
                .rows
                .lock()
                .map_err(|_| EvalError::Failed("rows lock poisoned".into()))?,
        ),
    };
    // The cameras' threads append in whatever order they run: sorted, the rows (and every
    // sum over them) are the same from run to run.
    let key = |m: &Measurement| {
        let camera = match m.camera {
            CameraId::Camera(c) => c,
            CameraId::Fused => u32::MAX,
        };
        (m.frame, camera, m.rod)
    };
    for v in [
        &mut rows.raw,
        &mut rows.filtered,
        &mut rows.fused,
        &mut rows.paper,
    ] {
        v.sort_by_key(key);
    }
    Ok((rows, report))
}
