//! Render speed: times N frames of one camera and prints the median ms/frame and frames/s.
//!
//! `cargo bench -p rodtrack-sim --bench render -- [fast|quality] [SCENARIO] [N] [FORMAT]`
//! (defaults: fast gameplay, 400 frames in fast mode and 40 in quality mode, bayer_rggb8).
//! Single thread, one 1440 x 1080 camera; frames are spread over the whole scenario. Results
//! are in `BENCHMARKS.md` beside this crate's `Cargo.toml`.

use rodtrack_core::PixelFormat;
use rodtrack_sim::{default_cameras, RenderMode, Scenario, SceneConfig, Simulation};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let mode = match args.first().map(String::as_str) {
        Some("quality") => RenderMode::Quality,
        _ => RenderMode::Fast,
    };
    let name = args.get(1).map(String::as_str).unwrap_or("gameplay");
    let n: usize = args
        .get(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(match mode {
            RenderMode::Fast => 400,
            RenderMode::Quality => 40,
        });
    let fmt = args
        .get(3)
        .and_then(|s| PixelFormat::from_name(s))
        .unwrap_or(PixelFormat::BayerRggb8);
    let scene = SceneConfig::default();
    let mut cams = default_cameras();
    cams.truncate(1);
    cams[0].pixel_format = fmt;
    let scenario = Scenario::by_name(name, &scene, 1).expect("known scenario");
    let t = Instant::now();
    let mut sim = Simulation::new(scene, cams, scenario, mode).expect("valid simulation");
    let setup = t.elapsed().as_secs_f64();
    let mut buf = vec![0u8; sim.frame_bytes(0).expect("camera 0")];
    let frames = sim.frame_count();
    // Spread the frames over the scenario so that hands, kicks and spins are included.
    let step = (frames / n.max(1)).max(1);
    let mut times = Vec::with_capacity(n);
    let mut phases = [0.0f64; 4];
    let mut tiles = 0usize;
    let mut cands = 0usize;
    for k in 0..n {
        let fi = (k * step) % frames.max(1);
        let t = Instant::now();
        sim.render(fi, 0, &mut buf).expect("render");
        times.push(t.elapsed().as_secs_f64() * 1e3);
        if let Some(s) = sim.last_render_stats(0) {
            phases[0] += s.restore_ms;
            phases[1] += s.markers_ms;
            phases[2] += s.objects_ms;
            phases[3] += s.finish_ms;
            tiles += s.object_tiles;
            cands += s.object_cands;
        }
    }
    let nf = n.max(1) as f64;
    println!(
        "mean per frame: restore {:.3} ms, markers {:.3} ms, objects {:.3} ms ({:.0} tiles, {:.1} objects per tile), finish {:.3} ms",
        phases[0] / nf,
        phases[1] / nf,
        phases[2] / nf,
        tiles as f64 / nf,
        cands as f64 / tiles.max(1) as f64,
        phases[3] / nf
    );
    let t = Instant::now();
    for k in 0..n {
        let fi = (k * step) % frames.max(1);
        std::hint::black_box(sim.truth(fi, 0).expect("truth"));
    }
    println!(
        "truth (8 rods, visibility by ray casting): {:.3} ms/frame",
        t.elapsed().as_secs_f64() * 1e3 / n.max(1) as f64
    );
    times.sort_by(f64::total_cmp);
    let med = times[times.len() / 2];
    let p90 = times[times.len() * 9 / 10];
    println!(
        "render {:?} {name} {fmt}: setup {setup:.2} s; {n} frames: median {med:.3} ms/frame ({:.0} frames/s), p90 {p90:.3} ms, max {:.3} ms",
        mode,
        1e3 / med,
        times[times.len() - 1]
    );
}
