//! What the camera network's tests share: the binary, a scratch folder, a simulated two-camera
//! calibration, free ports and the system clock.
#![allow(dead_code, clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

pub const BIN: &str = env!("CARGO_BIN_EXE_rodtrack");

pub fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

pub fn run_ok(args: &[&str]) {
    let out = Command::new(BIN).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "rodtrack {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A simulated table (exp3) and its two-camera calibration.
pub fn calibration(t: &Path) -> PathBuf {
    let rec = t.join("rec").display().to_string();
    run_ok(&[
        "simulate",
        "--scenario",
        "exp3",
        "--frames",
        "20",
        "--out",
        &rec,
    ]);
    let calib = t.join("c.toml");
    run_ok(&[
        "calibrate",
        "--inputs",
        &format!("{rec}/cam0.json"),
        "--inputs",
        &format!("{rec}/cam1.json"),
        "--out",
        &calib.display().to_string(),
    ]);
    calib
}

pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

pub fn unix_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as u64
}
