//! The fusion of several cameras' rows of one rod: the std it gains, quality weights, a
//! disagreeing or out-of-sync camera, missing rows.

use super::support::*;
use rodtrack_core::angle::wrap_2pi;
use rodtrack_core::filter::{FilterBank, FilterConfig};
use rodtrack_core::fusion::{Fuser, FusionConfig};
use rodtrack_core::Timestamp;
use rodtrack_core::{CameraId, Measurement, Status};
use std::f64::consts::{PI, TAU};

fn two_cameras(i: usize, t: &Truth, rng: &mut Rng) -> [Measurement; 2] {
    [row(0, i, t, rng), row(1, i, t, rng)]
}

#[test]
fn fusion_of_two_equal_cameras_divides_the_std_by_sqrt2() {
    let tr = truth(6000, |t| (20.0 + 10.0 * t, 6.2 + 0.5 * t));
    let mut rng = Rng::new(13);
    let mut fuser = Fuser::new(FusionConfig::default());
    let mut out = Vec::new();
    let (mut e1p, mut e1a, mut efp, mut efa) = (vec![], vec![], vec![], vec![]);
    for (i, t) in tr.iter().enumerate() {
        let rows = two_cameras(i, t, &mut rng);
        out.clear();
        fuser.fuse(&rows, None, &mut out);
        assert_eq!(out.len(), 1);
        let f = out[0];
        assert_eq!(f.camera, CameraId::Fused);
        assert_eq!(f.status, Status::Ok);
        assert!(fuser.disagreements().is_empty() && fuser.out_of_sync().is_empty());
        e1p.push(rows[0].position_mm - t.position_mm);
        e1a.push(rodtrack_core::filter::wrap_pi(
            rows[0].angle_rad - t.angle_rad,
        ));
        efp.push(f.position_mm - t.position_mm);
        // The truth crosses 2 pi: the circle mean must not break there.
        efa.push(rodtrack_core::filter::wrap_pi(f.angle_rad - t.angle_rad));
    }
    let rp = std(&efp) / std(&e1p);
    let ra = std(&efa) / std(&e1a);
    println!("fused / single std: position {rp:.3}, angle {ra:.3} (1/sqrt2 = 0.707)");
    for r in [rp, ra] {
        assert!(
            (r - 0.5f64.sqrt()).abs() < 0.15 * 0.5f64.sqrt(),
            "ratio {r}"
        );
    }
    assert!(
        efa.iter().all(|e| e.abs() < 0.1),
        "circle mean broke at 0 / 2 pi"
    );
}

#[test]
fn fusion_weights_by_quality() {
    let t = Truth {
        t: 1.0,
        position_mm: 0.0,
        angle_rad: 1.0,
    };
    let mut rng = Rng::new(14);
    let mut rows = two_cameras(0, &t, &mut rng);
    rows[0].position_mm = 0.0;
    rows[1].position_mm = 1.0;
    rows[0].quality = 1.0;
    rows[1].quality = 0.5;
    let mut fuser = Fuser::new(FusionConfig::default());
    let mut out = Vec::new();
    fuser.fuse(&rows, None, &mut out);
    // Weights 1 : 0.25.
    assert!((out[0].position_mm - 0.2).abs() < 1e-9, "{:?}", out[0]);
}

#[test]
fn disagreeing_camera_is_detected_and_resolved_by_the_filter() {
    let tr = truth(200, |t| (30.0 * t, 1.0 + 3.0 * t));
    let mut rng = Rng::new(15);
    let mut fuser = Fuser::new(FusionConfig::default());
    let mut bank = FilterBank::with_rods(FilterConfig::default(), [3]);
    let mut out = Vec::new();
    for (i, t) in tr.iter().enumerate() {
        let mut rows = two_cameras(i, t, &mut rng);
        let bad = i >= 100 && i % 10 == 0;
        if bad {
            // Camera 1 decodes one stripe period off, or its correlation peak one cell off.
            if i % 20 == 0 {
                rows[1].angle_rad = wrap_2pi(rows[1].angle_rad + PI / 4.0);
            } else {
                rows[1].position_mm += 4.0;
            }
        }
        // Without a referee: no ok value from two disagreeing cameras.
        let mut raw = Vec::new();
        fuser.fuse(&rows, None, &mut raw);
        out.clear();
        fuser.process(&rows, &mut bank, &mut out);
        let f = out[0];
        if bad {
            assert_eq!(raw[0].status, Status::Conflict);
            let d = fuser.disagreements();
            assert_eq!(d.len(), 1, "frame {i}");
            assert_eq!(d[0].cameras, [CameraId::Camera(0), CameraId::Camera(1)]);
            assert_eq!(d[0].rod, 3);
            assert!(d[0].angle_diff_rad.abs() > 0.5 || d[0].position_diff_mm.abs() > 3.0);
            // The filter's prediction picks camera 0.
            assert_eq!(f.status, Status::Ok, "frame {i}");
        } else {
            assert!(fuser.disagreements().is_empty());
        }
        if i > 3 {
            assert_eq!(f.status, Status::Ok);
            assert!((f.position_mm - t.position_mm).abs() < 1.0);
            assert!((f.angle_unwrapped_rad - t.angle_rad).abs() < 0.05);
        }
    }
}

#[test]
fn three_cameras_majority_wins_without_a_filter() {
    let t = Truth {
        t: 1.0,
        position_mm: 5.0,
        angle_rad: 2.0,
    };
    let mut rng = Rng::new(16);
    let mut rows = vec![
        row(0, 7, &t, &mut rng),
        row(1, 7, &t, &mut rng),
        row(2, 7, &t, &mut rng),
    ];
    rows[2].angle_rad += TAU / 32.0;
    let mut fuser = Fuser::new(FusionConfig::default());
    let mut out = Vec::new();
    fuser.fuse(&rows, None, &mut out);
    assert_eq!(out[0].status, Status::Ok);
    assert!((out[0].angle_rad - 2.0).abs() < 0.05);
    assert_eq!(fuser.disagreements().len(), 2);
}

#[test]
fn out_of_sync_camera_is_detected_and_left_out() {
    let t = Truth {
        t: 2.0,
        position_mm: 5.0,
        angle_rad: 2.0,
    };
    let mut rng = Rng::new(17);
    let mut fuser = Fuser::new(FusionConfig::default());
    let mut out = Vec::new();
    // Camera 1 is 3 ms late.
    let mut rows = two_cameras(42, &t, &mut rng);
    rows[1].timestamp_ns = Timestamp(rows[1].timestamp_ns.as_nanos() + 3_000_000);
    rows[1].position_mm += 20.0;
    fuser.fuse(&rows, None, &mut out);
    let s = fuser.out_of_sync();
    assert_eq!(s.len(), 1);
    assert_eq!(s[0].camera, CameraId::Camera(1));
    assert_eq!(s[0].reference, CameraId::Camera(0));
    assert!((s[0].offset_s - 0.003).abs() < 1e-9);
    assert_eq!(out[0].status, Status::Ok);
    assert!(
        (out[0].position_mm - 5.0).abs() < 1.5,
        "the late camera is not fused"
    );
    assert_eq!(out[0].timestamp_s(), 2.0);
    // Within the window: in sync.
    rows[1].timestamp_ns = Timestamp::from_secs_f64(2.0005);
    rows[1].position_mm = rows[0].position_mm;
    out.clear();
    fuser.fuse(&rows, None, &mut out);
    assert!(fuser.out_of_sync().is_empty());
    // A different frame id is out of sync whatever the time; with three cameras the two that
    // agree are the reference.
    let mut rows = vec![
        row(0, 9, &t, &mut rng),
        row(1, 9, &t, &mut rng),
        row(2, 9, &t, &mut rng),
    ];
    rows[0].frame = 8;
    out.clear();
    fuser.fuse(&rows, None, &mut out);
    let s = fuser.out_of_sync();
    assert_eq!(s.len(), 1);
    assert_eq!(s[0].camera, CameraId::Camera(0));
    assert_eq!((s[0].frame, s[0].reference_frame), (8, 9));
    assert_eq!(out[0].frame, 9);
}

#[test]
fn fusion_of_missing_rows_keeps_one_row_per_rod() {
    let t = Truth {
        t: 1.0,
        position_mm: 5.0,
        angle_rad: 2.0,
    };
    let mut rng = Rng::new(18);
    let mut rows = Vec::new();
    for rod in 0..4u32 {
        for cam in 0..2 {
            let mut m = row(cam, 1, &t, &mut rng);
            m.rod = rod;
            if rod == 1 && cam == 0 {
                m = missing(&m, Status::Occluded);
            }
            if rod == 2 {
                m = missing(
                    &m,
                    if cam == 0 {
                        Status::NotFound
                    } else {
                        Status::OutOfView
                    },
                );
            }
            rows.push(m);
        }
    }
    rows.reverse();
    let mut fuser = Fuser::new(FusionConfig::default());
    let mut out = Vec::new();
    fuser.fuse(&rows, None, &mut out);
    let rods: Vec<u32> = out.iter().map(|m| m.rod).collect();
    assert_eq!(rods, [0, 1, 2, 3]);
    assert!(out.iter().all(|m| m.camera == CameraId::Fused));
    assert_eq!(out[1].status, Status::Ok);
    assert_eq!(out[2].status, Status::NotFound);
    assert_eq!(out[2].position_mm, 0.0);
}
