//! A live run with two cameras flags the camera rows the fusion overruled, as a recording
//! does (issue #18): the simulator in real time (`live` sources, the session's default
//! pipeline settings), camera 1's image frozen for a while as a stuck camera would deliver it
//! while the rods move, so that its rows disagree with camera 0 and the track.
#![allow(clippy::unwrap_used, missing_docs)]

use rodtrack_core::{CameraId, CameraPipeline, Measurement, Mode, Status};
use rodtrack_io::runtime::RunMode;
use rodtrack_io::source::SourceInfo;
use rodtrack_io::{FrameBuffer, FrameSource, SourceError, VecSink};
use rodtrack_sdk::{Session, SessionCamera, SessionOptions};
use rodtrack_sim::{build_simulation, calibrate_sim_camera, Playback, SimSource};

/// Frames of the run (0.7 s at 200 fps); exp3's rods hold still for 0.3 s, then slide at up
/// to 400 mm/s (2 mm per frame).
const FRAMES: usize = 140;
/// Camera 1 shows frame `FROZEN.start - 1`'s pixels through these frames (ids and timestamps
/// its own).
const FROZEN: std::ops::Range<u64> = 80..110;

/// A source whose frames in [`FROZEN`] carry the pixels of the frame before.
struct Frozen {
    inner: SimSource,
    held: Vec<u8>,
}

impl FrameSource for Frozen {
    fn info(&self) -> SourceInfo {
        self.inner.info()
    }
    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        let got = self.inner.next_frame(buf)?;
        if got.is_some() {
            let id = buf.meta.frame_id;
            if id + 1 == FROZEN.start {
                self.held.clone_from(&buf.data);
            } else if FROZEN.contains(&id) && self.held.len() == buf.data.len() {
                buf.data.copy_from_slice(&self.held);
            }
        }
        Ok(got)
    }
}

fn rows_of(rows: &[Measurement], camera: CameraId) -> Vec<&Measurement> {
    rows.iter().filter(|m| m.camera == camera).collect()
}

#[test]
fn a_live_run_flags_the_camera_rows_the_fusion_overruled() {
    let seed = 1;
    let mut sim = build_simulation("exp3", Some(FRAMES), seed, false, "default").unwrap();
    let cals: Vec<_> = (0..2)
        .map(|c| calibrate_sim_camera(&mut sim, c, seed).unwrap().calibration)
        .collect();
    let playback = Playback {
        realtime: true,
        ..Playback::default()
    };
    let mut sources = SimSource::for_simulation(&sim, playback).unwrap();
    assert!(sources.iter().all(|s| s.info().live));
    let second = sources.pop().unwrap();
    let first = sources.pop().unwrap();
    let inputs: Vec<Box<dyn FrameSource>> = vec![
        Box::new(first),
        Box::new(Frozen {
            inner: second,
            held: Vec::new(),
        }),
    ];
    let cameras = inputs
        .into_iter()
        .zip(&cals)
        .map(|(source, cal)| SessionCamera {
            label: format!("camera {}", cal.index),
            source,
            pipe: CameraPipeline::new(cal, Mode::Enhanced).unwrap(),
        })
        .collect();
    let session = Session::from_cameras(cameras, SessionOptions::default());
    assert!(session.is_live());
    let (report, sink) = session.run(VecSink::default()).unwrap();
    // The defaults for live sources: really a live run, every frame set complete.
    assert_eq!(report.config.mode, RunMode::Live);
    assert_eq!(report.pipeline.sets_complete, FRAMES as u64, "{report:?}");

    let cam0 = rows_of(&sink.rows, CameraId::Camera(0));
    let cam1 = rows_of(&sink.rows, CameraId::Camera(1));
    let fused = rows_of(&sink.rows, CameraId::Fused);
    assert!(!fused.is_empty());
    // The rods both cameras see, and the fused rows of the frozen frames that took camera 0.
    let both: Vec<u32> = cals[0]
        .rods
        .iter()
        .map(|r| r.rod)
        .filter(|r| cals[1].rods.iter().any(|o| o.rod == *r))
        .collect();
    assert!(!both.is_empty());
    let conflicts1: Vec<&&Measurement> = cam1
        .iter()
        .filter(|m| m.status == Status::Conflict)
        .collect();
    let in_window = |m: &Measurement| (FROZEN.start..FROZEN.end + 10).contains(&m.frame);
    eprintln!(
        "camera 1: {} conflict rows of {} ({} rods seen by both cameras, {} frozen frames)",
        conflicts1.len(),
        cam1.len(),
        both.len(),
        FROZEN.end - FROZEN.start
    );
    // Camera 0 is never overruled, camera 1 only while (and just after) its image is stuck.
    assert!(cam0.iter().all(|m| m.status != Status::Conflict));
    for m in &conflicts1 {
        assert!(
            in_window(m),
            "camera 1 conflict outside the frozen frames: {m:?}"
        );
        assert_eq!(m.quality, 0.0, "{m:?}");
    }
    // The fusion overruled camera 1 on the frozen frames of a moving rod: its rows say so.
    let frozen_frames = (FROZEN.end - FROZEN.start) as usize;
    assert!(
        conflicts1.len() >= both.len() * frozen_frames / 2,
        "{} camera 1 conflict rows, expected at least half of {} rods x {frozen_frames} frozen frames",
        conflicts1.len(),
        both.len()
    );
}
