//! The ball seen by several cameras, as one `fused` row per frame.
//!
//! - Every camera whose row is `ok` is a candidate, weighted by the inverse variance of its
//!   position ([`crate::ball::BallTracker::row_sigma_mm`]: the detection's and the camera's
//!   systematic error in the table frame).
//! - Two candidates agree when their difference lies within [`AGREE_SIGMAS`] of their combined
//!   standard deviation; the fused position is the weighted mean of the largest agreeing group.
//! - Candidates that disagree are never averaged: the group the fused track's extrapolation
//!   (last fused position plus velocity times the interval) supports, alone within
//!   [`AGREE_SIGMAS`] of it, is reported `ok`; when none or several are, the row is
//!   `conflict` with the best-measured camera's position.
//! - No camera `ok`: the cameras' predictions, weighted alike, give a `predicted` row; none,
//!   `lost`.
//! - Hand-over: when the set of cameras in the fused position changes (a camera loses or
//!   finds the ball), the fused position would jump by the cameras' disagreement (their
//!   systematic errors). The jump, when it is within their uncertainties, is kept as an offset
//!   that decays with time constant [`HANDOVER_S`]: the fused track moves from one camera's
//!   frame to the other's smoothly. Not when the last fused row was `predicted` and this one
//!   is seen: the prediction's error (a bounce no camera saw) is no camera's offset, and the
//!   ball is where the cameras see it.
//!
//! No allocation per frame: the fuser holds its buffers.

use super::{BallRow, BallStatus};
use crate::{CameraId, Timestamp};

/// Agreement gate between two cameras' positions (and a camera and the fused track), in
/// standard deviations of their difference.
pub const AGREE_SIGMAS: f64 = 4.0;
/// Time constant of the hand-over between cameras, s: the offset between the cameras' frames
/// is spread over about this long (10 frames at 200 fps), much longer than one frame and much
/// shorter than a rally.
pub const HANDOVER_S: f64 = 0.05;
/// The most cameras fused (a bit set of their places).
pub const MAX_CAMERAS: usize = 64;

/// One camera's row of a frame with its position's standard deviation per axis, mm.
#[derive(Debug, Clone, Copy)]
pub struct CameraBall {
    /// The camera's row.
    pub row: BallRow,
    /// Its position's standard deviation per axis, mm (infinite when lost).
    pub sigma_mm: f64,
}

/// Fuses the cameras' rows of each frame into one `fused` row; see the module documentation.
///
/// ```
/// use rodtrack_core::ball::{BallFuser, BallRow, BallStatus, CameraBall};
/// use rodtrack_core::{CameraId, Timestamp};
/// let row = |cam: u32, x_mm: f64| BallRow {
///     frame: 0, timestamp_ns: Timestamp(0), camera: CameraId::Camera(cam),
///     x_mm, y_mm: 0.0, vx_mm_s: 0.0, vy_mm_s: 0.0, quality: 1.0, status: BallStatus::Ok,
/// };
/// let mut fuser = BallFuser::default();
/// // Both see it, camera 1 twice as well: the mean weighted 1 : 4.
/// let f = fuser.fuse(&[
///     CameraBall { row: row(0, 10.0), sigma_mm: 0.4 },
///     CameraBall { row: row(1, 10.5), sigma_mm: 0.2 },
/// ]);
/// assert_eq!(f.camera, CameraId::Fused);
/// assert_eq!(f.status, BallStatus::Ok);
/// assert!((f.x_mm - 10.4).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, Default)]
pub struct BallFuser {
    /// The last fused row that was not lost.
    last: Option<BallRow>,
    /// The cameras (places in the input) in the last fused position.
    last_set: u64,
    /// The hand-over offset added to the fused position, mm, and when it was set.
    offset_mm: [f64; 2],
    offset_ns: Timestamp,
}

impl BallFuser {
    /// The `fused` row of one frame from its cameras' rows (same frame, any order). Rows
    /// past [`MAX_CAMERAS`] are ignored.
    pub fn fuse(&mut self, cams: &[CameraBall]) -> BallRow {
        let cams = &cams[..cams.len().min(MAX_CAMERAS)];
        let (frame, timestamp_ns) = cams
            .first()
            .map(|c| (c.row.frame, c.row.timestamp_ns))
            .unwrap_or((0, Timestamp(0)));
        let mut out = BallRow::lost(frame, timestamp_ns, CameraId::Fused);
        let usable = |c: &CameraBall, s: BallStatus| {
            c.row.status == s && c.sigma_mm.is_finite() && c.sigma_mm > 0.0
        };
        let ok_set = set_of(cams, |c| usable(c, BallStatus::Ok));
        let (set, status) = if ok_set != 0 {
            self.choose(cams, ok_set)
        } else {
            let pred = set_of(cams, |c| usable(c, BallStatus::Predicted));
            (pred, BallStatus::Predicted)
        };
        if set == 0 {
            self.last = None;
            self.last_set = 0;
            self.offset_mm = [0.0; 2];
            return out;
        }
        let (m, sigma) = weighted(cams, set);
        let (mean, v) = ([m[0], m[1]], [m[2], m[3]]);
        out.quality = cams
            .iter()
            .enumerate()
            .filter(|(i, _)| set & (1 << i) != 0)
            .map(|(_, c)| c.row.quality)
            .fold(0.0, f64::max);
        // Hand-over: a change of the cameras used keeps the fused track where it was.
        let decay = |dt_s: f64| (-dt_s.max(0.0) / HANDOVER_S).exp();
        if let Some(prev) = &self.last {
            let dt = timestamp_ns.seconds_since(prev.timestamp_ns);
            // Only between measured rows: after predictions, the ball seen again is where the
            // cameras see it (the predictions' error is no camera's offset, and an offset left
            // from an earlier hand-over is gone with the cameras it was between).
            if set != self.last_set
                && prev.status == BallStatus::Predicted
                && status == BallStatus::Ok
            {
                self.offset_mm = [0.0; 2];
                self.offset_ns = timestamp_ns;
            } else if set != self.last_set && status != BallStatus::Conflict {
                let ex = [prev.x_mm + prev.vx_mm_s * dt, prev.y_mm + prev.vy_mm_s * dt];
                let jump = [ex[0] - mean[0], ex[1] - mean[1]];
                let bound = AGREE_SIGMAS * sigma.hypot(prev_sigma(cams, self.last_set));
                self.offset_mm = if jump[0].hypot(jump[1]) <= bound {
                    jump
                } else {
                    [0.0; 2]
                };
                self.offset_ns = timestamp_ns;
            }
        } else {
            self.offset_mm = [0.0; 2];
        }
        let k = decay(timestamp_ns.seconds_since(self.offset_ns));
        out.x_mm = mean[0] + k * self.offset_mm[0];
        out.y_mm = mean[1] + k * self.offset_mm[1];
        out.vx_mm_s = v[0];
        out.vy_mm_s = v[1];
        out.status = status;
        let out = out.sanitized();
        if out.status == BallStatus::Lost {
            self.last = None;
            self.last_set = 0;
        } else {
            self.last = Some(out);
            self.last_set = set;
        }
        out
    }

    /// The cameras to use among the `ok` ones (`ok_set`), and the status.
    fn choose(&self, cams: &[CameraBall], ok_set: u64) -> (u64, BallStatus) {
        // The largest group of mutually agreeing cameras; each candidate grows its own.
        let mut groups = [0u64; MAX_CAMERAS];
        let mut n_groups = 0;
        for (i, a) in cams.iter().enumerate() {
            if ok_set & (1 << i) == 0 {
                continue;
            }
            let mut g = 1u64 << i;
            for (j, b) in cams.iter().enumerate() {
                if j != i && ok_set & (1 << j) != 0 && agree(a, b) {
                    g |= 1 << j;
                }
            }
            if !groups[..n_groups].contains(&g) {
                groups[n_groups] = g;
                n_groups += 1;
            }
        }
        if n_groups == 1 {
            return (groups[0], BallStatus::Ok);
        }
        // Disagreement: the one group the fused track supports.
        if let Some(prev) = &self.last {
            let dt = cams[0].row.timestamp_ns.seconds_since(prev.timestamp_ns);
            let ex = [prev.x_mm + prev.vx_mm_s * dt, prev.y_mm + prev.vy_mm_s * dt];
            let prev_s = prev_sigma(cams, self.last_set);
            let mut supported = None;
            let mut count = 0;
            for &g in &groups[..n_groups] {
                let (m, s) = weighted(cams, g);
                let d = (m[0] - ex[0]).hypot(m[1] - ex[1]);
                if d <= AGREE_SIGMAS * s.hypot(prev_s) && supported != Some(g) {
                    supported = Some(g);
                    count += 1;
                }
            }
            if let (Some(g), 1) = (supported, count) {
                return (g, BallStatus::Ok);
            }
        }
        // No support: the best-measured camera's position, said to be in conflict.
        let best = cams
            .iter()
            .enumerate()
            .filter(|(i, _)| ok_set & (1 << i) != 0)
            .min_by(|a, b| a.1.sigma_mm.total_cmp(&b.1.sigma_mm))
            .map(|(i, _)| 1u64 << i)
            .unwrap_or(0);
        (best, BallStatus::Conflict)
    }
}

fn set_of(cams: &[CameraBall], keep: impl Fn(&CameraBall) -> bool) -> u64 {
    cams.iter()
        .enumerate()
        .filter(|(_, c)| keep(c))
        .fold(0, |s, (i, _)| s | (1 << i))
}

/// Whether two cameras' positions agree within their uncertainties.
fn agree(a: &CameraBall, b: &CameraBall) -> bool {
    let d = (a.row.x_mm - b.row.x_mm).hypot(a.row.y_mm - b.row.y_mm);
    d <= AGREE_SIGMAS * a.sigma_mm.hypot(b.sigma_mm)
}

/// The inverse-variance weighted mean of the cameras in `set` (x, y, vx, vy) and the
/// position's standard deviation.
fn weighted(cams: &[CameraBall], set: u64) -> ([f64; 4], f64) {
    let (mut m, mut wsum) = ([0.0; 4], 0.0);
    for (i, c) in cams.iter().enumerate() {
        if set & (1 << i) != 0 {
            let w = 1.0 / (c.sigma_mm * c.sigma_mm);
            let r = &c.row;
            for (acc, v) in m.iter_mut().zip([r.x_mm, r.y_mm, r.vx_mm_s, r.vy_mm_s]) {
                *acc += w * v;
            }
            wsum += w;
        }
    }
    if wsum > 0.0 {
        (m.map(|x| x / wsum), (1.0 / wsum).sqrt())
    } else {
        ([0.0; 4], f64::INFINITY)
    }
}

/// The standard deviation of the last fused position, from its cameras' present sigmas (the
/// smallest finite one when they are gone).
fn prev_sigma(cams: &[CameraBall], set: u64) -> f64 {
    let (_, s) = weighted(
        cams,
        set & set_of(cams, |c| c.sigma_mm.is_finite() && c.sigma_mm > 0.0),
    );
    if s.is_finite() {
        s
    } else {
        cams.iter()
            .map(|c| c.sigma_mm)
            .filter(|s| s.is_finite() && *s > 0.0)
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(c: u32, frame: u64, x_mm: f64, status: BallStatus, sigma_mm: f64) -> CameraBall {
        CameraBall {
            row: BallRow {
                frame,
                timestamp_ns: Timestamp(frame * 5_000_000),
                camera: CameraId::Camera(c),
                x_mm,
                y_mm: 0.0,
                vx_mm_s: 0.0,
                vy_mm_s: 0.0,
                quality: 1.0,
                status,
            },
            sigma_mm,
        }
    }

    /// One camera sees it: its position; none: lost.
    #[test]
    fn one_camera_alone_is_taken_and_none_is_lost() {
        let mut f = BallFuser::default();
        let r = f.fuse(&[
            cam(0, 0, 5.0, BallStatus::Lost, f64::INFINITY),
            cam(1, 0, 7.0, BallStatus::Ok, 0.3),
        ]);
        assert_eq!((r.status, r.x_mm), (BallStatus::Ok, 7.0));
        let r = f.fuse(&[
            cam(0, 1, 0.0, BallStatus::Lost, f64::INFINITY),
            cam(1, 1, 0.0, BallStatus::Lost, f64::INFINITY),
        ]);
        assert_eq!(r.status, BallStatus::Lost);
    }

    /// Two cameras 20 sigma apart are never averaged: without a track, a conflict at the
    /// better camera; with a track that one of them continues, that one.
    #[test]
    fn cameras_that_disagree_are_not_averaged() {
        let mut f = BallFuser::default();
        let r = f.fuse(&[
            cam(0, 0, 0.0, BallStatus::Ok, 0.5),
            cam(1, 0, 10.0, BallStatus::Ok, 0.3),
        ]);
        assert_eq!((r.status, r.x_mm), (BallStatus::Conflict, 10.0));
        let mut f = BallFuser::default();
        f.fuse(&[cam(0, 0, 0.0, BallStatus::Ok, 0.5)]);
        let r = f.fuse(&[
            cam(0, 1, 0.2, BallStatus::Ok, 0.5),
            cam(1, 1, 10.0, BallStatus::Ok, 0.3),
        ]);
        assert_eq!((r.status, r.x_mm), (BallStatus::Ok, 0.2));
    }

    /// A ball seen again after the cameras only predicted it (it bounced off a wall unseen,
    /// and the predictions ran on into the wall) is where the camera that sees it says, at
    /// once: the predictions' error is no camera's offset to hand over.
    #[test]
    fn a_ball_seen_again_after_predictions_is_where_the_camera_sees_it() {
        let mut f = BallFuser::default();
        let moving = |c: u32, frame: u64, x: f64, status: BallStatus, sigma: f64| {
            let mut b = cam(c, frame, x, status, sigma);
            b.row.vx_mm_s = 3000.0;
            b
        };
        // Camera 0 sees it rolling at 3 m/s (15 mm per frame), then camera 1 too (0.3 mm
        // beside it: an offset handed over).
        for frame in 0..5 {
            let x = 15.0 * frame as f64;
            let one = if frame >= 2 {
                moving(1, frame, x + 0.3, BallStatus::Ok, 0.5)
            } else {
                cam(1, frame, 0.0, BallStatus::Lost, f64::INFINITY)
            };
            f.fuse(&[moving(0, frame, x, BallStatus::Ok, 0.5), one]);
        }
        // Hidden for two frames: both predict it on at 3 m/s.
        for frame in 5..7 {
            let x = 15.0 * frame as f64;
            let r = f.fuse(&[
                moving(0, frame, x, BallStatus::Predicted, 1.0),
                moving(1, frame, x, BallStatus::Predicted, 1.0),
            ]);
            assert_eq!(r.status, BallStatus::Predicted);
        }
        // It bounced back within them: camera 1 sees it 7 mm short of the prediction (half
        // of it, behind a figure: its fit's sigma 2 mm), camera 0 still predicts.
        let seen = 15.0 * 7.0 - 7.0;
        let r = f.fuse(&[
            moving(0, 7, 15.0 * 7.0, BallStatus::Predicted, 1.2),
            cam(1, 7, seen, BallStatus::Ok, 2.0),
        ]);
        assert_eq!(r.status, BallStatus::Ok);
        assert!(
            (r.x_mm - seen).abs() < 1e-9,
            "fused at {:.3}, seen at {seen:.3}",
            r.x_mm
        );
    }

    /// A camera joining and leaving moves the fused track by less than a tenth of the
    /// cameras' 1 mm offset per frame, and it ends on the remaining camera.
    #[test]
    fn hand_over_between_cameras_is_without_a_jump() {
        let mut f = BallFuser::default();
        let mut xs = Vec::new();
        for frame in 0..90 {
            let a = cam(0, frame, 0.0, BallStatus::Ok, 0.4);
            let b_status = if frame >= 10 {
                BallStatus::Ok
            } else {
                BallStatus::Lost
            };
            let b = cam(1, frame, 1.0, b_status, 0.4);
            let a = if frame >= 30 {
                cam(0, frame, 0.0, BallStatus::Lost, f64::INFINITY)
            } else {
                a
            };
            xs.push(f.fuse(&[a, b]).x_mm);
        }
        let max_step = xs
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max);
        assert!(max_step < 0.1, "largest step {max_step:.3} mm: {xs:?}");
        assert!((xs[89] - 1.0).abs() < 0.01, "ends at {:.3}", xs[89]);
    }
}
