//! `Calibration` (a calibration file) and `calibrate` (calibration inputs to a calibration).

use super::errors::{to_py, CalibrationError};
use pyo3::prelude::*;
use rodtrack_core::calib::{CalibrationFile, CameraCalibration};
use std::path::PathBuf;

/// A validated calibration: every camera's rods, image size and pixel format.
///
/// Load one made by ``rodtrack calibrate`` with ``Calibration.load(path)``, make one from
/// calibration inputs with ``rodtrack.calibrate(inputs=[...])``, or take a simulation's
/// (``rodtrack.simulate(...).calibration``).
#[pyclass(module = "rodtrack", name = "Calibration", frozen)]
#[derive(Clone)]
pub struct PyCalibration {
    /// The calibration file.
    pub file: CalibrationFile,
}

impl PyCalibration {
    /// Camera `camera`, or an IndexError naming the cameras there are.
    pub fn camera(&self, camera: usize) -> PyResult<&CameraCalibration> {
        self.file.cameras.get(camera).ok_or_else(|| {
            pyo3::exceptions::PyIndexError::new_err(format!(
                "camera {camera} does not exist: the calibration has {} camera(s)",
                self.file.cameras.len()
            ))
        })
    }
}

#[pymethods]
impl PyCalibration {
    /// Reads, parses and validates a calibration file (TOML); raises ``CalibrationError``
    /// naming the file and the field.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<PyCalibration> {
        let file = py
            .detach(|| rodtrack_sdk::read_calibration(&path))
            .map_err(to_py)?;
        Ok(PyCalibration { file })
    }

    /// Writes the calibration file (TOML), atomically.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| rodtrack_sdk::write_calibration(&path, &self.file))
            .map_err(to_py)
    }

    /// Number of cameras.
    #[getter]
    fn cameras(&self) -> usize {
        self.file.cameras.len()
    }

    /// The camera's name (``cam0``).
    #[pyo3(signature = (camera = 0))]
    fn camera_name(&self, camera: usize) -> PyResult<String> {
        Ok(self.camera(camera)?.name.clone())
    }

    /// The rod ids the camera sees, in the order of its rows.
    #[pyo3(signature = (camera = 0))]
    fn rods(&self, camera: usize) -> PyResult<Vec<u32>> {
        Ok(self.camera(camera)?.rods.iter().map(|r| r.rod).collect())
    }

    /// The camera's pixel format (``bayer_rggb8``, ``mono16``, ...): the frames it takes.
    #[pyo3(signature = (camera = 0))]
    fn pixel_format(&self, camera: usize) -> PyResult<String> {
        let cam = self.camera(camera)?;
        let format = cam
            .format()
            .map_err(|e| CalibrationError::new_err(format!("camera {camera}: {e}")))?;
        Ok(format.name().to_string())
    }

    /// The camera's image size, ``(width, height)`` in pixels.
    #[pyo3(signature = (camera = 0))]
    fn image_size(&self, camera: usize) -> PyResult<(usize, usize)> {
        let cam = self.camera(camera)?;
        Ok((cam.image_width, cam.image_height))
    }

    /// The camera's frame rate, frames per second.
    #[pyo3(signature = (camera = 0))]
    fn fps(&self, camera: usize) -> PyResult<f64> {
        Ok(self.camera(camera)?.fps)
    }

    fn __repr__(&self) -> String {
        let cams: Vec<String> = self
            .file
            .cameras
            .iter()
            .map(|c| {
                format!(
                    "{} {}x{} {} rods {:?}",
                    c.name,
                    c.image_width,
                    c.image_height,
                    c.format().map(|f| f.name()).unwrap_or("?"),
                    c.rods.iter().map(|r| r.rod).collect::<Vec<_>>()
                )
            })
            .collect();
        format!("Calibration({})", cams.join("; "))
    }
}

/// Calibrates every camera from its calibration-inputs JSON file (camera ``i`` from
/// ``inputs[i]``; its reference frames are read from the folder the file names) into a
/// validated ``Calibration``. Unknown fields in the inputs give ``UserWarning``s; errors raise
/// ``CalibrationError`` naming the file and the field.
#[pyfunction]
#[pyo3(signature = (inputs))]
pub fn calibrate(py: Python<'_>, inputs: Vec<PathBuf>) -> PyResult<PyCalibration> {
    let mut warnings = Vec::new();
    let result = py.detach(|| {
        let paths: Vec<&std::path::Path> = inputs.iter().map(|p| p.as_path()).collect();
        rodtrack_sdk::calibrate_files(&paths, &mut |w| warnings.push(w))
    });
    for w in &warnings {
        let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
        let msg = std::ffi::CString::new(w.replace('\0', " "))
            .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
        PyErr::warn(py, &category, &msg, 1)?;
    }
    Ok(PyCalibration {
        file: result.map_err(to_py)?,
    })
}
