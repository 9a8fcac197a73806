//! The angle's error over the angle itself, on the first frame at each pose: random tables as
//! built (`asbuilt:SEED`), camera 0 calibrated from its clicks and the camera model, every rod
//! still at 48 angles over two of the stripes' periods and at places within 20 mm of the
//! reference (where calibration placed the centre line, so what is left is the phase's own
//! error), each state measured by a tracker fresh from calibration.
//!
//! Before the phase read the print through the lens' radius and the rod's own perspective,
//! weighed its samples by the print's contrast, and the rods' lines ran through their common
//! vanishing point, this test failed: angle std 2.49 / 2.96 / 2.31 mrad on tables 31 / 32 / 33
//! (max 10.7 mrad on table 32), 1.40-1.46 mrad over the angles alone (an error at twice the
//! stripes' frequency on every rod, from the silhouettes' radius and a radius correction chosen
//! by the stripes' energy, not by its bias). Now 1.21 / 1.98 / 1.17 mrad (max 7.5), 0.75-1.01
//! over the angles alone.
#![allow(clippy::unwrap_used, missing_docs)]

use rodtrack_core::angle::wrap_pi;
use rodtrack_core::{CameraPipeline, FrameView, Mode, Status, Timestamp};
use rodtrack_sim::{build_simulation, calibrate_sim_camera, RodPose, WorldState};
use std::f64::consts::TAU;

const ANGLES: usize = 48;
const PLACES_MM: [f64; 3] = [-20.0, 0.0, 20.0];
/// The phase's own error over the angles (std, rad).
const PHASE_STD_MAX: f64 = 0.0012;
/// The same with 3 x 3 point rays per pixel (std, rad): bit space 0's stripes alone gave 0.91
/// and 3.19 mrad on tables 31 and 32 (max 11.6 mrad), every bit space's edges 0.60 and 2.42
/// (max 8.4).
const POINT_RAYS_PHASE_STD_MAX: f64 = 0.0025;

/// (angle errors of the ok rows on visible markers as `(rod, place, error)`, visible rows, ok
/// rows).
fn table(seed: u64, point_rays: Option<usize>) -> (Vec<(usize, usize, f64)>, usize, usize) {
    let setup = format!("asbuilt:{seed}");
    let mut sim = build_simulation("static", Some(1), seed, false, &setup).unwrap();
    if let Some(n) = point_rays {
        sim = sim.with_point_rays(n);
    }
    let cal = calibrate_sim_camera(&mut sim, 0, seed).unwrap().calibration;
    assert!(
        cal.rods
            .iter()
            .all(|r| r.enhanced.lens_perspective.is_some()),
        "table {seed}: the camera model's calibration must give the rods' perspective"
    );
    let fresh = CameraPipeline::new(&cal, Mode::Enhanced).unwrap();
    let n_rods = sim.scene().rods.len();
    let mut buf = vec![0u8; sim.frame_bytes(0).unwrap()];
    let (mut errs, mut visible, mut ok) = (Vec::new(), 0, 0);
    let mut frame_id = 0u64;
    for (ip, &place) in PLACES_MM.iter().enumerate() {
        for k in 0..ANGLES {
            frame_id += 1;
            // Two stripe periods (8 per turn), each rod offset so they do not share an angle.
            let state = WorldState {
                rods: (0..n_rods)
                    .map(|i| RodPose {
                        position_mm: place,
                        angle_rad: (k as f64 / ANGLES as f64 * 2.0 + 0.37 * i as f64) * TAU / 8.0,
                        velocity_mm_s: 0.0,
                        angular_velocity_rad_s: 0.0,
                    })
                    .collect(),
                hands: vec![],
                ball: None,
            };
            let meta = sim.render_state(0, &state, frame_id, &mut buf).unwrap();
            let view =
                FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
            let mut pipe = fresh.clone();
            let mut rows = Vec::new();
            pipe.process(&view, frame_id, Timestamp::from_nanos(0), &mut rows)
                .unwrap();
            for row in rows {
                let i = row.rod as usize;
                if sim.marker_status(0, i, &state).unwrap() != Status::Ok {
                    continue;
                }
                visible += 1;
                if row.status == Status::Ok {
                    ok += 1;
                    errs.push((i, ip, wrap_pi(row.angle_rad - state.rods[i].angle_rad)));
                }
            }
        }
    }
    (errs, visible, ok)
}

/// The errors over the angles alone: each rod's mean error at each place removed (what the
/// centre line's place and direction add there), the phase's own error is left.
fn over_angles(errs: &[(usize, usize, f64)]) -> Vec<f64> {
    let mut out = Vec::new();
    for rod in 0..16 {
        for ip in 0..PLACES_MM.len() {
            let g: Vec<f64> = errs
                .iter()
                .filter(|e| e.0 == rod && e.1 == ip)
                .map(|e| e.2)
                .collect();
            if !g.is_empty() {
                let m = g.iter().sum::<f64>() / g.len() as f64;
                out.extend(g.iter().map(|e| e - m));
            }
        }
    }
    out
}

/// Standard deviation and largest absolute value of `v`.
fn std_max(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let std = (v.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
    (std, v.iter().fold(0.0f64, |m, e| m.max(e.abs())))
}

#[test]
fn the_first_frame_reads_every_angle_without_the_phase_bias() {
    for seed in [31, 32, 33] {
        let (errs, visible, ok) = table(seed, None);
        assert!(visible > 500, "table {seed}: only {visible} visible rows");
        let all: Vec<f64> = errs.iter().map(|e| e.2).collect();
        let (std, max) = std_max(&all);
        let (phase_std, phase_max) = std_max(&over_angles(&errs));
        eprintln!(
            "table asbuilt:{seed}: {ok} of {visible} visible rows ok; angle error std {:.2} \
             mrad, max {:.2} mrad; over the angles alone std {:.2} mrad, max {:.2} mrad",
            std * 1e3,
            max * 1e3,
            phase_std * 1e3,
            phase_max * 1e3
        );
        assert_eq!(ok, visible, "table {seed}: a visible rod not ok");
        // The accuracy issue's targets, 2 mrad std and 10 mrad max, on the first frame.
        assert!(std <= 0.002, "table {seed}: angle std {std}");
        assert!(max <= 0.01, "table {seed}: angle max {max}");
        assert!(
            phase_std <= PHASE_STD_MAX,
            "table {seed}: phase std {phase_std}"
        );
    }
}

/// The same with the markers rendered by 3 x 3 point rays per pixel (as the independent
/// validation table's renderer does, and as a sensor with a small fill factor samples): each
/// print edge's image position then aliases with the pixel grid, an error of its own at every
/// pose. Over the angles alone, before the Gray code's other bit spaces refined the angle
/// (bit space 0's stripes alone), this test failed on table 32: std 3.19 mrad, max 11.6 mrad
/// (see `POINT_RAYS_PHASE_STD_MAX`).
#[test]
fn an_aliasing_sensor_is_averaged_over_every_bit_space() {
    for seed in [31, 32] {
        let (errs, visible, ok) = table(seed, Some(3));
        assert!(visible > 500, "table {seed}: only {visible} visible rows");
        let all: Vec<f64> = errs.iter().map(|e| e.2).collect();
        let (std, max) = std_max(&all);
        let (phase_std, phase_max) = std_max(&over_angles(&errs));
        eprintln!(
            "table asbuilt:{seed}, 3 x 3 point rays: {ok} of {visible} visible rows ok; angle \
             error std {:.2} mrad, max {:.2} mrad; over the angles alone std {:.2} mrad, max \
             {:.2} mrad",
            std * 1e3,
            max * 1e3,
            phase_std * 1e3,
            phase_max * 1e3
        );
        assert_eq!(ok, visible, "table {seed}: a visible rod not ok");
        assert!(
            phase_std <= POINT_RAYS_PHASE_STD_MAX,
            "table {seed}: phase std {phase_std}"
        );
        // The 10 mrad, over the angles alone.
        assert!(phase_max <= 0.01, "table {seed}: phase max {phase_max}");
    }
}
