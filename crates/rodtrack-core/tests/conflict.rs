//! Fusion never averages or picks blindly, and the first frame: two simulated cameras' raw rows
//! through [`FrameSetFilter`] (each camera's filter, the fusion and its filter), one camera's
//! rows corrupted by a Gray-step offset as a glare on its code does.
#![allow(clippy::unwrap_used, missing_docs)]

use rodtrack_core::angle::{wrap_2pi, wrap_pi};
use rodtrack_core::Timestamp;
use rodtrack_core::{CameraId, FrameSetFilter, Measurement, Mode, Status};
use std::f64::consts::TAU;

const FPS: f64 = 200.0;
const GRAY_STEP: f64 = TAU / 32.0;

/// The raw row of `camera` for rod 2 at frame `i`: a still rod at 10 mm, 1.0 rad, with a small
/// deterministic noise.
fn raw(camera: u32, i: u64, offset_rad: f64) -> Measurement {
    let noise = 0.001 * ((i as f64 * 1.7 + camera as f64).sin());
    let mut m = Measurement::empty(
        i,
        Timestamp::from_secs_f64(1.0 + i as f64 / FPS),
        CameraId::Camera(camera),
        2,
        Status::Ok,
    );
    m.position_mm = 10.0 + 0.01 * noise;
    m.angle_rad = wrap_2pi(1.0 + noise + offset_rad);
    m.quality = if offset_rad != 0.0 { 0.94 } else { 0.95 };
    m.turns_known = true;
    m
}

/// Runs `frames` frame sets; `glare(i)`: camera 0's offset at frame `i`. Returns every
/// frame's output rows.
fn run(frames: u64, glare: impl Fn(u64) -> f64) -> Vec<Vec<Measurement>> {
    let mut f = FrameSetFilter::new(Mode::Enhanced, true);
    (0..frames)
        .map(|i| {
            let set = [raw(0, i, glare(i)), raw(1, i, 0.0)];
            let mut out = Vec::new();
            f.process(&set, &mut out);
            out
        })
        .collect()
}

fn row(rows: &[Measurement], camera: CameraId) -> Measurement {
    *rows.iter().find(|m| m.camera == camera).unwrap()
}

fn wrong(m: &Measurement) -> bool {
    wrap_pi(m.angle_rad - 1.0).abs() > 0.2 || (m.position_mm - 10.0).abs() > 5.0
}

#[test]
fn a_glare_on_one_camera_is_overruled_and_flagged() {
    // Frames 48-59: camera 0 reads 12 Gray steps (2.36 rad) off, camera 1 right.
    let out = run(120, |i| {
        if (48..60).contains(&i) {
            12.0 * GRAY_STEP
        } else {
            0.0
        }
    });
    for (i, rows) in out.iter().enumerate() {
        let fused = row(rows, CameraId::Fused);
        let cam0 = row(rows, CameraId::Camera(0));
        assert!(
            !(fused.status == Status::Ok && wrong(&fused)),
            "frame {i}: fused ok and wrong: {fused:?}"
        );
        assert!(
            !(cam0.status == Status::Ok && wrong(&cam0)),
            "frame {i}: camera 0 ok and wrong: {cam0:?}"
        );
        if (48..60).contains(&i) {
            // The fused row takes camera 1; camera 0's row says it lost.
            assert_eq!(fused.status, Status::Ok, "frame {i}");
            assert_eq!(cam0.status, Status::Conflict, "frame {i}: {cam0:?}");
            assert_eq!(cam0.quality, 0.0);
        }
    }
}

#[test]
fn a_glare_from_the_first_frame_is_a_conflict_not_a_pick() {
    // No track yet to say which camera is right: the fused row reports the conflict.
    let out = run(40, |i| if i < 12 { 12.0 * GRAY_STEP } else { 0.0 });
    for (i, rows) in out.iter().enumerate() {
        let fused = row(rows, CameraId::Fused);
        assert!(
            !(fused.status == Status::Ok && wrong(&fused)),
            "frame {i}: {fused:?}"
        );
        if i < 12 {
            assert_eq!(fused.status, Status::Conflict, "frame {i}: {fused:?}");
            assert!(!fused.turns_known);
        }
    }
    // Once the cameras agree, the fused row is ok at once (two cameras corroborate).
    assert_eq!(row(&out[12], CameraId::Fused).status, Status::Ok);
    assert_eq!(row(&out[39], CameraId::Fused).status, Status::Ok);
}

#[test]
fn the_first_frame_is_ok_when_two_cameras_agree() {
    let out = run(5, |_| 0.0);
    let fused = row(&out[0], CameraId::Fused);
    assert_eq!(fused.status, Status::Ok, "{fused:?}");
    assert!(fused.turns_known);
    assert!(!wrong(&fused));
    assert!(fused.quality > 0.9, "{fused:?}");
    // One camera alone is not corroborated: its row waits for the second frame.
    assert_eq!(row(&out[0], CameraId::Camera(0)).status, Status::Predicted);
    assert_eq!(row(&out[1], CameraId::Camera(0)).status, Status::Ok);
}

#[test]
fn a_wrong_first_frame_of_one_camera_is_never_ok() {
    // Camera 0's first frame is a stripe period off: the cameras disagree on frame 0, nothing
    // is confirmed on it, and no row is ever ok with a wrong value.
    let out = run(30, |i| if i == 0 { TAU / 8.0 } else { 0.0 });
    assert_ne!(row(&out[0], CameraId::Fused).status, Status::Ok);
    for (i, rows) in out.iter().enumerate() {
        for m in rows {
            assert!(!(m.status == Status::Ok && wrong(m)), "frame {i}: {m:?}");
        }
    }
    assert_eq!(row(&out[29], CameraId::Fused).status, Status::Ok);
}
