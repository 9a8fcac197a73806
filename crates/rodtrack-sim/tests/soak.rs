//! The soak test: thousands of frames over random tables as built, with everything that has
//! made the tracker wrong or blind: gameplay (fast slides, kicks, hands over the markers, the
//! ball), a glare lamp at a random place (on a Gray code half of the time), a rod spinning up
//! to as fast as 3000 rpm and down again, and dropped frames.
//!
//! It asserts, per camera, for the raw tracker rows and the filtered rows: no row `ok` with a
//! gross error (0.2 rad or 5 mm), no row `ok` whose turn count is reported known and slipped,
//! and no measurable rod (its marker wholly visible, not under
//! the lamp, turning slower than the paper's 60 rad/s) not `ok` for longer than the recovery
//! target. `RODTRACK_SOAK_FRAMES=N` runs N frames per table (default 200) and
//! `RODTRACK_SOAK_TABLES=N` N tables (default 3) by hand.
#![allow(missing_docs, clippy::unwrap_used)]

mod robust;

use robust::{describe, glare_on_rod, run, table, RunOptions};
use rodtrack_sim::rng::Rng;
use rodtrack_sim::scene::Glare;
use rodtrack_sim::{Lighting, Scenario, TrackBuilder};
use std::f64::consts::TAU;

/// Frames a measurable marker may stay not `ok` (the recovery target).
const RECOVERY_FRAMES: usize = 5;

fn env_or(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

#[test]
fn soak_random_tables_glare_hands_spins_dropped_frames() {
    let frames = env_or("RODTRACK_SOAK_FRAMES", 200);
    let tables = env_or("RODTRACK_SOAK_TABLES", 3) as u64;
    // The tables run in parallel (each one is independent and single-threaded).
    let failures: Vec<String> = std::thread::scope(|scope| {
        let runs: Vec<_> = (101..101 + tables)
            .map(|seed| scope.spawn(move || soak_table(seed, frames)))
            .collect();
        runs.into_iter()
            .flat_map(|r| r.join().expect("a soak table's thread panicked"))
            .collect()
    });
    assert!(
        failures.is_empty(),
        "soak failures:\n{}",
        failures.join("\n")
    );
}

/// One random table of the soak: its failures, described.
fn soak_table(seed: u64, frames: usize) -> Vec<String> {
    let mut failures = Vec::new();
    let setup = format!("asbuilt:{seed}");
    let (scene, cameras) = table(&setup);
    let mut rng = Rng::new(seed ^ 0x50A4_0000);
    let mut sc = Scenario::by_name("gameplay", &scene, seed)
        .unwrap()
        .with_frames(frames);
    let dur = sc.duration_s;
    // A spin up to 600..3000 rpm within 20..100 ms, held, and down again.
    let spin_rod = rng.below(scene.rods.len() as u64) as usize;
    let rate = rng.range(600.0, 3000.0) / 60.0 * TAU * if rng.below(2) == 0 { 1.0 } else { -1.0 };
    let ramp = rng.range(0.02, 0.1);
    let t0 = rng.range(0.1, 0.4) * dur;
    let mut a = TrackBuilder::new(0.0);
    a.hold(t0)
        .spin(rate, ramp)
        .hold(rng.range(0.2, 0.4) * dur)
        .spin(-rate, ramp);
    sc.rods[spin_rod].angle = a.build();
    // A lamp's reflection seen by one camera: on a rod's Gray code, or anywhere.
    let cam = rng.below(cameras.len() as u64) as usize;
    let glare_rod = rng.below(scene.rods.len() as u64) as usize;
    let (sigma, peak) = (rng.range(4.0, 20.0), rng.range(150.0, 260.0));
    let glare = if rng.below(4) != 0 {
        // On a Gray code, the rod standing still under it (as reported: a static rod).
        let g = &scene.marker.gray_code;
        let u = rng.range(g.start_mm, g.start_mm + g.bits as f64 * g.bit_space_mm);
        let h = scene.rods[glare_rod].half_travel_mm();
        let p = rng.range(-0.8 * h, 0.8 * h);
        sc.rods[glare_rod].position = rodtrack_sim::Track::constant(p);
        sc.rods[glare_rod].angle = rodtrack_sim::Track::constant(rng.range(0.0, TAU));
        glare_on_rod(&scene, glare_rod, u, p, sigma, peak, Some(cam))
    } else {
        Glare {
            at_mm: [
                rng.range(0.0, scene.field_length_mm),
                rng.range(0.0, scene.field_width_mm),
                80.0,
            ],
            sigma_px: sigma,
            peak_dn: peak,
            camera: Some(cam),
        }
    };
    sc.lighting = Some(Lighting {
        glare: Some(glare),
        ..scene.lighting
    });
    let mut g = TrackBuilder::new(0.0);
    g.hold(rng.range(0.05, 0.3) * dur)
        .move_to(1.0, 50.0, 1e4)
        .hold(rng.range(0.2, 0.5) * dur)
        .move_to(0.0, 50.0, 1e4);
    sc.glare = g.build();
    // About 2 % of the frames dropped.
    let dropped: Vec<usize> = (1..frames).filter(|_| rng.below(50) == 0).collect();
    // The rod under the lamp is the one whose axis is nearest to it.
    let at = glare.at_mm;
    let near = (0..scene.rods.len())
        .min_by(|&i, &j| {
            (scene.rods[i].x_mm - at[0])
                .abs()
                .total_cmp(&(scene.rods[j].x_mm - at[0]).abs())
        })
        .unwrap_or(0);
    let opts = RunOptions {
        dropped,
        glared: Some((cam, near as u32)),
        max_rate_rad_s: 60.0,
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let o = run(scene, cameras, sc, seed, &opts).unwrap();
    let name = format!(
        "{setup} ({frames} frames): spin rod {spin_rod} {:.0} rpm, glare camera {cam} near \
         rod {near} sigma {sigma:.0} px peak {peak:.0} DN, {} dropped, {:.1?}",
        rate.abs() * 60.0 / TAU,
        opts.dropped.len(),
        t.elapsed()
    );
    eprint!("{}", describe(&name, &o));
    for (c, (r, f)) in o.raw.iter().zip(&o.filtered).enumerate() {
        for (kind, tally) in [("raw", r), ("filtered", f)] {
            if !tally.gross.is_empty() {
                failures.push(format!(
                    "{setup} camera {c} {kind}: {} rows ok with a gross error, first {:?}",
                    tally.gross.len(),
                    tally.gross[0]
                ));
            }
            if tally.longest_out.0 > RECOVERY_FRAMES {
                failures.push(format!(
                    "{setup} camera {c} {kind}: rod {} measurable and not ok for {} frames \
                     from frame {}",
                    tally.longest_out.1, tally.longest_out.0, tally.longest_out.2
                ));
            }
        }
    }
    // No row ok with a turn count it claims known and that slipped.
    for (c, (r, f)) in o.raw.iter().zip(&o.filtered).enumerate() {
        for (kind, tally) in [("raw", r), ("filtered", f)] {
            if let Some(first) = tally.turn_slips.first() {
                failures.push(format!(
                    "{setup} camera {c} {kind}: {} rows ok with a known turn count that \
                     slipped, first (frame, rod, turns) {first:?}",
                    tally.turn_slips.len()
                ));
            }
        }
    }
    failures
}
