//! Accuracy on tables as built, not as drawn: random setups of the simulator (cameras tilted
//! about both axes and yawed, shifted, other lenses, rods off their places, print seams),
//! through the command line as a user runs it: `simulate --scenario poses --setup asbuilt:N`
//! (every frame a new random pose of every rod over its whole travel, so the first frame at
//! each pose is what is measured), `calibrate`, `track --raw`, `score`.
//!
//! With known poses (`--known-poses`: the rods at their travel's ends in the reference folder)
//! the targets of the accuracy issue are asserted for position over the whole travel and for
//! gross errors, and, since the known poses give the angle too, for the angle (calibration
//! measures the angle's bias along the travel there); without them the scale is carried by the
//! parallel rods' direction and the position bound is the one such a model gives, and the
//! angle is printed (its target is not met without known poses; see the as-built table of
//! `docs/accuracy.md`).
#![allow(missing_docs, clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn rodtrack(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_rodtrack"))
        .args(args)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "rodtrack {} failed:\n{text}",
        args.join(" ")
    );
    text
}

fn fresh_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The whole run's line of `rodtrack score --json` (every camera and rod).
struct Score {
    n: u64,
    coverage: f64,
    pos_std_mm: f64,
    pos_max_mm: f64,
    ang_std_rad: f64,
    ang_max_rad: f64,
    gross: u64,
    wrong_ok: u64,
}

/// What calibration is given besides the reference pose and the clicks.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Known {
    /// Known poses at the travel's ends with their angle.
    WithAngle,
    /// The same poses, their position alone.
    PositionOnly,
    /// None.
    No,
}

fn run_setup(seed: u64, known: Known, frames: &str) -> Score {
    let dir = fresh_dir(&format!("as_built_{seed}_{known:?}"));
    let d = |p: &str| dir.join(p).display().to_string();
    let setup = format!("asbuilt:{seed}");
    let seed_s = seed.to_string();
    let mut sim = vec![
        "simulate",
        "--scenario",
        "poses",
        "--frames",
        frames,
        "--setup",
        &setup,
        "--seed",
        &seed_s,
    ];
    match known {
        Known::WithAngle => sim.push("--known-poses"),
        Known::PositionOnly => sim.extend(["--known-poses", "--known-poses-without-angle"]),
        Known::No => {}
    }
    let rec = d("rec");
    sim.extend(["--out", &rec]);
    rodtrack(&sim);
    let inputs = std::fs::read_to_string(d("rec/cam0.json")).unwrap();
    assert_eq!(
        inputs.contains("known_poses"),
        known != Known::No,
        "setup {seed}: {known:?}"
    );
    let poses_with_angle = inputs.matches("\"angle_rad\"").count() > 8;
    assert_eq!(
        poses_with_angle,
        known == Known::WithAngle,
        "setup {seed}: {known:?}: {} angles in the inputs (8 references)",
        inputs.matches("\"angle_rad\"").count()
    );
    let calib = rodtrack(&[
        "calibrate",
        "--inputs",
        &d("rec/cam0.json"),
        "--inputs",
        &d("rec/cam1.json"),
        "--out",
        &d("c.toml"),
    ]);
    let model = if known != Known::No {
        "known_poses"
    } else {
        "vanishing_direction"
    };
    assert!(
        calib.contains(&format!("along the travel: {model}")),
        "setup {seed}: calibration did not use {model}:\n{calib}"
    );
    // The simulator's steel rods stand out from the field on both sides: every camera's rods'
    // common direction comes from their outlines.
    assert_eq!(
        calib
            .matches("the rods' common direction: outlines: ")
            .count(),
        2,
        "setup {seed}: the common direction not from the outlines:\n{calib}"
    );
    rodtrack(&[
        "track",
        "--calib",
        &d("c.toml"),
        "--input",
        &d("rec/cam0"),
        "--input",
        &d("rec/cam1"),
        "--raw",
        "--out",
        &d("out.csv"),
    ]);
    rodtrack(&[
        "score",
        "--truth",
        &d("rec/truth.csv"),
        "--measured",
        &d("out.csv"),
        "--json",
        &d("score.json"),
    ]);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("score.json")).unwrap()).unwrap();
    let all = v
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["rod"].is_null())
        .unwrap();
    let s = &all["stats"];
    let f = |k: &str| s[k].as_f64().unwrap();
    let score = Score {
        n: s["n"].as_u64().unwrap(),
        coverage: f("coverage"),
        pos_std_mm: f("pos_std_mm"),
        pos_max_mm: f("pos_max_mm"),
        ang_std_rad: f("ang_std_rad"),
        ang_max_rad: f("ang_max_rad"),
        gross: s["gross"].as_u64().unwrap(),
        wrong_ok: s["wrong_ok"].as_u64().unwrap(),
    };
    eprintln!(
        "setup asbuilt:{seed} ({model}): {} rows, coverage {:.3}, position std {:.4} max {:.4} \
         mm, angle std {:.4} max {:.4} rad, gross {}, wrong ok {}",
        score.n,
        score.coverage,
        score.pos_std_mm,
        score.pos_max_mm,
        score.ang_std_rad,
        score.ang_max_rad,
        score.gross,
        score.wrong_ok
    );
    score
}

/// Several random setups with known poses: position over the whole travel and angle within the
/// accuracy issue's targets (std 0.03 mm, max 0.15 mm; std 0.002 rad, max 0.01 rad), no gross
/// error, full coverage.
#[test]
fn random_setups_with_known_poses_meet_the_targets() {
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for seed in [11, 12, 13] {
        let s = run_setup(seed, Known::WithAngle, "25");
        assert!(s.n > 200, "setup {seed}: only {} rows", s.n);
        assert!(s.coverage >= 0.99, "setup {seed}: coverage {}", s.coverage);
        assert_eq!(s.gross, 0, "setup {seed}: gross errors");
        assert_eq!(s.wrong_ok, 0, "setup {seed}: wrong rows reported ok");
        assert!(
            s.pos_std_mm <= 0.03,
            "setup {seed}: position std {}",
            s.pos_std_mm
        );
        assert!(
            s.pos_max_mm <= 0.15,
            "setup {seed}: position max {}",
            s.pos_max_mm
        );
        // The known poses also give the angle's bias along the travel (calibration removes
        // it): the accuracy issue's angle targets, 0.002 rad std and 0.01 rad max.
        assert!(
            s.ang_std_rad <= 0.002,
            "setup {seed}: angle std {}",
            s.ang_std_rad
        );
        assert!(
            s.ang_max_rad <= 0.01,
            "setup {seed}: angle max {}",
            s.ang_max_rad
        );
        worst = (
            worst.0.max(s.pos_max_mm),
            worst.1.max(s.ang_std_rad),
            worst.2.max(s.ang_max_rad),
        );
    }
    eprintln!(
        "worst of the setups: position max {:.4} mm, angle std {:.4} rad, angle max {:.4} rad",
        worst.0, worst.1, worst.2
    );
}

/// Known poses without their angle (an operator who pushes the rods to their stops and does
/// not know their angle there, as in the validation set): they carry the scale along the
/// travel and place each rod's line; its direction is the rods' common one, from the bare
/// rods' outlines beside the markers. Position and angle within the accuracy issue's targets,
/// no gross error, full coverage. Setup 9 read 0.0023 rad std, 0.0133 rad max (its cameras
/// together) while the common direction came from the markers' silhouettes.
#[test]
fn random_setups_with_known_positions_alone_meet_the_targets() {
    for seed in [9, 11, 13] {
        let s = run_setup(seed, Known::PositionOnly, "25");
        assert!(s.coverage >= 0.99, "setup {seed}: coverage {}", s.coverage);
        assert_eq!(s.gross, 0, "setup {seed}: gross errors");
        assert_eq!(s.wrong_ok, 0, "setup {seed}: wrong rows reported ok");
        assert!(
            s.pos_std_mm <= 0.03 && s.pos_max_mm <= 0.15,
            "setup {seed}: position std {} max {}",
            s.pos_std_mm,
            s.pos_max_mm
        );
        assert!(
            s.ang_std_rad <= 0.002 && s.ang_max_rad <= 0.01,
            "setup {seed}: angle std {} rad, max {} rad",
            s.ang_std_rad,
            s.ang_max_rad
        );
    }
}

/// Without known poses the parallel rods' common direction carries the scale along the
/// travel: no gross error, full coverage, and position within 0.25 mm over the whole travel
/// (the affine scale of the reference pose alone is off by 1-2 mm at the travel's ends on
/// such tables). The accuracy issue's 0.15 mm is met with known poses (above), not always
/// without them: setup 21 reads 0.151 mm.
#[test]
fn random_setups_without_known_poses_use_the_rods_direction() {
    for seed in [21, 22] {
        let s = run_setup(seed, Known::No, "25");
        assert!(s.coverage >= 0.99, "setup {seed}: coverage {}", s.coverage);
        assert_eq!(s.gross, 0, "setup {seed}: gross errors");
        assert!(
            s.pos_max_mm <= 0.25,
            "setup {seed}: position max {}",
            s.pos_max_mm
        );
    }
}
