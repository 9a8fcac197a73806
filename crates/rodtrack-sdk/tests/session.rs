//! A recording of the simulator calibrated and tracked through the SDK, as the example does,
//! against the ground truth; and the session's errors.

#![allow(clippy::unwrap_used)]

use rodtrack_core::{CameraId, Status};
use rodtrack_io::VecSink;
use rodtrack_sdk::{calibrate_files, Hooks, Progress, SdkError, Session, SessionOptions};
use rodtrack_sim::{build_simulation, write_recording, RecordOptions};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

fn recording(name: &str, frames: usize) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rodtrack-sdk-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut sim = build_simulation("exp3", Some(frames), 3, false, "default").unwrap();
    write_recording(&mut sim, &dir, &RecordOptions::default(), &mut |_, _| {}).unwrap();
    dir
}

#[derive(Default)]
struct Counting {
    measured: AtomicU64,
    progress: AtomicU64,
}

impl Hooks for Counting {
    fn measured(
        &self,
        _camera: u32,
        _meta: &rodtrack_io::FrameMeta,
        rows: &[rodtrack_core::Measurement],
        _pipe: &rodtrack_core::CameraPipeline,
    ) {
        assert!(!rows.is_empty());
        self.measured.fetch_add(1, Ordering::Relaxed);
    }
    fn progress(&self, _p: &Progress) {
        self.progress.fetch_add(1, Ordering::Relaxed);
    }
}

#[test]
fn calibrate_and_track_a_recording_against_the_truth() {
    let rec = recording("track", 30);
    let inputs = [rec.join("cam0.json"), rec.join("cam1.json")];
    let paths: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
    let mut warnings = Vec::new();
    let cal = calibrate_files(&paths, &mut |w| warnings.push(w)).unwrap();
    assert_eq!(cal.cameras.len(), 2);
    assert!(warnings.is_empty(), "{warnings:?}");
    let frames = [rec.join("cam0"), rec.join("cam1")].map(|p| p.display().to_string());
    let hooks = Arc::new(Counting::default());
    let options = SessionOptions {
        progress_period: Some(std::time::Duration::from_millis(1)),
        ..SessionOptions::default()
    };
    let session = Session::open(&cal, &frames, options)
        .unwrap()
        .with_hooks(hooks.clone());
    let (report, sink) = session.run(VecSink::default()).unwrap();
    assert_eq!(hooks.measured.load(Ordering::Relaxed), 60);
    assert_eq!(report.pipeline.sets_complete, 30);
    assert!(!report.all_bad());
    let truth = rodtrack_io::read_measurements_csv(&rec.join("truth.csv")).unwrap();
    let mut checked = 0;
    for m in sink
        .rows
        .iter()
        .filter(|m| m.camera == CameraId::Fused && m.status == Status::Ok)
    {
        let t = truth
            .iter()
            .find(|(t, _)| t.frame == m.frame && t.rod == m.rod)
            .map(|(t, _)| t)
            .unwrap();
        assert!(
            (m.position_mm - t.position_mm).abs() < 0.5,
            "{m:?} vs {t:?}"
        );
        checked += 1;
    }
    assert!(checked >= 30 * 6, "{checked} fused ok rows");
    let _ = std::fs::remove_dir_all(&rec);
}

#[test]
fn a_missing_input_names_the_camera_and_the_input() {
    let rec = recording("missing", 2);
    let inputs = [rec.join("cam0.json"), rec.join("cam1.json")];
    let paths: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
    let cal = calibrate_files(&paths, &mut |_| {}).unwrap();
    let frames = [
        rec.join("cam0").display().to_string(),
        "/nonexistent/folder".to_string(),
    ];
    let Err(e) = Session::open(&cal, &frames, SessionOptions::default()) else {
        panic!("a missing folder opened");
    };
    let msg = e.to_string();
    assert!(matches!(e, SdkError::Source { .. }), "{msg}");
    assert!(
        msg.contains("camera 1") && msg.contains("/nonexistent/folder"),
        "{msg}"
    );
    let Err(e) = Session::open(&cal, &frames[..1], SessionOptions::default()) else {
        panic!("one input for two cameras accepted");
    };
    assert!(e.to_string().contains("2 camera(s) but 1 input"), "{e}");
    let _ = std::fs::remove_dir_all(&rec);
}

#[test]
fn a_malformed_calibration_file_names_the_file() {
    let dir = std::env::temp_dir().join(format!("rodtrack-sdk-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("calib.toml");
    std::fs::write(&p, "version = 1\n[[cameras]]\nname = 3\n").unwrap();
    let e = rodtrack_sdk::read_calibration(&p).unwrap_err();
    assert!(e.to_string().contains("calib.toml"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
