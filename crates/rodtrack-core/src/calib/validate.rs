//! Checks of calibration inputs and calibration files made before anything is allocated or
//! computed from them: sizes, counts and ranges that would otherwise make calibration or
//! tracking allocate without bound, plus the references between fields (rod ids unique, rods
//! present). Errors name the camera, the rod and the field.

use super::file::{CalibrationFile, CameraCalibration, CALIBRATION_VERSION};
use super::inputs::CalibrationInputs;
use crate::CoreError;

/// The largest rod id accepted (`u32::MAX` is reserved).
pub const MAX_ROD_ID: u32 = 65_535;
/// The most rods one camera may calibrate.
pub const MAX_RODS_PER_CAMERA: usize = 256;
/// The largest travel accepted, mm, from either end of the range (10 m: table-football rods
/// travel about 0.2 m).
pub const MAX_TRAVEL_MM: f64 = 10_000.0;
/// The largest image side accepted, px.
pub const MAX_IMAGE_SIDE: usize = 16_384;
/// The highest frame rate accepted, frames/s.
pub const MAX_FPS: f64 = 100_000.0;
/// The most path points one rod may have.
pub const MAX_PATH_POINTS: usize = 10_000;

fn cam_err(camera: &str, field: &str, reason: String) -> CoreError {
    CoreError::CameraField {
        camera: camera.to_string(),
        field: field.to_string(),
        reason,
    }
}

fn rod_err(rod: u32, field: &str, reason: String) -> CoreError {
    CoreError::Calibration {
        rod,
        field: field.to_string(),
        reason,
    }
}

/// Checks a rod id.
pub fn check_rod_id(rod: u32) -> Result<(), CoreError> {
    if rod > MAX_ROD_ID {
        return Err(rod_err(
            rod,
            "rod",
            format!("must be at most {MAX_ROD_ID}, got {rod}"),
        ));
    }
    Ok(())
}

/// Checks a travel range `[min, max]`, mm.
pub fn check_travel(rod: u32, travel_mm: [f64; 2]) -> Result<(), CoreError> {
    let [a, b] = travel_mm;
    let ok = a.is_finite()
        && b.is_finite()
        && a <= b
        && a.abs() <= MAX_TRAVEL_MM
        && b.abs() <= MAX_TRAVEL_MM;
    if !ok {
        return Err(rod_err(
            rod,
            "travel_mm",
            format!(
                "must be [min, max] with min <= max, both within +-{MAX_TRAVEL_MM} mm, got [{a}, {b}]"
            ),
        ));
    }
    Ok(())
}

/// Checks the rods' ids: within range and each given once.
pub fn check_rod_ids(
    camera: &str,
    field: &str,
    ids: impl IntoIterator<Item = u32>,
) -> Result<(), CoreError> {
    let mut seen: Vec<(u32, usize)> = Vec::new();
    for (i, id) in ids.into_iter().enumerate() {
        check_rod_id(id)?;
        if let Some((_, first)) = seen.iter().find(|(s, _)| *s == id) {
            return Err(rod_err(
                id,
                "rod",
                format!(
                    "is given twice in camera {camera} (`{field}[{first}]` and `{field}[{i}]`): \
                     one rod's data would be lost"
                ),
            ));
        }
        if seen.len() >= MAX_RODS_PER_CAMERA {
            return Err(cam_err(
                camera,
                field,
                format!("more than {MAX_RODS_PER_CAMERA} rods"),
            ));
        }
        seen.push((id, i));
    }
    if seen.is_empty() {
        return Err(cam_err(
            camera,
            field,
            "is empty: no rod to calibrate".into(),
        ));
    }
    Ok(())
}

fn check_image_size(camera: &str, field: &str, w: usize, h: usize) -> Result<(), CoreError> {
    if !(16..=MAX_IMAGE_SIDE).contains(&w) || !(16..=MAX_IMAGE_SIDE).contains(&h) {
        return Err(cam_err(
            camera,
            field,
            format!("must be 16 to {MAX_IMAGE_SIDE} px each, got {w}x{h}"),
        ));
    }
    Ok(())
}

fn check_fps(camera: &str, field: &str, fps: f64) -> Result<(), CoreError> {
    if !(fps.is_finite() && fps > 0.0 && fps <= MAX_FPS) {
        return Err(cam_err(
            camera,
            field,
            format!("must be a frame rate above 0 and at most {MAX_FPS}, got {fps}"),
        ));
    }
    Ok(())
}

/// Checks one camera's calibration inputs (camera `index` in the run) before calibrating:
/// image size, frame rate, rods present, rod ids unique and in range, travel ranges, path
/// point counts and values.
pub fn validate_inputs(inputs: &CalibrationInputs, index: u32) -> Result<(), CoreError> {
    let camera = format!("{index} ({})", inputs.camera_name);
    let s = inputs.image_size;
    check_image_size(&camera, "image_size", s.width, s.height)?;
    if let Some(fps) = inputs.fps {
        check_fps(&camera, "fps", fps)?;
    }
    check_rod_ids(&camera, "rods", inputs.rods.iter().map(|r| r.rod))?;
    for r in &inputs.rods {
        check_travel(r.rod, r.travel_mm)?;
        let n = r.path_points_px.len();
        if n > MAX_PATH_POINTS {
            return Err(rod_err(
                r.rod,
                "path_points_px",
                format!("has {n} points, at most {MAX_PATH_POINTS} accepted"),
            ));
        }
        if let Some(i) = r
            .path_points_px
            .iter()
            .position(|p| !(p[0].is_finite() && p[1].is_finite()))
        {
            return Err(rod_err(
                r.rod,
                "path_points_px",
                format!("entry {i} is not a finite point"),
            ));
        }
        let p = r.reference;
        if !(p.position_mm.is_finite() && p.angle_rad.is_finite()) {
            return Err(rod_err(r.rod, "reference", "must be finite".into()));
        }
    }
    Ok(())
}

/// Checks one camera of a calibration file: size, frame rate, rods unique and in range,
/// travel ranges. Called by [`CalibrationFile::validate`].
pub fn validate_camera(cam: &CameraCalibration) -> Result<(), CoreError> {
    let camera = cam.index.to_string();
    let field = |f: &str| format!("cameras[{}].{f}", cam.index);
    check_image_size(
        &camera,
        &field("image_width/height"),
        cam.image_width,
        cam.image_height,
    )?;
    check_fps(&camera, &field("fps"), cam.fps)?;
    check_rod_ids(&camera, &field("rods"), cam.rods.iter().map(|r| r.rod))?;
    for r in &cam.rods {
        check_travel(r.rod, r.travel_mm)?;
    }
    if let Some(t) = &cam.table {
        if cam.opencv_model.is_none() {
            return Err(cam_err(
                &camera,
                "table",
                "needs the camera model (`opencv_model`) it was measured with".into(),
            ));
        }
        t.validate(&camera)?;
    }
    if let Some(b) = &cam.ball {
        if cam.table.is_none() {
            return Err(cam_err(
                &camera,
                "ball",
                "needs the table frame (`[cameras.table]`) to place the ball".into(),
            ));
        }
        b.validate(&camera)?;
    }
    Ok(())
}

/// Checks that camera indices are unique in a calibration file.
pub fn validate_file(file: &CalibrationFile) -> Result<(), CoreError> {
    for (i, c) in file.cameras.iter().enumerate() {
        if file.cameras[..i].iter().any(|d| d.index == c.index) {
            return Err(cam_err(
                &c.index.to_string(),
                "cameras.index",
                "is given twice".into(),
            ));
        }
    }
    Ok(())
}

impl CalibrationFile {
    /// Checks every field; the error names the camera, rod and field.
    pub fn validate(&self) -> Result<(), CoreError> {
        if self.version != CALIBRATION_VERSION {
            return Err(CoreError::FileField {
                field: "version".into(),
                reason: format!("must be {CALIBRATION_VERSION}, got {}", self.version),
            });
        }
        validate_file(self)?;
        for cam in &self.cameras {
            cam.format()?;
            validate_camera(cam)?;
            for rod in &cam.rods {
                rod.validate(cam.image_width, cam.image_height)?;
            }
        }
        Ok(())
    }
}
