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
    Ok(Rendered {
        bytes,
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
    })
}
