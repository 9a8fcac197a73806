//! The Python module: classes and functions, each in the file of its responsibility.

mod calibration;
mod errors;
mod frame;
mod session;
mod simulate;
mod tracker;

use crate::columns::{
    PyBallRows, PyRows, BALL_COLUMN_NAMES, BALL_STATUS_NAMES, COLUMN_NAMES, FUSED_CAMERA,
    STATUS_NAMES,
};
use pyo3::prelude::*;
use rodtrack_io::sink::decimals;

/// rodtrack: visual encoders for table-football rods (native module; import `rodtrack`).
#[pymodule]
#[pyo3(name = "_rodtrack")]
fn rodtrack_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("COLUMNS", pyo3::types::PyTuple::new(py, COLUMN_NAMES)?)?;
    m.add("STATUS_NAMES", pyo3::types::PyTuple::new(py, STATUS_NAMES)?)?;
    m.add("FUSED", FUSED_CAMERA)?;
    m.add(
        "BALL_COLUMNS",
        pyo3::types::PyTuple::new(py, BALL_COLUMN_NAMES)?,
    )?;
    m.add(
        "BALL_STATUS_NAMES",
        pyo3::types::PyTuple::new(py, BALL_STATUS_NAMES)?,
    )?;
    m.add(
        "MODES",
        pyo3::types::PyTuple::new(py, rodtrack_sdk::MODE_NAMES)?,
    )?;
    let d = pyo3::types::PyDict::new(py);
    for (name, n) in [
        ("timestamp_s", decimals::TIMESTAMP_S),
        ("position_mm", decimals::POSITION_MM),
        ("angle_rad", decimals::ANGLE_RAD),
        ("angle_unwrapped_rad", decimals::ANGLE_RAD),
        ("velocity_mm_s", decimals::VELOCITY_MM_S),
        ("angular_velocity_rad_s", decimals::ANGULAR_VELOCITY_RAD_S),
        ("quality", decimals::QUALITY),
    ] {
        d.set_item(name, n)?;
    }
    m.add("CSV_DECIMALS", d)?;
    errors::register(m)?;
    m.add_class::<PyRows>()?;
    m.add_class::<PyBallRows>()?;
    m.add_class::<calibration::PyCalibration>()?;
    m.add_class::<tracker::PyTracker>()?;
    m.add_class::<session::PySession>()?;
    m.add_class::<session::PyFrameSet>()?;
    m.add_class::<simulate::PySimulation>()?;
    m.add_function(wrap_pyfunction!(calibration::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(session::open, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(frame::read_frame, m)?)?;
    Ok(())
}
