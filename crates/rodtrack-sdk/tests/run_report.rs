//! The session's report of the rods' health and its control handle, on the simulator: a rod
//! spinning up to 3000 rpm within 40 ms, frames lost for 60 ms (the turn counts of every rod
//! may have slipped there), and a re-anchoring sent to the running session from a hook.
#![allow(clippy::unwrap_used, missing_docs)]

use rodtrack_core::{CameraId, CameraPipeline, Measurement, Mode, Status};
use rodtrack_io::source::SourceInfo;
use rodtrack_io::{FrameBuffer, FrameMeta, FrameSource, SourceError, VecSink};
use rodtrack_sdk::{Hooks, Session, SessionCamera, SessionControl, SessionOptions};
use rodtrack_sim::{
    calibrate_sim_camera, default_cameras, RenderMode, Scenario, SceneConfig, SimSource,
    Simulation, TrackBuilder,
};
use std::f64::consts::TAU;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

const FRAMES: usize = 110;
/// Frames the source loses (read and thrown away): 60 ms at 200 fps.
const GAP: std::ops::Range<u64> = 40..52;
/// The frame at which the hook re-anchors the still rod.
const REANCHOR_AT: u64 = 80;
const REANCHOR_TURNS: i64 = 7;

/// A source that loses the frames of [`GAP`], in step with the other cameras' sources: it
/// hands out a frame only when every other camera has handed out the one [`SKEW_FRAMES`]
/// before it (or ended). Without that, the simulator's sources run as fast as their threads
/// do, and on a loaded machine one camera ran 28 frames ahead of the other: its re-anchoring
/// at frame [`REANCHOR_AT`] then reached the fused filter before the gap's sets were fused,
/// and the fused rows never showed the count unknown.
struct Gap {
    source: Box<dyn FrameSource>,
    camera: usize,
    /// Each camera's last frame handed out (`u64::MAX` once ended).
    handed: Arc<Vec<AtomicU64>>,
}

/// How many frames a camera's source may run ahead of the others'.
const SKEW_FRAMES: u64 = 2;

impl FrameSource for Gap {
    fn info(&self) -> SourceInfo {
        self.source.info()
    }
    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        loop {
            let r = self.source.next_frame(buf)?;
            if r.is_none() {
                self.handed[self.camera].store(u64::MAX, Ordering::SeqCst);
                return Ok(r);
            }
            let f = buf.meta.frame_id;
            while self.handed.iter().enumerate().any(|(c, h)| {
                c != self.camera && h.load(Ordering::SeqCst).saturating_add(SKEW_FRAMES) < f
            }) {
                std::thread::sleep(std::time::Duration::from_micros(100));
            }
            self.handed[self.camera].store(f, Ordering::SeqCst);
            if !GAP.contains(&f) {
                return Ok(r);
            }
        }
    }
}

/// Re-anchors rod `rod` once, when camera 0 measured frame [`REANCHOR_AT`].
struct Reanchor {
    control: SessionControl,
    rod: u32,
    sent: AtomicBool,
}

impl Hooks for Reanchor {
    fn measured(&self, camera: u32, meta: &FrameMeta, _rows: &[Measurement], _p: &CameraPipeline) {
        if camera == 0 && meta.frame_id >= REANCHOR_AT && !self.sent.swap(true, Ordering::SeqCst) {
            self.control
                .reanchor(None, self.rod, REANCHOR_TURNS)
                .unwrap();
        }
    }
}

#[test]
fn the_report_counts_what_the_rows_show_and_a_reanchor_reaches_every_filter() {
    let scene = SceneConfig::default();
    let mut sc = Scenario::by_name("static", &scene, 5)
        .unwrap()
        .with_frames(FRAMES);
    let spin_rod = 3;
    let mut a = TrackBuilder::new(0.0);
    a.hold(0.1).spin(3000.0 / 60.0 * TAU, 0.04);
    sc.rods[spin_rod].angle = a.build();
    let mut sim = Simulation::new(scene, default_cameras(), sc, RenderMode::Fast)
        .unwrap()
        .with_seed(5);
    let ncam = sim.cameras().len();
    let cals: Vec<_> = (0..ncam)
        .map(|c| calibrate_sim_camera(&mut sim, c, 5).unwrap().calibration)
        .collect();
    let sources = SimSource::for_simulation(&sim, Default::default()).unwrap();
    let handed: Arc<Vec<AtomicU64>> = Arc::new((0..ncam).map(|_| AtomicU64::new(0)).collect());
    let cameras: Vec<SessionCamera> = sources
        .into_iter()
        .zip(&cals)
        .enumerate()
        .map(|(camera, (s, cal))| SessionCamera {
            label: format!("camera {}", cal.index),
            source: Box::new(Gap {
                source: Box::new(s),
                camera,
                handed: Arc::clone(&handed),
            }),
            pipe: CameraPipeline::new(cal, Mode::Enhanced).unwrap(),
        })
        .collect();
    let still_rod = cals[0].rods[0].rod;
    let spin_id = cals[0].rods[spin_rod].rod;
    let session = Session::from_cameras(cameras, SessionOptions::default());
    let hooks = std::sync::Arc::new(Reanchor {
        control: session.control(),
        rod: still_rod,
        sent: AtomicBool::new(false),
    });
    let (report, sink) = session.with_hooks(hooks).run(VecSink::default()).unwrap();
    eprintln!("{}", report.summary());
    let rows = &sink.rows;
    assert!(!rows.is_empty());
    // Each camera's rods, and the fused rows' (every rod some camera sees).
    let mut keys: Vec<(CameraId, Vec<u32>)> = cals
        .iter()
        .map(|c| {
            (
                CameraId::Camera(c.index),
                c.rods.iter().map(|r| r.rod).collect(),
            )
        })
        .collect();
    let mut all: Vec<u32> = keys.iter().flat_map(|(_, r)| r.clone()).collect();
    all.sort_unstable();
    all.dedup();
    keys.push((CameraId::Fused, all));
    let mut reanchored = 0;
    for (camera, rods) in keys {
        for rod in rods {
            let h = report
                .rods
                .iter()
                .find(|h| h.camera == camera && h.rod == rod)
                .unwrap_or_else(|| panic!("no report for {camera:?} rod {rod}"));
            let mine: Vec<&Measurement> = rows
                .iter()
                .filter(|m| m.camera == camera && m.rod == rod)
                .collect();
            let unknown = mine
                .iter()
                .filter(|m| matches!(m.status, Status::Ok | Status::Predicted) && !m.turns_known)
                .count() as u64;
            let conflicts = mine.iter().filter(|m| m.status == Status::Conflict).count() as u64;
            assert_eq!(h.rows_turns_unknown, unknown, "{camera:?} rod {rod}: {h:?}");
            assert_eq!(h.conflicts, conflicts, "{camera:?} rod {rod}: {h:?}");
            // The gap is longer than any count survives: every rod's count was lost there, and
            // rows said so until it was re-anchored (by the filter at 200 fps, or the user).
            assert!(h.turns_lost >= 1, "{camera:?} rod {rod}: {h:?}");
            assert!(h.rows_turns_unknown >= 1, "{camera:?} rod {rod}: {h:?}");
            assert!(
                h.turns_reanchored + h.turns_set_by_user >= 1,
                "{camera:?} rod {rod}: {h:?}"
            );
            assert!(h.learnt_resets <= h.fresh_searches, "{h:?}");
            if camera == CameraId::Fused {
                assert_eq!((h.fresh_searches, h.learnt_resets), (0, 0), "{h:?}");
            }
            // The re-anchoring reached this filter: the still rod's last row is at turn 7.
            let last = mine.last().unwrap();
            if rod == still_rod {
                reanchored += 1;
                assert_eq!(h.turns_set_by_user, 1, "{camera:?}: {h:?}");
                let turns = ((last.angle_unwrapped_rad - last.angle_rad) / TAU).round() as i64;
                assert_eq!(turns, REANCHOR_TURNS, "{camera:?}: {last:?}");
                assert!(last.turns_known, "{last:?}");
            } else {
                assert_eq!(h.turns_set_by_user, 0, "{camera:?} rod {rod}: {h:?}");
            }
        }
    }
    assert!(reanchored >= 2, "the still rod in {reanchored} filter(s)");
    // The spinning rod's rows are in the report like the others'; the summary names only rods
    // with non-zero counters.
    assert!(report.rods.iter().any(|h| h.rod == spin_id));
    let summary = report.summary();
    assert!(summary.contains("turn count lost 1x"), "{summary}");
    assert!(summary.contains("set by the user 1x"), "{summary}");
}
