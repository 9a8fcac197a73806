//! `simulate`: the built-in simulator's frames, ground truth and calibration as numpy arrays.

use super::calibration::PyCalibration;
use super::errors::RodtrackError;
use crate::columns::{Columns, PyRows};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use rodtrack_sim::SimError;

/// A simulated recording: the frames of every camera, the ground truth and the calibration an
/// operator would make of that table.
#[pyclass(module = "rodtrack", name = "Simulation", frozen)]
pub struct PySimulation {
    frames: Py<PyAny>,
    truth: Columns,
    visible: Vec<bool>,
    frame_ids: Vec<u64>,
    timestamps_ns: Vec<u64>,
    calibration: PyCalibration,
    ball: Option<Vec<rodtrack_sim::ball::BallTruthRow>>,
    events: Vec<rodtrack_core::ball::events::BallEvent>,
}

#[pymethods]
impl PySimulation {
    /// The frames, shape ``(cameras, frames, height, width)``, ``uint8`` (raw Bayer RGGB),
    /// ready for ``Tracker.process(sim.frames[camera, i], ...)``.
    #[getter]
    fn frames(&self, py: Python<'_>) -> Py<PyAny> {
        self.frames.clone_ref(py)
    }

    /// Ground truth, one row per (frame, camera, rod) in that order: the tracker's columns
    /// with the true values at the middle of each exposure (quality 1, status ``ok`` when the
    /// marker is visible).
    #[getter]
    fn truth(&self) -> PyRows {
        PyRows {
            cols: self.truth.clone(),
        }
    }

    /// Per truth row: True when the whole marker is in the frame and nothing hides it.
    #[getter]
    fn visible<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_slice(py, &self.visible)
    }

    /// The frame ids, one per frame.
    #[getter]
    fn frame_ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_slice(py, &self.frame_ids)
    }

    /// The trigger times, nanoseconds, one per frame.
    #[getter]
    fn timestamps_ns<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_slice(py, &self.timestamps_ns)
    }

    /// The ball's truth, one entry per frame, or ``None`` in a scenario without a ball: a dict
    /// of numpy arrays ``frame``, ``timestamp_s``, ``x_mm``, ``y_mm`` (its centre at
    /// mid-exposure, the table frame), ``vx_mm_s``, ``vy_mm_s`` and ``visible``, shape
    /// ``(frames, cameras)``: the fraction of the ball each camera sees.
    #[getter]
    fn ball_truth<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<Bound<'py, pyo3::types::PyDict>>> {
        let Some(rows) = &self.ball else {
            return Ok(None);
        };
        let d = pyo3::types::PyDict::new(py);
        let col = |f: fn(&rodtrack_sim::ball::BallTruthRow) -> f64| -> Vec<f64> {
            rows.iter().map(f).collect()
        };
        let frames: Vec<u64> = rows.iter().map(|r| r.frame).collect();
        d.set_item("frame", PyArray1::from_vec(py, frames))?;
        d.set_item(
            "timestamp_s",
            PyArray1::from_vec(py, col(|r| r.timestamp_ns.as_secs_f64())),
        )?;
        d.set_item("x_mm", PyArray1::from_vec(py, col(|r| r.x_mm)))?;
        d.set_item("y_mm", PyArray1::from_vec(py, col(|r| r.y_mm)))?;
        d.set_item("vx_mm_s", PyArray1::from_vec(py, col(|r| r.vx_mm_s)))?;
        d.set_item("vy_mm_s", PyArray1::from_vec(py, col(|r| r.vy_mm_s)))?;
        let cameras = rows.first().map_or(0, |r| r.visible.len());
        let visible: Vec<f64> = rows.iter().flat_map(|r| r.visible.clone()).collect();
        d.set_item(
            "visible",
            PyArray1::from_vec(py, visible).reshape([rows.len(), cameras])?,
        )?;
        Ok(Some(d))
    }

    /// The scenario's scripted events within the simulation's frames (goals, shots, ...), each
    /// a dict as a line of ``rodtrack track --events-out``; empty without a ball.
    #[getter]
    fn events_truth<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        super::session::events_as_dicts(py, &self.events)
    }

    /// Every camera calibrated as an operator would (simulated clicks with about 1 px of
    /// error, the rendered reference frame; in a scenario with a ball, its colour from a
    /// frame of its own and the table frame): use it with ``Tracker`` or ``rodtrack.open`` on
    /// these frames or on ``sim://`` inputs of the same scenario and seed.
    #[getter]
    fn calibration(&self) -> PyCalibration {
        self.calibration.clone()
    }
}

/// The rendered frames and truth of every camera.
struct Rendered {
    bytes: Vec<u8>,
    cameras: usize,
    frames: usize,
    width: usize,
    height: usize,
    truth: Columns,
    visible: Vec<bool>,
    frame_ids: Vec<u64>,
    timestamps_ns: Vec<u64>,
    calibration: rodtrack_core::calib::CalibrationFile,
    ball: Option<Vec<rodtrack_sim::ball::BallTruthRow>>,
    events: Vec<rodtrack_core::ball::events::BallEvent>,
}

fn render(
    scenario: &str,
    frames: Option<usize>,
    seed: u64,
    setup: &str,
) -> Result<Rendered, Box<dyn std::error::Error + Send + Sync>> {
    let mut sim = rodtrack_sim::build_simulation(scenario, frames, seed, false, setup)?;
    let ncam = sim.cameras().len();
    let n = sim.frame_count();
    // With a ball in the scenario, its colour is calibrated too (from its own frame), so that
    // `open(..., ball=True)` tracks it.
    let with_ball = sim.ball_truth(0).is_some();
    let mut cams = Vec::new();
    for c in 0..ncam {
        cams.push(if with_ball {
            sim.calibrated_camera_with_ball(c, seed)?
        } else {
            rodtrack_sim::calibrate_sim_camera(&mut sim, c, seed)?.calibration
        });
    }
    let calibration = rodtrack_sdk::calibration_file(cams)?;
    let frame_bytes = sim.frame_bytes(0)?;
    let mut bytes = vec![0u8; frame_bytes * n * ncam];
    let (mut width, mut height) = (0, 0);
    let mut truth = Columns::default();
    let mut visible = Vec::new();
    let mut frame_ids = Vec::with_capacity(n);
    let mut timestamps_ns = Vec::with_capacity(n);
    for f in 0..n {
        for c in 0..ncam {
            let start = (c * n + f) * frame_bytes;
            let out = bytes
                .get_mut(start..start + frame_bytes)
                .ok_or(SimError::NoSuchCamera {
                    index: c,
                    count: ncam,
                })?;
            let info = sim.render(f, c, out)?;
            if info.format.bytes_per_pixel() != 1 || info.stride != info.width {
                return Err(
                    format!("camera {c}: {} frames are not supported here", info.format).into(),
                );
            }
            (width, height) = (info.width, info.height);
            if c == 0 {
                frame_ids.push(info.frame_id);
                timestamps_ns.push(info.timestamp_ns.as_nanos());
            }
            for t in sim.truth(f, c)? {
                truth.push(&t.m);
                visible.push(t.visible);
            }
        }
    }
    let ball = with_ball.then(|| (0..n).filter_map(|f| sim.ball_truth(f)).collect());
    let events = sim.events_truth();
    Ok(Rendered {
        bytes,
        ball,
        events,
        cameras: ncam,
        frames: n,
        width,
        height,
        truth,
        visible,
        frame_ids,
        timestamps_ns,
        calibration,
    })
}

/// Renders ``frames`` frames of the simulator's ``scenario`` (``exp1``, ``exp2``, ``exp3``,
/// ``gameplay``, ...; default length: the scenario's) on the table ``setup`` (``default``, a
/// variation, or ``asbuilt:SEED`` for a randomly built table), scene noise drawn from
/// ``seed``: the same frames as ``rodtrack simulate`` and ``sim://`` with those arguments.
/// Returns a ``Simulation`` (frames, truth, calibration as numpy arrays and objects).
#[pyfunction]
#[pyo3(signature = (scenario = "exp3", frames = None, seed = 1, setup = "default"))]
pub fn simulate(
    py: Python<'_>,
    scenario: &str,
    frames: Option<usize>,
    seed: u64,
    setup: &str,
) -> PyResult<PySimulation> {
    let r = py
        .detach(|| render(scenario, frames, seed, setup))
        .map_err(|e| RodtrackError::new_err(format!("simulating {scenario}: {e}")))?;
    let array =
        PyArray1::from_vec(py, r.bytes).reshape([r.cameras, r.frames, r.height, r.width])?;
    Ok(PySimulation {
        frames: array.into_any().unbind(),
        truth: r.truth,
        visible: r.visible,
        frame_ids: r.frame_ids,
        timestamps_ns: r.timestamps_ns,
        calibration: PyCalibration {
            file: r.calibration,
        },
        ball: r.ball,
        events: r.events,
    })
}
