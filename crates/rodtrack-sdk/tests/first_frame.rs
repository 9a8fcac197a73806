//! A lone camera's first frame: every rod it measures well is `ok` on the run's first frame
//! (no other camera can corroborate it, so its quality confirms it; see
//! `rodtrack_core::pipeline::filter_config_alone`), and no `ok` row of the run is wrong.
//! Over seeded as-built tables of the simulator, camera 0 alone, a still scene.
#![allow(clippy::unwrap_used, missing_docs)]

use rodtrack_core::angle::wrap_pi;
use rodtrack_core::{CameraPipeline, Measurement, Mode, Status};
use rodtrack_io::{FrameMeta, VecSink};
use rodtrack_sdk::{Hooks, Session, SessionCamera, SessionOptions};
use rodtrack_sim::{build_simulation, calibrate_sim_camera, SimSource};
use std::sync::{Arc, Mutex};

const FRAMES: usize = 6;
const TABLES: std::ops::RangeInclusive<u64> = 1..=4;

/// The tracker's raw rows of frame 0 (before the filter).
#[derive(Default)]
struct FirstRaw(Mutex<Vec<Measurement>>);

impl Hooks for FirstRaw {
    fn measured(&self, _camera: u32, meta: &FrameMeta, rows: &[Measurement], _p: &CameraPipeline) {
        if meta.frame_id == 0 {
            self.0.lock().unwrap().extend_from_slice(rows);
        }
    }
}

/// (rods measured well on frame 0, rods ok on frame 0, ok rows of the run, wrong ok rows).
fn table(seed: u64) -> (usize, usize, usize, Vec<String>) {
    let setup = format!("asbuilt:{seed}");
    let mut sim = build_simulation("static", Some(FRAMES), seed, false, &setup).unwrap();
    let cal = calibrate_sim_camera(&mut sim, 0, seed).unwrap().calibration;
    let source = SimSource::for_simulation(&sim, Default::default())
        .unwrap()
        .into_iter()
        .next()
        .unwrap();
    let camera = SessionCamera {
        label: "camera 0".into(),
        source: Box::new(source),
        pipe: CameraPipeline::new(&cal, Mode::Enhanced).unwrap(),
    };
    let first = Arc::new(FirstRaw::default());
    let (_, sink) = Session::from_cameras(vec![camera], SessionOptions::default())
        .with_hooks(first.clone())
        .run(VecSink::default())
        .unwrap();
    let mut raw_good = 0;
    let mut first_ok = 0;
    let mut ok = 0;
    let mut wrong = Vec::new();
    let frame0 = first.0.lock().unwrap().clone();
    let truth0 = sim.truth(0, 0).unwrap();
    for raw in &frame0 {
        let t = &truth0[raw.rod as usize];
        if t.visible && raw.status == Status::Ok && raw.quality >= 0.9 {
            raw_good += 1;
            let out = sink
                .rows
                .iter()
                .find(|m| m.frame == 0 && m.rod == raw.rod)
                .unwrap();
            first_ok += (out.status == Status::Ok) as usize;
        }
    }
    for m in &sink.rows {
        if m.status != Status::Ok {
            continue;
        }
        ok += 1;
        let t = &sim.truth(m.frame as usize, 0).unwrap()[m.rod as usize].m;
        let da = wrap_pi(m.angle_rad - t.angle_rad).abs();
        let dp = (m.position_mm - t.position_mm).abs();
        if da > 0.05 || dp > 0.5 {
            wrong.push(format!(
                "{setup} frame {} rod {}: {da:.3} rad, {dp:.3} mm",
                m.frame, m.rod
            ));
        }
    }
    (raw_good, first_ok, ok, wrong)
}

#[test]
fn a_lone_cameras_first_frame_is_ok_when_its_measurement_is_good() {
    let results: Vec<_> = std::thread::scope(|s| {
        let handles: Vec<_> = TABLES.map(|seed| s.spawn(move || table(seed))).collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let good: usize = results.iter().map(|r| r.0).sum();
    let first_ok: usize = results.iter().map(|r| r.1).sum();
    let ok: usize = results.iter().map(|r| r.2).sum();
    let wrong: Vec<&String> = results.iter().flat_map(|r| &r.3).collect();
    eprintln!("first frame: {first_ok} of {good} rods measured well are ok; {ok} ok rows");
    assert!(
        good >= 6 * TABLES.count(),
        "only {good} rods measured well on frame 0"
    );
    assert_eq!(
        first_ok, good,
        "rods measured well but not ok on the first frame"
    );
    assert!(wrong.is_empty(), "ok rows off the truth: {wrong:?}");
}
