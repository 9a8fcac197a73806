//! Writes a recording: `cargo run --release -p rodtrack-sim --example record -- SCENARIO OUT_DIR [FRAMES] [quality]`.

use rodtrack_sim::{
    default_cameras, write_recording, RecordOptions, RenderMode, Scenario, SceneConfig, Simulation,
};
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map(String::as_str).unwrap_or("exp1");
    let out = args.get(2).map(String::as_str).unwrap_or("/tmp/sim_rec");
    let frames: Option<usize> = args.get(3).and_then(|s| s.parse().ok());
    let mode = if args.get(4).map(String::as_str) == Some("quality") {
        RenderMode::Quality
    } else {
        RenderMode::Fast
    };
    let scene = SceneConfig::default();
    let scenario = Scenario::by_name(name, &scene, 1)?;
    let mut sim = Simulation::new(scene, default_cameras(), scenario, mode)?;
    let opts = RecordOptions {
        frames: frames.map(|n| 0..n),
        ..RecordOptions::default()
    };
    let t = Instant::now();
    let s = write_recording(&mut sim, Path::new(out), &opts, &mut |d, n| {
        if d % 100 == 0 || d == n {
            eprintln!("{d}/{n} frames, {:.1} s", t.elapsed().as_secs_f64());
        }
    })?;
    eprintln!("{s:?} in {:.1} s", t.elapsed().as_secs_f64());
    Ok(())
}
