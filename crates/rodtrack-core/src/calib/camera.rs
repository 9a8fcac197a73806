//! One camera's calibration from its inputs and its reference frames, already in memory.

use super::ball::calibrate_ball;
use super::file::CameraCalibration;
use super::inputs::CalibrationInputs;
use super::rods::calibrate_rods;
use super::table::calibrate_table;
use crate::{CameraIntrinsics, CoreError, FrameView};

/// Calibrates every rod of camera `index` from its inputs and the frames they name: `frames`
/// holds `(frame index, view)` for each rod's reference frame and known poses. Every view must
/// have the inputs' `image_size`; the pixel format is the views'. `default_fps` is used when
/// the inputs give no `fps`.
///
/// The rods are calibrated together ([`calibrate_rods`]: their common direction feeds each
/// rod's along-travel model); the first rod that fails gives the error, which names the rod.
///
/// ```no_run
/// # fn demo(inputs: &rodtrack_core::calib::CalibrationInputs, view: rodtrack_core::FrameView<'_>)
/// # -> Result<(), rodtrack_core::CoreError> {
/// let frames = [(inputs.reference_frames.reference_frame, view)];
/// let cal = rodtrack_core::calib::calibrate_camera(inputs, &frames, 0, 200.0)?;
/// println!("{} rods calibrated", cal.rods.len());
/// # Ok(()) }
/// ```
pub fn calibrate_camera(
    inputs: &CalibrationInputs,
    frames: &[(usize, FrameView)],
    index: u32,
    default_fps: f64,
) -> Result<CameraCalibration, CoreError> {
    let camera = || format!("{index} ({})", inputs.camera_name);
    let field = |field: &str, reason: String| CoreError::CameraField {
        camera: camera(),
        field: field.to_string(),
        reason,
    };
    let intrinsics = inputs
        .opencv_model_optional
        .as_ref()
        .map(|m| CameraIntrinsics::from_opencv(m.camera_matrix, &m.dist_coeffs))
        .transpose()
        .map_err(|e| field("opencv_model_optional", e.to_string()))?;
    let Some((_, first)) = frames.first() else {
        return Err(field(
            "reference_frames",
            "no frame given to calibrate from".into(),
        ));
    };
    let size = &inputs.image_size;
    for (i, view) in frames {
        if view.width() != size.width || view.height() != size.height {
            return Err(field(
                "image_size",
                format!(
                    "says {}x{} but frame {i} is {}x{}",
                    size.width,
                    size.height,
                    view.width(),
                    view.height()
                ),
            ));
        }
    }
    let rods = calibrate_rods(&inputs.rods, frames, intrinsics.as_ref())
        .into_iter()
        .collect::<Result<Vec<_>, _>>()?;
    let name = camera();
    let table = match (&inputs.table, &intrinsics) {
        (Some(t), Some(k)) => Some(calibrate_table(t, k, &name)?),
        (Some(_), None) => {
            return Err(field(
                "table",
                "needs the camera model (`opencv_model_optional` or `opencv_model_file`)".into(),
            ))
        }
        (None, _) => None,
    };
    let ball = match (&inputs.ball, &table, &intrinsics) {
        (Some(b), Some(t), Some(k)) => {
            let Some((_, view)) = frames.iter().find(|(i, _)| *i == b.frame) else {
                return Err(field(
                    "ball.frame",
                    format!("frame {} was not given to calibrate from", b.frame),
                ));
            };
            Some(calibrate_ball(b, view, t, k, &name)?)
        }
        (Some(_), _, _) => {
            return Err(field(
                "ball",
                "needs the table frame (`table.points`) to place the ball".into(),
            ))
        }
        (None, _, _) => None,
    };
    Ok(CameraCalibration {
        name: inputs.camera_name.clone(),
        index,
        image_width: size.width,
        image_height: size.height,
        pixel_format: first.format().name().to_string(),
        fps: inputs.fps.unwrap_or(default_fps),
        opencv_model: inputs.opencv_model_optional.clone(),
        table,
        ball,
        rods,
    })
}

/// [`calibrate_camera`] from one frame in which every rod is at its reference pose (no known
/// poses): the simulator's and the console's case. The inputs' `ball` is left out (its click
/// is in a frame of its own: use [`calibrate_camera`] with that frame).
pub fn calibrate_camera_from_view(
    inputs: &CalibrationInputs,
    view: &FrameView,
    index: u32,
    default_fps: f64,
) -> Result<CameraCalibration, CoreError> {
    let mut frames: Vec<(usize, FrameView)> = Vec::new();
    for r in &inputs.rods {
        if !frames.iter().any(|(i, _)| *i == r.reference.frame) {
            frames.push((r.reference.frame, *view));
        }
    }
    if frames.is_empty() {
        frames.push((inputs.reference_frames.reference_frame, *view));
    }
    if inputs.ball.is_some() {
        // The ball has its own frame, which this one view is not: no ball colour here.
        let mut without_ball = inputs.clone();
        without_ball.ball = None;
        return calibrate_camera(&without_ball, &frames, index, default_fps);
    }
    calibrate_camera(inputs, &frames, index, default_fps)
}
