//! Calibration files and calibration inputs: reading (with warnings for the fields other tools
//! add), writing, and calibrating cameras from inputs files and their reference frames.
//!
//! ```no_run
//! // `calibrate --inputs`: one calibration-inputs file per camera, then one calibration file.
//! let cal = rodtrack_sdk::calibrate_files(
//!     &["rec/cam0.json".as_ref(), "rec/cam1.json".as_ref()],
//!     &mut rodtrack_sdk::print_warning,
//! )?;
//! rodtrack_sdk::write_calibration("table.toml".as_ref(), &cal)?;
//! assert_eq!(rodtrack_sdk::read_calibration("table.toml".as_ref())?.cameras.len(), 2);
//! # Ok::<(), rodtrack_sdk::SdkError>(())
//! ```

use crate::SdkError;
use rodtrack_core::calib::inputs::OPENCV_MODEL_FILE_KEY;
use rodtrack_core::calib::opencv::{is_model_key, parse_opencv_model};
use rodtrack_core::calib::{
    CalibrationFile, CalibrationInputs, CameraCalibration, OpencvModel, CALIBRATION_VERSION,
};
use rodtrack_core::{FrameView, PixelFormat};
use rodtrack_io::source::{decode_image_file, list_image_files};
use rodtrack_io::FrameBuffer;
use std::path::Path;

/// The frame rate written into a camera's calibration when its inputs give none.
///
/// ```
/// assert_eq!(rodtrack_sdk::DEFAULT_FPS, 200.0);
/// ```
pub const DEFAULT_FPS: f64 = 200.0;

/// Receives the warnings of a read (`FILE: ignoring unknown field 'x'`).
///
/// ```
/// use rodtrack_sdk::calibration::Warn;
/// let mut seen = Vec::new();
/// let mut keep = |msg: String| seen.push(msg);
/// let warn: Warn<'_> = &mut keep;
/// warn("cam0.json: ignoring unknown field 'note'".into());
/// assert_eq!(seen.len(), 1);
/// ```
pub type Warn<'a> = &'a mut dyn FnMut(String);

/// Prints a warning on standard error, prefixed `warning: `: the warning sink of the CLI.
///
/// ```no_run
/// // Warnings of reading calibration inputs, printed on standard error.
/// let inputs = rodtrack_sdk::read_inputs("cam0.json".as_ref(), &mut rodtrack_sdk::print_warning)?;
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn print_warning(msg: String) {
    eprintln!("warning: {msg}");
}

/// Reads and parses a calibration-inputs JSON file. An `opencv_model_file` entry (an OpenCV
/// FileStorage YAML or JSON file, relative to the inputs file) is read into
/// `opencv_model_optional`. Fields the inputs do not know are ignored, each with a warning.
///
/// ```no_run
/// let mut warnings = Vec::new();
/// let inputs = rodtrack_sdk::read_inputs("cam0.json".as_ref(), &mut |w| warnings.push(w))?;
/// println!("{} rods, {} warnings", inputs.rods.len(), warnings.len());
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn read_inputs(path: &Path, warn: Warn<'_>) -> Result<CalibrationInputs, SdkError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        SdkError::file(
            path,
            format!("cannot read calibration inputs {}: {e}", path.display()),
        )
    })?;
    let malformed = |e: serde_json::Error| {
        SdkError::file(
            path,
            format!("calibration inputs {} are malformed: {e}", path.display()),
        )
    };
    let mut value: serde_json::Value = serde_json::from_str(&text).map_err(malformed)?;
    // An inline OpenCV model's extra keys (other tools write doc strings there) are warned
    // about and dropped; its reader refuses keys it does not know.
    let mut dropped = false;
    if let Some(model) = value
        .get_mut("opencv_model_optional")
        .and_then(|m| m.as_object_mut())
    {
        let extra: Vec<String> = model.keys().filter(|k| !is_model_key(k)).cloned().collect();
        for k in extra {
            warn(unknown_field(path, &format!("opencv_model_optional.{k}")));
            model.remove(&k);
            dropped = true;
        }
    }
    let Some(file) = value
        .as_object_mut()
        .and_then(|o| o.remove(OPENCV_MODEL_FILE_KEY))
    else {
        if dropped {
            return from_json_warning_unknown(value, path, warn).map_err(malformed);
        }
        // Straight from the text: errors with line and column.
        let mut de = serde_json::Deserializer::from_str(&text);
        return from_json_warning_unknown(&mut de, path, warn).map_err(malformed);
    };
    let field = |reason: String| {
        SdkError::file(
            path,
            format!(
                "calibration inputs {}: field `{OPENCV_MODEL_FILE_KEY}`: {reason}",
                path.display()
            ),
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
    let model = read_opencv_model(&model_path).map_err(|e| field(e.to_string()))?;
    if let Some(o) = value.as_object_mut() {
        let model = serde_json::to_value(&model)
            .map_err(|e| field(format!("cannot convert the OpenCV model: {e}")))?;
        o.insert("opencv_model_optional".into(), model);
    }
    from_json_warning_unknown(value, path, warn).map_err(malformed)
}

/// Deserialises `T`, warning for every field `T` does not know, with `path` and the field
/// (inputs written by other tools carry extra fields; the specification allows them).
///
/// ```
/// use rodtrack_sdk::calibration::from_json_warning_unknown;
/// #[derive(serde::Deserialize)]
/// struct Size {
///     width: u32,
/// }
/// let mut de = serde_json::Deserializer::from_str(r#"{"width": 1440, "colour": "red"}"#);
/// let mut warnings = Vec::new();
/// let s: Size = from_json_warning_unknown(&mut de, "size.json".as_ref(), &mut |w| warnings.push(w))?;
/// assert_eq!(s.width, 1440);
/// assert_eq!(warnings, ["size.json: ignoring unknown field 'colour'"]);
/// # Ok::<(), serde_json::Error>(())
/// ```
pub fn from_json_warning_unknown<'de, T, D>(
    de: D,
    path: &Path,
    warn: Warn<'_>,
) -> Result<T, D::Error>
where
    T: serde::Deserialize<'de>,
    D: serde::Deserializer<'de>,
{
    serde_ignored::deserialize(de, |field| warn(unknown_field(path, &field.to_string())))
}

fn unknown_field(path: &Path, field: &str) -> String {
    format!(
        "{}: ignoring unknown field '{field}'",
        path.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| path.display().to_string())
    )
}

/// Reads an OpenCV camera model from a `cv::FileStorage` file (YAML or JSON, as OpenCV writes
/// it after `calibrateCamera`); errors name the file and the field.
///
/// ```no_run
/// // The file OpenCV's calibrateCamera wrote (cv::FileStorage, YAML or JSON).
/// let model = rodtrack_sdk::read_opencv_model("cam0_intrinsics.yml".as_ref())?;
/// println!("{:?}", model);
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn read_opencv_model(path: &Path) -> Result<OpencvModel, SdkError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        SdkError::file(
            path,
            format!(
                "cannot read the OpenCV camera model {}: {e}",
                path.display()
            ),
        )
    })?;
    parse_opencv_model(&text)
        .map_err(|e| SdkError::file(path, format!("OpenCV camera model {}: {e}", path.display())))
}

/// Reads, parses and validates a calibration file (TOML).
///
/// ```no_run
/// let cal = rodtrack_sdk::read_calibration("calib.toml".as_ref())?;
/// println!("{} camera(s)", cal.cameras.len());
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn read_calibration(path: &Path) -> Result<CalibrationFile, SdkError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        SdkError::file(
            path,
            format!("cannot read calibration file {}: {e}", path.display()),
        )
    })?;
    let cal: CalibrationFile = toml::from_str(&text).map_err(|e| {
        SdkError::file(
            path,
            format!("calibration file {} is malformed: {e}", path.display()),
        )
    })?;
    cal.validate().map_err(|e| {
        SdkError::file(
            path,
            format!("calibration file {} is invalid: {e}", path.display()),
        )
    })?;
    if cal.cameras.is_empty() {
        return Err(SdkError::file(
            path,
            format!("calibration file {} holds no camera", path.display()),
        ));
    }
    Ok(cal)
}

/// Writes a calibration file (TOML) atomically (a temporary file renamed over `path`).
///
/// ```no_run
/// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
/// rodtrack_sdk::write_calibration("copy.toml".as_ref(), &cal)?;
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn write_calibration(path: &Path, cal: &CalibrationFile) -> Result<(), SdkError> {
    let text = toml::to_string_pretty(cal)
        .map_err(|e| SdkError::file(path, format!("cannot serialise the calibration: {e}")))?;
    let header = "# rodtrack calibration file. Made by `rodtrack calibrate`; validated on load.\n\
                  # knots: the rod's line every step_mm along its axis (enhanced mode);\n\
                  # paper: the paper's parameters (O_m = offset_px, S_m = spacing_px, T_hat = period_px).\n\n";
    let tmp = path.with_extension("toml.tmp");
    std::fs::write(&tmp, format!("{header}{text}"))
        .map_err(|e| SdkError::file(&tmp, format!("cannot write {}: {e}", tmp.display())))?;
    std::fs::rename(&tmp, path)
        .map_err(|e| SdkError::file(path, format!("cannot write {}: {e}", path.display())))?;
    Ok(())
}

/// Calibrates camera `index` from its inputs, read from `path`: the reference frames named
/// by the inputs are read from `reference_frames.dir` (relative to `path`).
///
/// ```no_run
/// let path = std::path::Path::new("rec/cam0.json");
/// let inputs = rodtrack_sdk::read_inputs(path, &mut rodtrack_sdk::print_warning)?;
/// let camera = rodtrack_sdk::calibrate_camera_file(&inputs, path, 0)?;
/// let file = rodtrack_sdk::calibration_file(vec![camera])?;
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn calibrate_camera_file(
    inputs: &CalibrationInputs,
    path: &Path,
    index: u32,
) -> Result<CameraCalibration, SdkError> {
    let name = path.display().to_string();
    let err = |reason: String| SdkError::file(path, reason);
    rodtrack_core::calib::validate::validate_inputs(inputs, index)
        .map_err(|e| err(format!("calibration inputs {name} are invalid: {e}")))?;
    let folder = ReferenceFolder::open(inputs, path)?;
    if inputs.reference_frames.reference_frame >= folder.files.len() {
        return Err(err(format!(
            "{name}: camera {index}: field `reference_frames.reference_frame`: frame {} does not \
             exist ({} images in {})",
            inputs.reference_frames.reference_frame,
            folder.files.len(),
            folder.dir.display()
        )));
    }
    // Every frame a rod names: its reference frame and its known poses.
    let mut wanted: Vec<(u32, &str, usize)> = Vec::new();
    for rod in &inputs.rods {
        wanted.push((rod.rod, "reference.frame", rod.reference.frame));
        for k in rod.all_known_poses() {
            wanted.push((rod.rod, "known_poses", k.frame));
        }
    }
    let mut frames: Vec<(usize, FrameBuffer)> = Vec::new();
    for (rod, field, idx) in wanted {
        if frames.iter().any(|(i, _)| *i == idx) {
            continue;
        }
        let buf = folder.read(idx, &format!("rod {rod}: field `{field}`"))?;
        frames.push((idx, buf));
    }
    if let Some(b) = &inputs.ball {
        if !frames.iter().any(|(i, _)| *i == b.frame) {
            let buf = folder.read(b.frame, "field `ball.frame`")?;
            frames.push((b.frame, buf));
        }
    }
    let mut views: Vec<(usize, FrameView)> = Vec::new();
    for (i, buf) in &frames {
        let view = buf
            .view()
            .map_err(|e| SdkError::core(format!("{name}: reference frame {i}"), e))?;
        views.push((*i, view));
    }
    rodtrack_core::calib::calibrate_camera(inputs, &views, index, DEFAULT_FPS)
        .map_err(|e| SdkError::core(format!("{name}: calibrating camera {index}"), e))
}

/// The reference frames of a camera's calibration inputs: the images of
/// `reference_frames.dir` (relative to the inputs file), in reading order, decoded in the
/// inputs' pixel format.
///
/// ```no_run
/// use rodtrack_sdk::ReferenceFolder;
/// let path = std::path::Path::new("rec/cam0.json");
/// let inputs = rodtrack_sdk::read_inputs(path, &mut rodtrack_sdk::print_warning)?;
/// let folder = ReferenceFolder::open(&inputs, path)?;
/// println!("{} frames in {}", folder.files.len(), folder.dir.display());
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
#[derive(Debug, Clone)]
pub struct ReferenceFolder {
    /// The inputs file, for messages.
    pub name: String,
    /// The folder.
    pub dir: std::path::PathBuf,
    /// Its image files, in reading order.
    pub files: Vec<std::path::PathBuf>,
    /// The inputs' pixel format.
    pub format: PixelFormat,
}

impl ReferenceFolder {
    /// The reference folder of `inputs`, read from `path`; errors name the file and the field.
    ///
    /// ```no_run
    /// let path = std::path::Path::new("rec/cam0.json");
    /// let inputs = rodtrack_sdk::read_inputs(path, &mut rodtrack_sdk::print_warning)?;
    /// let folder = rodtrack_sdk::ReferenceFolder::open(&inputs, path)?;
    /// println!("{}", folder.format.name());
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn open(inputs: &CalibrationInputs, path: &Path) -> Result<ReferenceFolder, SdkError> {
        let name = path.display().to_string();
        let format = PixelFormat::from_name(&inputs.pixel_format).ok_or_else(|| {
            SdkError::file(
                path,
                format!(
                    "{name}: field `pixel_format`: unknown format {:?}",
                    inputs.pixel_format
                ),
            )
        })?;
        let dir = path
            .parent()
            .unwrap_or(Path::new("."))
            .join(&inputs.reference_frames.dir);
        let files = list_image_files(&dir).map_err(|e| {
            SdkError::file(path, format!("{name}: field `reference_frames.dir`: {e}"))
        })?;
        Ok(ReferenceFolder {
            name,
            dir,
            files,
            format,
        })
    }

    /// Frame `idx` of the folder, decoded; `what` (`rod 3: field `known_poses``) names who
    /// asked for it in the error when there is no such frame.
    ///
    /// ```no_run
    /// let path = std::path::Path::new("rec/cam0.json");
    /// let inputs = rodtrack_sdk::read_inputs(path, &mut rodtrack_sdk::print_warning)?;
    /// let folder = rodtrack_sdk::ReferenceFolder::open(&inputs, path)?;
    /// let frame = folder.read(inputs.reference_frames.reference_frame, "the reference frame")?;
    /// println!("{}x{}", frame.meta.width, frame.meta.height);
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn read(&self, idx: usize, what: &str) -> Result<FrameBuffer, SdkError> {
        let file = self.files.get(idx).ok_or_else(|| SdkError::File {
            path: self.name.clone(),
            reason: format!(
                "{}: {what}: frame {idx} does not exist ({} images in {})",
                self.name,
                self.files.len(),
                self.dir.display()
            ),
        })?;
        let mut buf = FrameBuffer::new();
        decode_image_file(file, Some(self.format), &mut buf).map_err(|e| SdkError::Io {
            context: format!("reference frame {}", file.display()),
            source: e,
        })?;
        Ok(buf)
    }
}

/// Calibrates every camera from its calibration-inputs file, in order (camera `i` from
/// `paths[i]`), into a validated calibration file. `warn` gets the inputs' warnings.
///
/// ```no_run
/// let paths = ["rec/cam0.json".as_ref(), "rec/cam1.json".as_ref()];
/// let cal = rodtrack_sdk::calibrate_files(&paths, &mut rodtrack_sdk::print_warning)?;
/// rodtrack_sdk::write_calibration("calib.toml".as_ref(), &cal)?;
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn calibrate_files(paths: &[&Path], warn: Warn<'_>) -> Result<CalibrationFile, SdkError> {
    let mut cameras = Vec::new();
    for (index, path) in paths.iter().enumerate() {
        let inputs = read_inputs(path, &mut *warn)?;
        cameras.push(calibrate_camera_file(&inputs, path, index as u32)?);
    }
    calibration_file(cameras)
}

/// The calibration file of `cameras`, validated.
///
/// ```
/// // Camera 0 of the simulator, calibrated as an operator would.
/// let mut sim = rodtrack_sim::build_simulation("exp3", Some(1), 1, false, "default").unwrap();
/// let camera = rodtrack_sim::calibrate_sim_camera(&mut sim, 0, 1).unwrap().calibration;
/// let file = rodtrack_sdk::calibration_file(vec![camera])?;
/// assert_eq!(file.cameras.len(), 1);
/// // Two cameras with the same index do not make a file.
/// let twice = vec![file.cameras[0].clone(), file.cameras[0].clone()];
/// assert!(rodtrack_sdk::calibration_file(twice).is_err());
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn calibration_file(cameras: Vec<CameraCalibration>) -> Result<CalibrationFile, SdkError> {
    let file = CalibrationFile {
        version: CALIBRATION_VERSION,
        cameras,
    };
    file.validate()
        .map_err(|e| SdkError::core("the calibration made is invalid", e))?;
    Ok(file)
}
