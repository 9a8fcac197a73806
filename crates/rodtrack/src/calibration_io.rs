//! Reading calibration inputs and calibration files, with errors that name the file.

use anyhow::{anyhow, bail, Context, Result};
use rodtrack_core::calib::inputs::OPENCV_MODEL_FILE_KEY;
use rodtrack_core::calib::opencv::{is_model_key, parse_opencv_model};
use rodtrack_core::calib::{CalibrationFile, CalibrationInputs, OpencvModel};
use std::path::Path;

/// Reads and parses a calibration-inputs JSON file. An `opencv_model_file` entry (an OpenCV
/// FileStorage YAML or JSON file, relative to the inputs file) is read into
/// `opencv_model_optional`.
pub fn read_inputs(path: &Path) -> Result<CalibrationInputs> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read calibration inputs {}", path.display()))?;
    let malformed = || format!("calibration inputs {} are malformed", path.display());
    // Parse straight into the inputs (errors with line and column) unless the file names an
    // OpenCV model file.
    let mut value: serde_json::Value = serde_json::from_str(&text).with_context(malformed)?;
    // An inline OpenCV model's extra keys (other tools write doc strings there) are warned
    // about and dropped; its reader refuses keys it does not know.
    let mut dropped = false;
    if let Some(model) = value
        .get_mut("opencv_model_optional")
        .and_then(|m| m.as_object_mut())
    {
        let extra: Vec<String> = model.keys().filter(|k| !is_model_key(k)).cloned().collect();
        for k in extra {
            warn_unknown(path, &format!("opencv_model_optional.{k}"));
            model.remove(&k);
            dropped = true;
        }
    }
    let Some(file) = value
        .as_object_mut()
        .and_then(|o| o.remove(OPENCV_MODEL_FILE_KEY))
    else {
        if dropped {
            return from_json_warning_unknown(value, path).with_context(malformed);
        }
        let mut de = serde_json::Deserializer::from_str(&text);
        return from_json_warning_unknown(&mut de, path).with_context(malformed);
    };
    let field = |reason: String| {
        anyhow!(
            "calibration inputs {}: field `{OPENCV_MODEL_FILE_KEY}`: {reason}",
            path.display()
        )
    };
    let Some(file) = file.as_str() else {
        return Err(field(format!("must be a file name, got {file}")));
    };
    if value
        .get("opencv_model_optional")
        .is_some_and(|v| !v.is_null())
    {
        return Err(field(
            "give either `opencv_model_file` or `opencv_model_optional`, not both".into(),
        ));
    }
    let model_path = path.parent().unwrap_or(Path::new(".")).join(file);
    let model = read_opencv_model(&model_path).map_err(|e| field(format!("{e:#}")))?;
    if let Some(o) = value.as_object_mut() {
        o.insert(
            "opencv_model_optional".into(),
            serde_json::to_value(&model).context("cannot convert the OpenCV model")?,
        );
    }
    from_json_warning_unknown(value, path).with_context(malformed)
}

/// Deserialises `T`, printing a warning that names `path` and the field for every field `T`
/// does not know (inputs written by other tools carry extra fields; SPEC section 5 allows them).
pub fn from_json_warning_unknown<'de, T, D>(de: D, path: &Path) -> Result<T, D::Error>
where
    T: serde::Deserialize<'de>,
    D: serde::Deserializer<'de>,
{
    serde_ignored::deserialize(de, |field| warn_unknown(path, &field.to_string()))
}

fn warn_unknown(path: &Path, field: &str) {
    eprintln!(
        "warning: {}: ignoring unknown field '{field}'",
        path.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| path.display().to_string())
    );
}

/// Reads an OpenCV camera model from a `cv::FileStorage` file (YAML or JSON, as OpenCV writes
/// it after `calibrateCamera`); errors name the file and the field.
pub fn read_opencv_model(path: &Path) -> Result<OpencvModel> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the OpenCV camera model {}", path.display()))?;
    parse_opencv_model(&text).map_err(|e| anyhow!("OpenCV camera model {}: {e}", path.display()))
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
