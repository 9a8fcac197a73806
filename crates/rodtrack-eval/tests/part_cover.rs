//! A marker partly covered (a hand resting over one side of the rod, or over one end of the
//! marker, drifting slowly over it) is either measured within the accuracy target or says
//! that it is not: the reported case was markers 81-93 % visible reported `ok` with up to
//! 0.022 rad error.
//!
//! What "says so" means is the temporal filter's own rule: a row's claimed std is the
//! camera's noise at quality 1 over its quality, and the filter gates a measurement at
//! `gate_sigma` of those. An `ok` row off by more than the target must be off by no more
//! than that gate at its claimed std, or it would be taken as a confident measurement and
//! pull the track.
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_core::filter::FilterConfig;
use rodtrack_eval::quality::{calibrate_table, run_scene, Scene};

/// The angle's accuracy target, rad.
const TARGET_RAD: f64 = 0.01;

#[test]
fn a_partly_covered_marker_is_accurate_or_says_it_is_not() {
    let cfg = FilterConfig::default();
    let mut bad = Vec::new();
    let (mut rows_n, mut covered_n) = (0, 0);
    for seed in [4u64, 5] {
        let cal = calibrate_table(seed).unwrap();
        let rows = run_scene(seed, &cal, Scene::PartCover, 30).unwrap();
        for r in &rows {
            rows_n += 1;
            covered_n += (!r.visible) as usize;
            if !r.ok || r.angle_error_rad <= TARGET_RAD {
                continue;
            }
            let claimed = cfg.angle_noise_rad / r.quality.max(1e-9);
            if r.angle_error_rad > cfg.gate_sigma * claimed {
                bad.push(*r);
            }
        }
    }
    eprintln!("{rows_n} rows, {covered_n} with the marker partly covered or hidden");
    assert!(covered_n > 0, "no marker was covered: the scene is wrong");
    assert!(
        bad.is_empty(),
        "{} rows ok, off by more than {TARGET_RAD} rad and more than {} times the std their \
         quality claims; first {:?}",
        bad.len(),
        cfg.gate_sigma,
        bad.first()
    );
}
