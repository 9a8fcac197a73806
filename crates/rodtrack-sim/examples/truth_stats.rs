//! Counts truth statuses over a scenario: `cargo run --release -p rodtrack-sim --example truth_stats -- gameplay`.
use rodtrack_sim::{default_cameras, RenderMode, Scenario, SceneConfig, Simulation};
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let name = std::env::args().nth(1).unwrap_or_else(|| "gameplay".into());
    let scene = SceneConfig::default();
    let sc = Scenario::by_name(&name, &scene, 1)?;
    let s = Simulation::new(scene, default_cameras(), sc, RenderMode::Fast)?;
    for cam in 0..2 {
        let mut counts = vec![[0usize; 3]; 8];
        for f in 0..s.frame_count() {
            for r in s.truth(f, cam)? {
                let k = match r.m.status {
                    rodtrack_core::Status::Ok => 0,
                    rodtrack_core::Status::Occluded => 1,
                    _ => 2,
                };
                counts[r.m.rod as usize][k] += 1;
            }
        }
        println!("{name} cam{cam} (ok, occluded, out_of_view) per rod: {counts:?}");
    }
    Ok(())
}
