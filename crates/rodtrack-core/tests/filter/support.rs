//! Synthetic measurement sequences for the filter and fusion tests: the truth of a trajectory,
//! noisy rows of it, a filter run over it and the checks of its output.

use rodtrack_core::angle::wrap_2pi;
use rodtrack_core::filter::{FilterConfig, Rejection, RodFilter};
use rodtrack_core::Timestamp;
use rodtrack_core::{CameraId, Measurement, Status};
use std::f64::consts::PI;

pub use crate::common::Rng;

pub const FPS: f64 = 200.0;
pub const SIGMA_POS: f64 = 0.1;
pub const SIGMA_ANG: f64 = 0.004;

/// The true state at one frame.
#[derive(Clone, Copy, Debug)]
pub struct Truth {
    pub t: f64,
    pub position_mm: f64,
    pub angle_rad: f64,
}

pub fn truth(n: usize, f: impl Fn(f64) -> (f64, f64)) -> Vec<Truth> {
    (0..n)
        .map(|i| {
            let t = 1.0 + i as f64 / FPS;
            let (p, a) = f(t - 1.0);
            Truth {
                t,
                position_mm: p,
                angle_rad: a,
            }
        })
        .collect()
}

pub fn row(cam: u32, i: usize, tr: &Truth, rng: &mut Rng) -> Measurement {
    Measurement {
        frame: i as u64,
        timestamp_ns: Timestamp::from_secs_f64(tr.t),
        camera: CameraId::Camera(cam),
        rod: 3,
        position_mm: tr.position_mm + SIGMA_POS * rng.gauss(),
        angle_rad: wrap_2pi(tr.angle_rad + SIGMA_ANG * rng.gauss()),
        angle_unwrapped_rad: 0.0,
        velocity_mm_s: 0.0,
        angular_velocity_rad_s: 0.0,
        quality: 1.0,
        status: Status::Ok,
        turns_known: true,
    }
}

pub fn missing(m: &Measurement, status: Status) -> Measurement {
    Measurement::empty(m.frame, m.timestamp_ns, m.camera, m.rod, status)
}

/// Errors of one filtered row against the truth; the angle error uses the unwrapped angle, so
/// a wrong turn count shows as a 2 pi error.
pub fn errors(out: &Measurement, tr: &Truth) -> (f64, f64) {
    (
        out.position_mm - tr.position_mm,
        out.angle_unwrapped_rad - tr.angle_rad,
    )
}

pub fn std(v: &[f64]) -> f64 {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Runs a filter over a trajectory; `edit` may drop or corrupt frame `i`'s row. Returns the
/// filtered rows.
pub fn run(
    cfg: FilterConfig,
    tr: &[Truth],
    seed: u64,
    mut edit: impl FnMut(usize, Measurement) -> Measurement,
) -> (Vec<Measurement>, Vec<Option<Rejection>>) {
    let mut rng = Rng::new(seed);
    let mut f = RodFilter::new(cfg);
    let mut out = Vec::new();
    let mut rej = Vec::new();
    for (i, t) in tr.iter().enumerate() {
        let m = edit(i, row(0, i, t, &mut rng));
        out.push(f.update(&m));
        rej.push(f.last_rejection());
    }
    (out, rej)
}

/// Every `ok` and `predicted` row must count turns exactly and be close; `ok` rows closer.
pub fn assert_tracks(out: &[Measurement], tr: &[Truth], ok_pos: f64, ok_ang: f64, what: &str) {
    for (i, (o, t)) in out.iter().zip(tr).enumerate() {
        let (ep, ea) = errors(o, t);
        match o.status {
            Status::Ok => {
                assert!(
                    ep.abs() < ok_pos && ea.abs() < ok_ang,
                    "{what}: frame {i} ok with error {ep:.3} mm {ea:.4} rad: {o:?} truth {t:?}"
                );
            }
            Status::Predicted => {
                assert!(
                    ea.abs() < PI,
                    "{what}: frame {i} predicted with a wrong turn count ({ea:.3} rad)"
                );
            }
            _ => {}
        }
    }
}
