//! What the command-line test suites share: running the binary and a simulated recording with
//! its calibration, made once per suite.
#![allow(dead_code, clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_rodtrack");

/// Runs the binary to completion.
pub fn rodtrack(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().unwrap()
}

/// A simulated recording and the calibration of its camera 0.
pub struct Fixture {
    /// The recording's folder (`cam0/`, `cam0.json`, ...) under `root`.
    pub rec: PathBuf,
    /// The suite's own folder.
    pub dir: PathBuf,
    /// `c.toml` in `dir`: camera 0 calibrated.
    pub calib: PathBuf,
}

/// Simulates `frames` frames of `scenario` into `<tmp>/<name>/<sub>` (`sub` empty: the suite's
/// folder itself) and calibrates camera 0 into `<tmp>/<name>/c.toml`.
pub fn recording(name: &str, sub: &str, scenario: &str, frames: u64) -> Fixture {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    let rec = if sub.is_empty() {
        dir.clone()
    } else {
        dir.join(sub)
    };
    let o = rodtrack(&[
        "simulate",
        "--scenario",
        scenario,
        "--out",
        rec.to_str().unwrap(),
        "--frames",
        &frames.to_string(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let calib = dir.join("c.toml");
    let o = rodtrack(&[
        "calibrate",
        "--inputs",
        rec.join("cam0.json").to_str().unwrap(),
        "--out",
        calib.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    Fixture { rec, dir, calib }
}

/// A simulated recording of two cameras (`<tmp>/<name>/rec`, scenario `exp3`) and their
/// calibration (`<tmp>/<name>/c.toml`); returns the folder and the calibration.
pub fn two_cameras(name: &str, frames: u64) -> (PathBuf, PathBuf) {
    two_cameras_of(name, "exp3", frames)
}

/// [`two_cameras`] of the simulator's `scenario`.
pub fn two_cameras_of(name: &str, scenario: &str, frames: u64) -> (PathBuf, PathBuf) {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    let rec = dir.join("rec");
    let ok = |args: &[&str]| {
        let o = rodtrack(args);
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    let r = rec.display().to_string();
    ok(&[
        "simulate",
        "--scenario",
        scenario,
        "--frames",
        &frames.to_string(),
        "--out",
        &r,
    ]);
    let calib = dir.join("c.toml");
    ok(&[
        "calibrate",
        "--inputs",
        &format!("{r}/cam0.json"),
        "--inputs",
        &format!("{r}/cam1.json"),
        "--out",
        calib.to_str().unwrap(),
    ]);
    (dir, calib)
}

/// `track` of a [`two_cameras`] folder's recording (`dir/rec/cam0`, `dir/rec/cam1`) with
/// `calib` and the options `extra`.
pub fn track_two_cameras(dir: &Path, calib: &Path, extra: &[&str]) -> Output {
    let rec = dir.join("rec");
    let (cam0, cam1) = (rec.join("cam0"), rec.join("cam1"));
    let mut args = vec![
        "track",
        "--calib",
        calib.to_str().unwrap(),
        "--input",
        cam0.to_str().unwrap(),
        "--input",
        cam1.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    rodtrack(&args)
}
