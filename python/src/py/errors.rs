//! The exceptions: the Rust errors' messages (which name the file, field, camera or rod)
//! carried into Python.

use pyo3::prelude::*;

pyo3::create_exception!(
    rodtrack,
    RodtrackError,
    pyo3::exceptions::PyException,
    "An error of rodtrack: a calibration, a source, a session or the tracker refused something; \
     the message names the file, field, camera or rod."
);
pyo3::create_exception!(
    rodtrack,
    CalibrationError,
    RodtrackError,
    "A calibration file or calibration inputs cannot be read, are malformed or are invalid."
);
pyo3::create_exception!(
    rodtrack,
    SessionClosed,
    RodtrackError,
    "The session was closed (or has ended) and cannot be used any more."
);

/// Adds the exceptions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("RodtrackError", py.get_type::<RodtrackError>())?;
    m.add("CalibrationError", py.get_type::<CalibrationError>())?;
    m.add("SessionClosed", py.get_type::<SessionClosed>())?;
    Ok(())
}

/// A rodtrack error as a Python exception: [`CalibrationError`] for files, else
/// [`RodtrackError`], with the full message.
pub fn to_py(e: rodtrack_sdk::SdkError) -> PyErr {
    match e {
        rodtrack_sdk::SdkError::File { .. } => CalibrationError::new_err(e.to_string()),
        _ => RodtrackError::new_err(e.to_string()),
    }
}

/// A core error (the tracker, a calibration) with its context.
pub fn core_to_py(context: &str, e: rodtrack_core::CoreError) -> PyErr {
    RodtrackError::new_err(format!("{context}: {e}"))
}
