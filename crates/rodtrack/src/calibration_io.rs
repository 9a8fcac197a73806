//! Reading calibration inputs and calibration files, with errors that name the file.

use anyhow::{bail, Context, Result};
use rodtrack_core::calib::{CalibrationFile, CalibrationInputs};
use std::path::Path;

/// Reads and parses a calibration-inputs JSON file.
pub fn read_inputs(path: &Path) -> Result<CalibrationInputs> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read calibration inputs {}", path.display()))?;
    serde_json::from_str(&text)
        .with_context(|| format!("calibration inputs {} are malformed", path.display()))
}

/// Reads, parses and validates a calibration file (TOML).
pub fn read_calibration(path: &Path) -> Result<CalibrationFile> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read calibration file {}", path.display()))?;
    let cal: CalibrationFile = toml::from_str(&text)
        .with_context(|| format!("calibration file {} is malformed", path.display()))?;
    cal.validate()
        .with_context(|| format!("calibration file {} is invalid", path.display()))?;
    if cal.cameras.is_empty() {
        bail!("calibration file {} holds no camera", path.display());
    }
    Ok(cal)
}

/// Writes a calibration file (TOML) atomically.
pub fn write_calibration(path: &Path, cal: &CalibrationFile) -> Result<()> {
    let text = toml::to_string_pretty(cal).context("cannot serialise the calibration")?;
    let header = "# rodtrack calibration file. Made by `rodtrack calibrate`; validated on load.\n\
                  # knots: the rod's line every step_mm along its axis (enhanced mode);\n\
                  # paper: the paper's parameters (O_m = offset_px, S_m = spacing_px, T_hat = period_px).\n\n";
    let tmp = path.with_extension("toml.tmp");
    std::fs::write(&tmp, format!("{header}{text}"))
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}
