//! All of a camera's rods calibrated together: each rod from its reference frame and its known
//! poses, then again with the 3-D direction the rods share (they are parallel), which carries
//! the scale along the travel of the rods that have no known poses and cross-checks those that
//! have (see [`super::travel`]).

use super::compute::{calibrate_rod_with, RodExtras};
use super::file::RodCalibration;
use super::inputs::{KnownPose, RodInputs};
use super::travel::{line_plane, robust_common_direction};
use crate::camera::CameraIntrinsics;
use crate::frame::FrameView;
use crate::line::fit_line_tls;
use crate::CoreError;

/// Calibrates every rod of one camera. `frames` holds the reference folder's frames that the
/// rods' `reference.frame` and known poses name (index in name order, view); a known pose whose
/// frame is missing is an error of that rod. Each rod's result is its own: one rod's failure
/// does not stop the others.
pub fn calibrate_rods(
    rods: &[RodInputs],
    frames: &[(usize, FrameView)],
    intrinsics: Option<&CameraIntrinsics>,
) -> Vec<Result<RodCalibration, CoreError>> {
    let frame = |rod: u32, field: &str, i: usize| {
        frames
            .iter()
            .find(|(k, _)| *k == i)
            .map(|(_, v)| *v)
            .ok_or_else(|| CoreError::Calibration {
                rod,
                field: field.into(),
                reason: format!("frame {i} is not among the reference frames"),
            })
    };
    type Known<'a> = Vec<(KnownPose, FrameView<'a>)>;
    let inputs: Vec<Result<(FrameView, Known), CoreError>> = rods
        .iter()
        .map(|r| {
            let view = frame(r.rod, "reference.frame", r.reference.frame)?;
            let known = r
                .all_known_poses()
                .into_iter()
                .filter(|k| k.frame != r.reference.frame)
                .map(|k| Ok((k, frame(r.rod, "known_poses", k.frame)?)))
                .collect::<Result<Known, CoreError>>()?;
            Ok((view, known))
        })
        .collect();
    let pass = |direction: Option<[f64; 3]>| -> Vec<Result<RodCalibration, CoreError>> {
        rods.iter()
            .zip(&inputs)
            .map(|(r, i)| {
                let (view, known) = i.as_ref().map_err(Clone::clone)?;
                let extras = RodExtras { known, direction };
                calibrate_rod_with(r, view, intrinsics, &extras)
            })
            .collect()
    };
    let first = pass(None);
    let Some(k) = intrinsics else {
        return first;
    };
    let planes: Vec<([f64; 3], f64)> = first
        .iter()
        .filter_map(|c| c.as_ref().ok())
        .filter_map(|c| rod_plane(c, k))
        .collect();
    // The bare rods' outlines beside their markers, where three rods or more show one: over
    // the span each marker sweeps, far longer than its rings (module `limbs`).
    let mut outlined = 0;
    let mut outlines = Vec::new();
    for (c, i) in first.iter().zip(&inputs) {
        if let (Ok(c), Ok((view, _))) = (c, i) {
            let p = super::limbs::limb_planes(c, view, k);
            outlined += usize::from(!p.is_empty());
            outlines.extend(p);
        }
    }
    // Three rods at least: two always meet somewhere.
    let rods_ok = first.iter().filter(|c| c.is_ok()).count();
    let (direction, source) = match robust_common_direction(&outlines).filter(|_| outlined >= 3) {
        Some(d) => (
            Some(d),
            format!("outlines: {} sides of {outlined} rods", outlines.len()),
        ),
        None => (
            robust_common_direction(&planes).filter(|_| planes.len() >= 3),
            format!(
                "marker lines (the bare rods' outlines stand out from the background beside \
                 {outlined} of {rods_ok} rods, 3 needed)"
            ),
        ),
    };
    let Some(d) = direction else {
        return first;
    };
    let mut second = pass(Some(d));
    for c in second.iter_mut().flatten() {
        c.residuals.common_direction = source.clone();
    }
    second
}

/// The plane through the camera centre that holds a calibrated rod's line (its knots
/// undistorted), as in [`line_plane`], and its weight in the rods' common direction: the
/// square of the measured line's length (normalised units). A line's direction errs by its
/// points' error over its length, so a rod with a short travel (a goalkeeper's) or few
/// clicks fixes its plane's tilt less than a long one.
fn rod_plane(cal: &RodCalibration, k: &CameraIntrinsics) -> Option<([f64; 3], f64)> {
    let kn = &cal.knots;
    let marker_len = cal.marker.validate().ok()?.length_mm();
    let pts: Vec<[f64; 2]> = (0..kn.len())
        .filter(|&i| {
            let s = kn.s0_mm + i as f64 * kn.step_mm;
            // The marker's part of the line at the reference pose and the clicked span: what
            // was measured, not extrapolated.
            s >= cal.travel_mm[0] && s <= cal.travel_mm[1] + marker_len
        })
        .map(|i| {
            let (x, y) = k.pixel_to_normalized(kn.x_px[i], kn.y_px[i]);
            [x, y]
        })
        .collect();
    let (c, d) = fit_line_tls(&pts)?;
    let (a, b) = (pts.first()?, pts.last()?);
    let span = (a[0] - b[0]).hypot(a[1] - b[1]);
    Some((line_plane(c, d), span * span))
}
