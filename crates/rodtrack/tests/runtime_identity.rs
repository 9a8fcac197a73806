//! "Done when" of the runtime: the same simulated recording tracked from PNG files, from the
//! live simulator (`sim://`) and, with the `video` feature, from a lossless (FFV1) video gives
//! byte-identical measurement files. Runs the built binary.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_rodtrack");
const FRAMES: usize = 40;

/// Runs rodtrack, which must succeed.
fn run<S: AsRef<str>>(args: &[S]) -> Output {
    let args: Vec<&str> = args.iter().map(AsRef::as_ref).collect();
    let out = Command::new(BIN)
        .args(&args)
        .output()
        .expect("cannot run rodtrack");
    assert!(
        out.status.success(),
        "rodtrack {args:?} failed ({}):\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `rodtrack simulate` of `frames` frames of experiment 3 (seed 1, as `sim://...&seed=1`) into a
/// fresh folder `name`, and `rodtrack calibrate` of its first `cameras` cameras: (the folder,
/// the calibration file).
fn simulate_and_calibrate(name: &str, frames: usize, cameras: usize) -> (PathBuf, PathBuf) {
    let t = dir(name);
    run(&[
        "simulate",
        "--scenario",
        "exp3",
        "--out",
        &t.display().to_string(),
        "--frames",
        &frames.to_string(),
    ]);
    let calib = t.join("c.toml");
    let mut args = vec!["calibrate".to_string()];
    for cam in 0..cameras {
        args.push("--inputs".into());
        args.push(t.join(format!("cam{cam}.json")).display().to_string());
    }
    args.push("--out".into());
    args.push(calib.display().to_string());
    run(&args);
    (t, calib)
}

fn track(calib: &Path, inputs: &[String], out: &Path) -> Vec<u8> {
    let mut args = vec![
        "track".to_string(),
        "--calib".into(),
        calib.display().to_string(),
        "--out".into(),
        out.display().to_string(),
    ];
    for i in inputs {
        args.push("--input".into());
        args.push(i.clone());
    }
    run(&args);
    std::fs::read(out).unwrap()
}

#[test]
fn png_files_live_simulator_and_video_give_identical_measurements() {
    // `simulate` seeds the simulation (and the clicks) with --seed, default 1; `sim://` too.
    let (t, calib) = simulate_and_calibrate("runtime_identity", FRAMES, 2);
    let png = track(
        &calib,
        &[
            t.join("cam0").display().to_string(),
            t.join("cam1").display().to_string(),
        ],
        &t.join("png.csv"),
    );
    let sim = track(
        &calib,
        &[
            format!("sim://exp3?camera=0&frames={FRAMES}&seed=1"),
            format!("sim://exp3?camera=1&frames={FRAMES}&seed=1"),
        ],
        &t.join("sim.csv"),
    );
    let text = String::from_utf8(png.clone()).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // Header, then 7 rods per camera, 2 cameras, plus 8 fused rods, per frame.
    assert_eq!(lines.len(), 1 + FRAMES * (7 + 7 + 8), "{}", &text[..200]);
    let ok = lines.iter().filter(|l| l.ends_with(",ok")).count();
    assert!(ok > FRAMES * 20, "only {ok} ok rows");
    assert!(png == sim, "PNG and sim:// measurements differ");

    #[cfg(feature = "video")]
    {
        if Command::new("ffmpeg").arg("-version").output().is_err() {
            eprintln!("ffmpeg not found: video case skipped");
            return;
        }
        let mut inputs = Vec::new();
        for cam in ["cam0", "cam1"] {
            let video = t.join(format!("{cam}.mkv"));
            let st = Command::new("ffmpeg")
                .args(["-v", "error", "-y", "-framerate", "200", "-i"])
                .arg(t.join(cam).join("%06d.png"))
                .args(["-c:v", "ffv1", "-pix_fmt", "gray"])
                .arg(&video)
                .status()
                .unwrap();
            assert!(st.success(), "ffmpeg failed for {cam}");
            inputs.push(format!("video:{}", video.display()));
        }
        let vid = track(&calib, &inputs, &t.join("video.csv"));
        assert!(png == vid, "PNG and FFV1 video measurements differ");
    }
}

#[test]
fn sim_sources_with_different_seeds_differ() {
    // The identity above is not vacuous: another seed gives other frames, other rows.
    let (t, calib) = simulate_and_calibrate("runtime_identity_seed", 3, 1);
    let a = track(
        &calib,
        &["sim://exp3?camera=0&frames=3&seed=1".into()],
        &t.join("a.csv"),
    );
    let png = track(
        &calib,
        &[t.join("cam0").display().to_string()],
        &t.join("png.csv"),
    );
    let b = track(
        &calib,
        &["sim://exp3?camera=0&frames=3&seed=2".into()],
        &t.join("b.csv"),
    );
    assert!(a == png);
    assert!(a != b);
}
