//! `open` and `Session`: cameras through the SDK's session in a background thread; frame sets
//! iterated from Python.

use super::calibration::PyCalibration;
use super::errors::{to_py, SessionClosed};
use crate::columns::{BallColumns, Columns, PyBallRows, PyRows};
use crate::stream::{BallShare, FrameSet, Next, Stream};
use pyo3::prelude::*;
use rodtrack_core::CameraId;
use rodtrack_sdk::{RunReport, Session, SessionOptions};
use std::sync::Mutex;
use std::time::Duration;

/// How long a wait for the next frame set lasts before Python's signals (Ctrl-C) are checked.
const POLL: Duration = Duration::from_millis(50);

/// The rows of one frame set: every camera's rows for one frame id and the fused rows.
#[pyclass(module = "rodtrack", name = "FrameSet", frozen)]
pub struct PyFrameSet {
    set: FrameSet,
    cameras: usize,
}

#[pymethods]
impl PyFrameSet {
    /// The frame id.
    #[getter]
    fn frame(&self) -> u64 {
        self.set.frame
    }

    /// Every row of the set, in the order a CSV file gets them: camera 0's rows, camera 1's,
    /// ..., then the fused rows.
    #[getter]
    fn rows(&self) -> PyRows {
        PyRows {
            cols: Columns::of(&self.set.rows),
        }
    }

    /// The fused rows, one per rod: the state a control program wants. With one camera (no
    /// fusion) or without the filter, that camera's rows.
    #[getter]
    fn fused(&self) -> PyRows {
        let fused = self.set.rows.iter().filter(|m| m.camera == CameraId::Fused);
        if self.cameras > 1 && fused.clone().next().is_some() {
            return PyRows {
                cols: Columns::of(fused),
            };
        }
        PyRows {
            cols: Columns::of(
                self.set
                    .rows
                    .iter()
                    .filter(|m| m.camera == CameraId::Camera(0)),
            ),
        }
    }

    /// Camera ``index``'s rows of the set.
    fn camera(&self, index: u32) -> PyRows {
        PyRows {
            cols: Columns::of(
                self.set
                    .rows
                    .iter()
                    .filter(|m| m.camera == CameraId::Camera(index)),
            ),
        }
    }

    /// The ball's rows the set carries (``open(..., ball=True)``): this frame's, each
    /// camera's then the fused one, after the rows of older frames that came late (a camera
    /// behind); empty without the ball.
    #[getter]
    fn ball(&self) -> PyBallRows {
        PyBallRows {
            cols: BallColumns::of(&self.set.ball),
        }
    }

    /// The ball's state of the table for this frame: its fused row (with one camera, the
    /// camera's row); empty without the ball or when the set carries no row of its frame.
    #[getter]
    fn ball_fused(&self) -> PyBallRows {
        let want = if self.cameras > 1 {
            CameraId::Fused
        } else {
            CameraId::Camera(0)
        };
        PyBallRows {
            cols: BallColumns::of(
                self.set
                    .ball
                    .iter()
                    .filter(|b| b.frame == self.set.frame && b.camera == want),
            ),
        }
    }

    /// The ball's events decided since the previous set (``open(..., events=True)``), each
    /// a dict as a line of ``rodtrack track --events-out``: ``frame``, ``timestamp_s``,
    /// ``event`` (``goal``, ``shot``, ``ball_out``, ``ball_stopped``) and its fields.
    #[getter]
    fn events<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        events_as_dicts(py, &self.set.events)
    }

    fn __len__(&self) -> usize {
        self.set.rows.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "FrameSet(frame={}, rows={}, ball rows={}, events={})",
            self.set.frame,
            self.set.rows.len(),
            self.set.ball.len(),
            self.set.events.len()
        )
    }
}

/// Events as dicts, each as a line of `--events-out` read by Python's `json`.
pub(super) fn events_as_dicts<'py>(
    py: Python<'py>,
    events: &[rodtrack_core::ball::events::BallEvent],
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let json = py.import("json")?;
    events
        .iter()
        .map(|e| json.call_method1("loads", (e.json_line(),)))
        .collect()
}

/// A running session: iterate it for its frame sets; use it as a context manager (``with``)
/// or call ``close()`` to stop it. A closed session raises ``SessionClosed``.
#[pyclass(module = "rodtrack", name = "Session")]
pub struct PySession {
    stream: Mutex<Option<Stream>>,
    cameras: usize,
    report: Option<RunReport>,
    ended: bool,
    /// The events decided after the last frame set, once the session has ended.
    final_events: Vec<rodtrack_core::ball::events::BallEvent>,
}

impl PySession {
    fn closed_err() -> PyErr {
        SessionClosed::new_err("the session is closed")
    }
}

#[pymethods]
impl PySession {
    fn __enter__(slf: PyRef<'_, Self>) -> PyResult<PyRef<'_, Self>> {
        if slf.stream.lock().map_or(true, |s| s.is_none()) {
            return Err(Self::closed_err());
        }
        Ok(slf)
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(
        &mut self,
        py: Python<'_>,
        _args: &Bound<'_, pyo3::types::PyTuple>,
    ) -> PyResult<bool> {
        self.close(py)?;
        Ok(false)
    }

    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<PyFrameSet>> {
        loop {
            let next = {
                let mut guard = self.stream.lock().map_err(|_| Self::closed_err())?;
                let Some(stream) = guard.as_mut() else {
                    return Err(Self::closed_err());
                };
                if self.ended {
                    return Ok(None);
                }
                py.detach(|| stream.next_timeout(POLL))
            };
            match next {
                Next::Set(set) => {
                    return Ok(Some(PyFrameSet {
                        set,
                        cameras: self.cameras,
                    }))
                }
                Next::Pending => py.check_signals()?,
                Next::Ended(result) => {
                    self.ended = true;
                    if let Ok(guard) = self.stream.lock() {
                        if let Some(stream) = guard.as_ref() {
                            self.final_events.extend(stream.take_final_events());
                        }
                    }
                    self.report = Some(*result.map_err(to_py)?);
                    return Ok(None);
                }
            }
        }
    }

    /// Stops the session and waits for its threads (pending frame sets are discarded); raises
    /// the session's error if it failed. Closing twice does nothing.
    fn close(&mut self, py: Python<'_>) -> PyResult<()> {
        let stream = self.stream.lock().map(|mut s| s.take()).unwrap_or(None);
        if let Some(mut stream) = stream {
            let result = py.detach(|| stream.close());
            self.final_events.extend(stream.take_final_events());
            if !self.ended {
                self.ended = true;
                self.report = Some(result.map_err(to_py)?);
            }
        }
        Ok(())
    }

    /// True while the session is open (not closed).
    #[getter]
    fn is_open(&self) -> bool {
        self.stream.lock().is_ok_and(|s| s.is_some())
    }

    /// True when a source is live (a camera, ``sim://...&realtime=1``).
    #[getter]
    fn is_live(&self) -> PyResult<bool> {
        let guard = self.stream.lock().map_err(|_| Self::closed_err())?;
        Ok(guard.as_ref().is_some_and(|s| s.is_live()))
    }

    /// Frame sets dropped because the Python loop was behind (live sources only; recordings
    /// wait for the loop instead).
    #[getter]
    fn dropped_sets(&self) -> u64 {
        self.stream
            .lock()
            .ok()
            .and_then(|s| s.as_ref().map(|s| s.dropped_sets()))
            .unwrap_or(0)
    }

    /// The session's report once it has ended or been closed (frames read, processed,
    /// dropped and bad per camera, tracker times); ``None`` before.
    #[getter]
    fn summary(&self) -> Option<String> {
        self.report.as_ref().map(|r| r.summary().trim().to_string())
    }

    /// The ball's events decided after the last frame set (the end of the run decides what
    /// was still pending), once the session has ended or been closed: dicts as the frame
    /// sets' ``events``. Every event goes out once, in a set or here (a live set dropped for
    /// a loop that is behind hands its events to the next set).
    #[getter]
    fn final_events<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        events_as_dicts(py, &self.final_events)
    }

    /// Ball rows dropped because no frame set took them in time (the session's frame sets
    /// stopped coming while its ball rows did).
    #[getter]
    fn dropped_ball_rows(&self) -> u64 {
        self.stream
            .lock()
            .ok()
            .and_then(|s| s.as_ref().map(|s| s.dropped_ball_rows()))
            .unwrap_or(0)
    }

    /// Number of cameras.
    #[getter]
    fn cameras(&self) -> usize {
        self.cameras
    }
}

/// Opens one input per camera of ``calibration`` (in its camera order) and starts tracking
/// them in a background thread: a folder of images, ``raw:FILE?...``, ``sim://SCENARIO?...``,
/// and, in builds with those features, ``video:FILE`` and ``genicam://ID``.
///
/// ``mode``: the algorithm; ``filter``: the temporal filter and the fusion (else each
/// camera's raw rows); ``max_frames``: stop after this many frames per camera; ``queue``: the
/// frame sets held for a Python loop that is behind (live sources drop sets beyond it and
/// count them in ``dropped_sets``; recordings wait). ``ball``: track the ball too (cameras
/// whose calibration has a ball), its rows in each set's ``ball``; ``events``: detect its
/// events too (goals with the score, shots, ball out, ball stopped; implies ``ball``; needs
/// the calibration's table frame), in each set's ``events``, with the goal mouth
/// ``goal_width_mm`` wide (the reference table's 205 mm by default).
#[pyfunction]
#[pyo3(signature = (calibration, inputs, mode = "enhanced", filter = true, max_frames = None, queue = 64, ball = false, events = false, goal_width_mm = None))]
#[allow(clippy::too_many_arguments)]
pub fn open(
    py: Python<'_>,
    calibration: &PyCalibration,
    inputs: Vec<String>,
    mode: &str,
    filter: bool,
    max_frames: Option<u64>,
    queue: usize,
    ball: bool,
    events: bool,
    goal_width_mm: Option<f64>,
) -> PyResult<PySession> {
    let options = SessionOptions {
        mode: rodtrack_sdk::mode_from_name(mode).map_err(to_py)?,
        filter,
        max_frames,
        ..SessionOptions::default()
    };
    if goal_width_mm.is_some() && !events {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "goal_width_mm sets the events' rules: pass events=True",
        ));
    }
    let mut rules = rodtrack_core::ball::events::EventConfig::default();
    if let Some(w) = goal_width_mm {
        rules.goal_width_mm = w;
    }
    let cal = &calibration.file;
    let share = (ball || events).then(BallShare::default);
    let stream = py
        .detach(|| {
            let mut s = Session::open(cal, &inputs, options)?;
            if let Some(share) = &share {
                s = s.with_ball(cal, Box::new(share.clone()))?;
            }
            if let (true, Some(share)) = (events, &share) {
                s = s.with_events(cal, rules, Box::new(share.clone()))?;
            }
            Stream::start(s, queue, share)
        })
        .map_err(to_py)?;
    Ok(PySession {
        stream: Mutex::new(Some(stream)),
        cameras: cal.cameras.len(),
        report: None,
        ended: false,
        final_events: Vec::new(),
    })
}
