//! The core on synthetic frames drawn by a small orthographic renderer (independent of the
//! simulator): calibration from a reference frame, then tracking against ground truth.
#![allow(clippy::unwrap_used, missing_docs)]

use rodtrack_core::angle::wrap_pi_fold;
use rodtrack_core::calib::{calibrate_rod, ReferencePose, RodInputs};
use rodtrack_core::{FrameView, Marker, MarkerSpec, Mode, PixelFormat, RodTracker, Status};
use std::f64::consts::TAU;

const W: usize = 240;
const H: usize = 1080;
const PX_PER_MM: f64 = 1.4;
const AXIS_X: f64 = 120.3;
const START_Y: f64 = 420.0; // marker start at position 0, px

struct Setup {
    /// +1: marker u along image +y.
    dir: f64,
    /// +1: print angle grows along image +x.
    sigma: f64,
    psi0: f64,
}

fn render(s: &Setup, position_mm: f64, angle_rad: f64, noise: f64, seed: u64) -> Vec<u8> {
    let m = Marker::v1();
    let r = m.radius_mm();
    let mut out = vec![0u8; W * H];
    let mut state = seed.wrapping_mul(0x9E3779B97F4A7C15) | 1;
    let ss = 4;
    for py in 0..H {
        for px in 0..W {
            let mut acc = 0.0;
            for sy in 0..ss {
                for sx in 0..ss {
                    let x = px as f64 + (sx as f64 + 0.5) / ss as f64 - 0.5;
                    let y = py as f64 + (sy as f64 + 0.5) / ss as f64 - 0.5;
                    let ox = (x - AXIS_X) / PX_PER_MM;
                    acc += if ox.abs() >= r {
                        60.0
                    } else {
                        let d = (ox / r).asin();
                        let u = s.dir * (y - START_Y) / PX_PER_MM - position_mm;
                        let shade = 0.75 + 0.25 * d.cos();
                        if !(0.0..m.length_mm()).contains(&u) {
                            110.0 * shade
                        } else {
                            let psi = angle_rad + s.psi0 + s.sigma * d;
                            (if m.is_black(u, psi) { 20.0 } else { 220.0 }) * shade
                        }
                    };
                }
            }
            let mut v = acc / (ss * ss) as f64;
            if noise > 0.0 {
                // Sum of uniforms: roughly Gaussian.
                let mut n = 0.0;
                for _ in 0..4 {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    n += (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                }
                v += noise * n * 1.732;
            }
            out[py * W + px] = v.round().clamp(0.0, 255.0) as u8;
        }
    }
    out
}

fn inputs() -> RodInputs {
    RodInputs {
        rod: 3,
        path_points_px: vec![
            [AXIS_X + 0.4, 80.0],
            [AXIS_X - 0.3, 500.0],
            [AXIS_X + 0.2, 1000.0],
        ],
        travel_mm: [-100.0, 100.0],
        reference: ReferencePose {
            frame: 0,
            position_mm: 0.0,
            angle_rad: 0.0,
        },
        known_poses: Vec::new(),
        travel_frames: None,
        marker: MarkerSpec::default(),
    }
}

fn ang_err(a: f64, b: f64) -> f64 {
    wrap_pi_fold(a - b).abs()
}

fn run(setup: &Setup, mode: Mode, noise: f64) -> (f64, f64, f64, f64, usize) {
    let ref_frame = render(setup, 0.0, 0.0, noise, 1);
    let view = FrameView::packed(&ref_frame, W, H, PixelFormat::Mono8).unwrap();
    let cal = calibrate_rod(&inputs(), &view, None).unwrap();
    let mut tr = RodTracker::new(&cal, W, H, mode).unwrap();
    let (mut pe, mut ae, mut pmax, mut amax, mut bad) = (0.0, 0.0, 0.0f64, 0.0f64, 0);
    let n = 40;
    for i in 0..n {
        let pos = -95.0 + 190.0 * (i as f64 * 0.618).fract();
        let ang = TAU * (i as f64 * 0.377).fract();
        let f = render(setup, pos, ang, noise, 100 + i as u64);
        let v = FrameView::packed(&f, W, H, PixelFormat::Mono8).unwrap();
        let r = tr.process(&v).unwrap();
        if r.status != Status::Ok {
            bad += 1;
            continue;
        }
        let e_p = r.position_mm - pos;
        let e_a = ang_err(r.angle_rad, ang);
        pe += e_p * e_p;
        ae += e_a * e_a;
        pmax = pmax.max(e_p.abs());
        amax = amax.max(e_a);
    }
    let k = (n - bad).max(1) as f64;
    ((pe / k).sqrt(), (ae / k).sqrt(), pmax, amax, bad)
}

#[test]
fn enhanced_on_synthetic_frames_all_orientations() {
    for (dir, sigma) in [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
        let s = Setup {
            dir,
            sigma,
            psi0: 1.234,
        };
        let (p_rms, a_rms, p_max, a_max, bad) = run(&s, Mode::Enhanced, 2.0);
        eprintln!(
            "enhanced dir {dir} sigma {sigma}: pos rms {p_rms:.3} max {p_max:.3} mm, angle rms {a_rms:.4} max {a_max:.4} rad, not ok {bad}"
        );
        assert_eq!(bad, 0);
        assert!(
            p_rms < 0.1 && p_max < 0.5,
            "position rms {p_rms} max {p_max}"
        );
        assert!(
            a_rms < 0.01 && a_max < 0.03,
            "angle rms {a_rms} max {a_max}"
        );
    }
}

#[test]
fn paper_on_synthetic_frames() {
    let s = Setup {
        dir: 1.0,
        sigma: -1.0,
        psi0: 0.3,
    };
    let (p_rms, a_rms, p_max, a_max, bad) = run(&s, Mode::Paper, 2.0);
    eprintln!(
        "paper: pos rms {p_rms:.3} max {p_max:.3} mm, angle rms {a_rms:.4} max {a_max:.4} rad, not ok {bad}"
    );
    assert_eq!(bad, 0);
    // The paper's resolution: about one pixel (0.7 mm here), angle of the order of 0.01-0.05.
    assert!(p_max < 2.0, "position max {p_max}");
    assert!(a_rms < 0.1, "angle rms {a_rms}");
}
