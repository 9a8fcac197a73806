//! Calibrate and track a recording with the SDK: `cargo run --release -p rodtrack-sdk
//! --example calibrate_and_track -- REC` where REC is a folder made by
//! `rodtrack simulate --scenario exp3 --frames 50 --out REC` (or by cameras, with a
//! calibration-inputs file `camN.json` and the frames `camN/` per camera).
use rodtrack_core::CameraId;
use rodtrack_io::VecSink;
use rodtrack_sdk::{calibrate_files, print_warning, Session, SessionOptions};
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let rec = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "rec".into()));
    let cams: Vec<String> = (0..)
        .map(|i| format!("cam{i}"))
        .take_while(|c| rec.join(c).is_dir())
        .collect();
    let inputs: Vec<PathBuf> = cams.iter().map(|c| rec.join(format!("{c}.json"))).collect();
    let paths: Vec<&std::path::Path> = inputs.iter().map(|p| p.as_path()).collect();
    let cal = calibrate_files(&paths, &mut print_warning)?;
    let frames: Vec<String> = cams
        .iter()
        .map(|c| rec.join(c).display().to_string())
        .collect();
    let session = Session::open(&cal, &frames, SessionOptions::default())?;
    let (report, sink) = session.run(VecSink::default())?;
    let want = if cams.len() > 1 {
        CameraId::Fused
    } else {
        CameraId::Camera(0)
    };
    for m in sink
        .rows
        .iter()
        .filter(|m| m.camera == want)
        .rev()
        .take(cal.cameras[0].rods.len())
    {
        println!(
            "frame {} rod {}: {:8.3} mm {:7.4} rad {}",
            m.frame, m.rod, m.position_mm, m.angle_rad, m.status
        );
    }
    println!("{}", report.summary());
    Ok(())
}
