//! The temporal filter run in parts (each camera's filter in its own thread, the fusion
//! apart), as the runtime runs it, gives the rows of [`FrameSetFilter`] over each set.

use rodtrack_core::Timestamp;
use rodtrack_core::{CameraFilter, CameraId, FrameSetFilter, Measurement, Mode, SetFusion, Status};

/// A frame set of `ncam` cameras x 8 rods: motion, noise, an occluded rod, a camera that
/// sometimes disagrees, a row of low quality.
fn frame_set(frame: u64, ncam: u32, noise: &mut u64) -> Vec<Measurement> {
    let mut rnd = || {
        *noise ^= *noise << 13;
        *noise ^= *noise >> 7;
        *noise ^= *noise << 17;
        (*noise >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let t = frame as f64 / 200.0;
    let mut rows = Vec::new();
    for cam in 0..ncam {
        for rod in 0..8u32 {
            let status = if rod == 3 && frame % 37 < 4 {
                Status::Occluded
            } else {
                Status::Ok
            };
            let mut m = Measurement::empty(
                frame,
                Timestamp::from_secs_f64(t),
                CameraId::Camera(cam),
                rod,
                status,
            );
            if status == Status::Ok {
                let phase = f64::from(rod);
                m.position_mm = 40.0 * (6.0 * t + phase).sin() + 0.05 * rnd();
                if cam == 1 && rod == 5 && frame % 50 == 7 {
                    m.position_mm += 5.0;
                }
                let angle = 3.0 * t * (1.0 + phase) + 0.004 * rnd();
                m.angle_unwrapped_rad = angle;
                m.angle_rad = rodtrack_core::angle::wrap_2pi(angle);
                m.quality = if frame % 23 == 0 { 0.1 } else { 0.9 };
            }
            rows.push(m);
        }
    }
    rows
}

#[test]
fn camera_filters_and_set_fusion_give_the_frame_set_filters_rows() {
    for mode in [Mode::Enhanced, Mode::Paper] {
        for ncam in [1u32, 2] {
            let mut reference = FrameSetFilter::new(mode, ncam > 1);
            let mut cameras: Vec<CameraFilter> = (0..ncam)
                .map(|_| {
                    if ncam > 1 {
                        CameraFilter::new(mode)
                    } else {
                        CameraFilter::alone(mode)
                    }
                })
                .collect();
            let mut fusion = SetFusion::new(mode);
            let mut noise = 0x9e37_79b9_7f4a_7c15;
            let (mut want, mut got, mut one) = (Vec::new(), Vec::new(), Vec::new());
            let (mut changed, mut fused) = (0, 0);
            for frame in 0..400 {
                let raw = frame_set(frame, ncam, &mut noise);
                want.clear();
                reference.process(&raw, &mut want);
                got.clear();
                for (c, f) in cameras.iter_mut().enumerate() {
                    one.clear();
                    one.extend(
                        raw.iter()
                            .filter(|m| m.camera == CameraId::Camera(c as u32))
                            .copied(),
                    );
                    f.process(&one, &mut got);
                }
                if ncam > 1 {
                    let cameras_end = got.len();
                    fusion.process(&raw, &mut got);
                    // The camera rows the fusion overruled are flagged, as a runtime that
                    // writes a frame set at once does.
                    fusion.flag_overruled(&mut got[..cameras_end]);
                }
                assert_eq!(got, want, "{mode:?}, {ncam} camera(s), frame {frame}");
                changed += raw
                    .iter()
                    .zip(&want)
                    .filter(|(r, w)| r.position_mm != w.position_mm)
                    .count();
                fused += want
                    .iter()
                    .filter(|m| m.camera == CameraId::Fused && m.status == Status::Ok)
                    .count();
            }
            // Not vacuous: the filters changed the values and, with 2 cameras, fused them.
            assert!(changed > 1000, "{mode:?}: {changed}");
            assert_eq!(fused > 1000, ncam > 1, "{mode:?}: {fused}");
        }
    }
}
