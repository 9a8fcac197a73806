//! The known poses read back with the final calibration (a first frame: nothing learnt):
//! their position errors, and where their angle is given, the centre line moved across the
//! rod to where the angle says it is, then the angle's bias left there.
//!
//! A known pose's angle read off by `b` says that the line the tracker reads the print around
//! is beside the rod's: the phase samples the print at the wrong surface angles, by about
//! `offset / (R cos d)` at angle `d` from the facing line. Left as an angle bias (added to
//! every reading near that position), that is right only at the known pose's own angle: the
//! samples' and the Gray edges' weights move with the angle, and with them how much of the
//! offset the reading takes up. Moved into the line it is right at every angle. The
//! reading's sensitivity to the line (rad per px) is measured on the frame itself, by
//! reading it again with the line moved across by [`PROBE_PX`].

use super::file::{angle_bias_at, RodCalibration};
use super::inputs::KnownPose;
use crate::angle::{wrap_2pi, wrap_pi};
use crate::frame::FrameView;
use crate::line::Knots;
use crate::marker::Marker;
use crate::track::{Mode, RodResult, RodTracker};
use crate::{CoreError, Status};
use std::f64::consts::TAU;

/// The most a known pose's angle may be off before it is taken as a wrong pose rather than
/// a bias (a pixel of centre line across an 11 px radius is 0.09 rad; the biases measured are
/// a few hundredths of that).
pub(super) const MAX_ANGLE_BIAS_RAD: f64 = 0.05;

/// How far across the rod the line is moved to measure the reading's sensitivity to it, px:
/// small beside the rod's radius (the reading is linear in it), large beside the noise.
const PROBE_PX: f64 = 0.25;

/// A rod's marker, its reference frame and the angle it stands at there.
pub(super) struct Reference<'a> {
    pub(super) marker: &'a Marker,
    pub(super) frame: &'a FrameView<'a>,
    pub(super) angle_rad: f64,
}

/// Reads the known poses back with `cal` (see the module's documentation): records their
/// position errors in the residuals, moves the centre line by what their angles say (then
/// the angle's offset at the reference pose again), and keeps what is left of their angles'
/// errors as the angle's bias along the travel.
pub(super) fn read_back_known_poses(
    cal: &mut RodCalibration,
    known: &[(KnownPose, FrameView)],
    reference: &Reference,
) -> Result<(), CoreError> {
    let s_ref = cal.reference_position_mm;
    let c0 = reference.marker.bit_space_centre_mm(0);
    // The line's offset each known angle asks for, at the phase rows' place along the line.
    let mut shifts: Vec<[f64; 2]> = Vec::new();
    for (kp, kframe) in known {
        let Some(a) = kp.angle_rad else { continue };
        let Some(r) = read(cal, kframe)? else {
            continue;
        };
        let b = wrap_pi(r - a);
        if b.abs() > MAX_ANGLE_BIAS_RAD {
            continue;
        }
        let mut probe = cal.clone();
        shift_across(&mut probe.knots, &[], PROBE_PX);
        let Some(rp) = read(&probe, kframe)? else {
            continue;
        };
        let k = wrap_pi(rp - r) / PROBE_PX;
        // At most what the largest bias taken asks for with the nominal sensitivity (one
        // radian per radius) twice over: a reading that hardly moves with the line cannot
        // place it.
        let shift = -b / k;
        let radius = cal.knots.at(kp.position_mm + c0).radius_px;
        if shift.is_finite() && shift.abs() <= 2.0 * MAX_ANGLE_BIAS_RAD * radius {
            shifts.push([kp.position_mm + c0, shift]);
        }
    }
    if !shifts.is_empty() {
        shifts.push([s_ref + c0, 0.0]);
        let shifts = merge_points(shifts);
        let before = cal.knots.clone();
        shift_across(&mut cal.knots, &shifts, 0.0);
        let r = first_frame(cal, reference.frame)?;
        if r.status == Status::Ok {
            let steps = reference.marker.steps() as f64;
            cal.enhanced.angle_offset_rad =
                wrap_2pi(r.theta_steps * TAU / steps - reference.angle_rad);
        } else {
            // The angle's offset cannot follow the moved line: keep the line as it was.
            cal.knots = before;
            cal.residuals.warnings.push(format!(
                "the reference frame reads as {} with the line moved by the known poses' \
                 angles: the line is left where the silhouettes put it",
                r.status
            ));
        }
    }
    let mut bias: Vec<[f64; 2]> = Vec::new();
    for (kp, kframe) in known {
        let r = first_frame(cal, kframe)?;
        if r.status == Status::Ok {
            cal.residuals
                .known_pose_errors_mm
                .push([kp.frame as f64, r.position_mm - kp.position_mm]);
            if let Some(a) = kp.angle_rad {
                let b = wrap_pi(r.angle_rad - a);
                if b.abs() <= MAX_ANGLE_BIAS_RAD {
                    bias.push([kp.position_mm, b]);
                } else {
                    cal.residuals.warnings.push(format!(
                        "known pose in frame {}: angle read {b:+.3} rad off the one given; \
                         check the pose (not used for the angle)",
                        kp.frame
                    ));
                }
            }
        } else {
            cal.residuals.warnings.push(format!(
                "known pose in frame {} reads as {}",
                kp.frame, r.status
            ));
        }
    }
    if !bias.is_empty() {
        bias.push([s_ref, 0.0]);
        cal.enhanced.angle_bias_rad = merge_points(bias);
    }
    Ok(())
}

/// The angle `cal` reads in `frame` from a fresh tracker, when it reads it `ok`.
fn read(cal: &RodCalibration, frame: &FrameView) -> Result<Option<f64>, CoreError> {
    let r = first_frame(cal, frame)?;
    Ok((r.status == Status::Ok).then_some(r.angle_rad))
}

/// What a tracker fresh from `cal` reads in `frame` (its first frame: nothing learnt).
fn first_frame(cal: &RodCalibration, frame: &FrameView) -> Result<RodResult, CoreError> {
    let mut t = RodTracker::new(cal, frame.width(), frame.height(), Mode::Enhanced)?;
    t.process(frame)
}

/// Moves every knot across the line (towards the left of its direction, as
/// [`crate::line::LinePoint::offset`] does) by `extra_px` plus the offset interpolated at its
/// `s` from `points` (`[s_mm, px]`, sorted; held beyond the ends; none: 0).
fn shift_across(knots: &mut Knots, points: &[[f64; 2]], extra_px: f64) {
    let n = knots.x_px.len();
    if n < 2 {
        return;
    }
    let (x0, y0) = (knots.x_px.clone(), knots.y_px.clone());
    for i in 0..n {
        let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
        let (dx, dy) = (x0[b] - x0[a], y0[b] - y0[a]);
        let len = (dx * dx + dy * dy).sqrt();
        if len <= 0.0 {
            continue;
        }
        let (tx, ty) = (dx / len, dy / len);
        let s = knots.s0_mm + i as f64 * knots.step_mm;
        let d = extra_px + angle_bias_at(points, s);
        knots.x_px[i] = x0[i] - ty * d;
        knots.y_px[i] = y0[i] + tx * d;
    }
}

/// Points sorted by position, those within 1 mm of each other averaged.
fn merge_points(mut pts: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]));
    let mut out: Vec<([f64; 2], f64)> = Vec::new();
    for p in pts {
        match out.last_mut() {
            Some((q, n)) if (p[0] - q[0] / *n).abs() <= 1.0 => {
                q[0] += p[0];
                q[1] += p[1];
                *n += 1.0;
            }
            _ => out.push((p, 1.0)),
        }
    }
    out.into_iter().map(|(q, n)| [q[0] / n, q[1] / n]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(n: usize) -> Knots {
        Knots {
            s0_mm: -10.0,
            step_mm: 2.0,
            x_px: (0..n).map(|i| 100.0 + 0.1 * i as f64).collect(),
            y_px: (0..n).map(|i| 50.0 + 2.0 * i as f64).collect(),
            radius_px: vec![11.0; n],
        }
    }

    #[test]
    fn the_line_moves_across_by_the_interpolated_offset() {
        let mut k = straight(11);
        let before = k.clone();
        // 0 px at s = 0 (knot 5), 1 px at s = 10 (knot 10), held before s = 0.
        shift_across(&mut k, &[[0.0, 0.0], [10.0, 1.0]], 0.0);
        for i in 0..11 {
            let want = if i <= 5 { 0.0 } else { (i - 5) as f64 / 5.0 };
            let (dx, dy) = (k.x_px[i] - before.x_px[i], k.y_px[i] - before.y_px[i]);
            let moved = (dx * dx + dy * dy).sqrt();
            assert!(
                (moved - want).abs() < 1e-9,
                "knot {i}: moved {moved}, want {want}"
            );
            // Across: perpendicular to the line's direction (0.1, 2) / |.|.
            assert!(
                (dx * 0.1 + dy * 2.0).abs() < 1e-9,
                "knot {i} moved along the line"
            );
            // Towards the left of the direction, as LinePoint::offset's positive `across`.
            if want > 0.0 {
                assert!(dx < 0.0, "knot {i}: dx {dx}");
            }
        }
        let p = before.at(8.0).offset(0.0, 0.8);
        let q = k.at(8.0);
        assert!((p.0 - q.x).abs() < 1e-9 && (p.1 - q.y).abs() < 1e-9);
    }

    #[test]
    fn points_within_a_millimetre_are_averaged() {
        let m = merge_points(vec![[5.0, 1.0], [0.0, 2.0], [5.5, 3.0]]);
        assert_eq!(m, vec![[0.0, 2.0], [5.25, 2.0]]);
    }
}
