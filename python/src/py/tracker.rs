//! `Tracker`: one camera's tracker, a frame at a time from numpy.

use super::calibration::PyCalibration;
use super::errors::{core_to_py, to_py};
use super::frame::BorrowedFrame;
use crate::columns::{Columns, PyRows};
use pyo3::prelude::*;
use rodtrack_core::{CameraFilter, CameraPipeline, Measurement, PixelFormat};
use rodtrack_io::Timestamp;
use std::time::Instant;

/// One camera's tracker: give it that camera's frames, one at a time, in order.
///
/// ``Tracker(calibration, camera=0, mode="enhanced", filter=True)``: the camera's rods as
/// calibrated, the algorithm ``mode`` (``"enhanced"``, or ``"paper"``, the published method),
/// and with ``filter`` the camera's temporal filter (velocities, predictions through short
/// occlusions); without it, the raw measurements (``rodtrack track --raw``).
#[pyclass(module = "rodtrack", name = "Tracker")]
pub struct PyTracker {
    pipe: CameraPipeline,
    filter: Option<CameraFilter>,
    format: PixelFormat,
    width: usize,
    height: usize,
    fps: f64,
    label: String,
    raw: Vec<Measurement>,
    filtered: Vec<Measurement>,
    last_ns: u64,
}

#[pymethods]
impl PyTracker {
    #[new]
    #[pyo3(signature = (calibration, camera = 0, mode = "enhanced", filter = true))]
    fn new(
        calibration: &PyCalibration,
        camera: usize,
        mode: &str,
        filter: bool,
    ) -> PyResult<PyTracker> {
        let mode = rodtrack_sdk::mode_from_name(mode).map_err(to_py)?;
        let cam = calibration.camera(camera)?;
        let label = format!("camera {} ({})", cam.index, cam.name);
        let format = cam.format().map_err(|e| core_to_py(&label, e))?;
        let pipe = CameraPipeline::new(cam, mode).map_err(|e| core_to_py(&label, e))?;
        let n = cam.rods.len();
        Ok(PyTracker {
            pipe,
            // The filter of a camera the session would run: alone in a one-camera
            // calibration, beside a fusion otherwise (its rows equal `rodtrack track`'s).
            filter: filter.then(|| {
                if calibration.file.cameras.len() > 1 {
                    CameraFilter::new(mode)
                } else {
                    CameraFilter::alone(mode)
                }
            }),
            format,
            width: cam.image_width,
            height: cam.image_height,
            fps: cam.fps,
            label,
            raw: Vec::with_capacity(n),
            filtered: Vec::with_capacity(n),
            last_ns: 0,
        })
    }

    /// Measures every rod of the camera in ``frame`` and returns one row per rod (``Rows``).
    ///
    /// ``frame``: a numpy array of shape ``(height, width)`` (``(height, width, 3)`` for
    /// ``rgb8``), ``uint8`` for 8-bit pixel formats or ``uint16`` for 16-bit ones, as the
    /// calibration says; borrowed without a copy (padded rows and row steps are fine; a
    /// layout that cannot be a frame raises ``ValueError``, another element type
    /// ``TypeError``). Do not write to it from another thread during the call: the GIL is
    /// released while tracking. ``timestamp_ns`` defaults to ``frame_id / fps``.
    #[pyo3(signature = (frame, frame_id, timestamp_ns = None))]
    fn process(
        &mut self,
        py: Python<'_>,
        frame: &Bound<'_, PyAny>,
        frame_id: u64,
        timestamp_ns: Option<u64>,
    ) -> PyResult<PyRows> {
        let borrowed =
            BorrowedFrame::borrow(frame, self.format, self.width, self.height, &self.label)?;
        let view = borrowed.view()?;
        let ts = timestamp_ns
            .map(Timestamp::from_nanos)
            .unwrap_or_else(|| Timestamp::from_frame(frame_id, self.fps));
        let PyTracker {
            pipe,
            filter,
            raw,
            filtered,
            last_ns,
            ..
        } = self;
        let result = py.detach(|| {
            raw.clear();
            filtered.clear();
            let start = Instant::now();
            let r = pipe.process(&view, frame_id, ts, raw);
            if r.is_ok() {
                if let Some(f) = filter.as_mut() {
                    f.process(raw, filtered);
                }
            }
            *last_ns = start.elapsed().as_nanos() as u64;
            r
        });
        result.map_err(|e| core_to_py(&format!("{}: frame {frame_id}", self.label), e))?;
        let rows = if self.filter.is_some() {
            &self.filtered
        } else {
            &self.raw
        };
        Ok(PyRows {
            cols: Columns::of(rows),
        })
    }

    /// The rod ids, in the order of the rows.
    #[getter]
    fn rods(&self) -> Vec<u32> {
        self.pipe.rods().iter().map(|r| r.rod()).collect()
    }

    /// The pixel format the frames must be in.
    #[getter]
    fn pixel_format(&self) -> &'static str {
        self.format.name()
    }

    /// The frame shape wanted, ``(height, width)`` or ``(height, width, 3)``.
    #[getter]
    fn shape(&self) -> Vec<usize> {
        if self.format == PixelFormat::Rgb8 {
            vec![self.height, self.width, 3]
        } else {
            vec![self.height, self.width]
        }
    }

    /// Time the last ``process`` call spent in Rust tracking (and filtering), nanoseconds:
    /// the call's time minus this is the binding's overhead.
    #[getter]
    fn last_process_ns(&self) -> u64 {
        self.last_ns
    }

    fn __repr__(&self) -> String {
        format!(
            "Tracker({}, {} {}x{}, rods {:?}, filter={})",
            self.label,
            self.format,
            self.width,
            self.height,
            self.rods(),
            self.filter.is_some()
        )
    }
}
