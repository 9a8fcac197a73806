//! Renders one frame of a scenario for every camera and writes PNGs (for looking at).
//!
//! `cargo run --release -p rodtrack-sim --example render_one -- SCENARIO FRAME OUT_DIR [rgb8|mono8|bayer] [quality]`

use rodtrack_core::PixelFormat;
use rodtrack_sim::{
    default_cameras, record::write_png, RenderMode, Scenario, SceneConfig, Simulation,
};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map(String::as_str).unwrap_or("gameplay");
    let frame: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0);
    let out = args.get(3).map(String::as_str).unwrap_or("/tmp/sim_one");
    let fmt = match args.get(4).map(String::as_str) {
        Some("mono8") => PixelFormat::Mono8,
        Some("bayer") => PixelFormat::BayerRggb8,
        _ => PixelFormat::Rgb8,
    };
    let mode = if args.get(5).map(String::as_str) == Some("quality") {
        RenderMode::Quality
    } else {
        RenderMode::Fast
    };
    let scene = SceneConfig::default();
    let mut cams = default_cameras();
    for c in &mut cams {
        c.pixel_format = fmt;
    }
    let scenario = Scenario::by_name(name, &scene, 1)?;
    let t = std::time::Instant::now();
    let mut sim = Simulation::new(scene, cams, scenario, mode)?;
    eprintln!("setup {:.2} s", t.elapsed().as_secs_f64());
    std::fs::create_dir_all(out)?;
    for ci in 0..sim.cameras().len() {
        let mut buf = vec![0u8; sim.frame_bytes(ci)?];
        let m = sim.render(frame, ci, &mut buf)?;
        let p = Path::new(out).join(format!("{}_{:06}.png", sim.cameras()[ci].name, frame));
        write_png(&p, &buf, m.width, m.height, m.format, true)?;
        for r in sim.truth(frame, ci)? {
            eprintln!(
                "cam{ci} rod{} pos {:.2} ang {:.3} {}",
                r.m.rod, r.m.position_mm, r.m.angle_rad, r.m.status
            );
        }
    }
    Ok(())
}
