//! Automatic calibration: markers found without clicks, and `rodtrack calibrate --auto` from a
//! recording in which every rod sweeps its travel, end to end through `track` and `score`.
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_core::calib::find::find_markers;
use rodtrack_core::{FrameView, Marker};
use rodtrack_sim::{default_cameras, RenderMode, Scenario, SceneConfig, Simulation};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn sim(scenario: &str, frames: Option<usize>, seed: u64) -> Simulation {
    let scene = SceneConfig::default();
    let mut sc = Scenario::by_name(scenario, &scene, seed).unwrap();
    if let Some(n) = frames {
        sc = sc.with_frames(n);
    }
    Simulation::new(scene, default_cameras(), sc, RenderMode::Fast)
        .unwrap()
        .with_seed(seed)
}

#[test]
fn markers_are_found_where_they_are() {
    let mut s = sim("static", Some(1), 2);
    let marker = Marker::v1();
    for cam in 0..2 {
        let mut buf = vec![0u8; s.frame_bytes(cam).unwrap()];
        let meta = s.render_reference(cam, &mut buf).unwrap();
        let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
        let found = find_markers(&view, &marker, true, 0.7);
        let inputs = s.calibration_inputs(cam, 2).unwrap();
        assert_eq!(found.len(), inputs.rods.len(), "camera {cam}: {found:?}");
        for r in &inputs.rods {
            let rod = &s.scene().rods[r.rod as usize];
            let centre_y = rod.marker_y(36.0, 0.0);
            let (tx, ty) = s
                .project_rod_axis(cam, r.rod as usize, centre_y)
                .unwrap()
                .unwrap();
            let best = found
                .iter()
                .map(|f| ((f.x_px - tx).powi(2) + (f.y_px - ty).powi(2)).sqrt())
                .fold(f64::MAX, f64::min);
            eprintln!("camera {cam} rod {}: nearest detection {best:.2} px", r.rod);
            assert!(best < 3.0, "camera {cam} rod {}: {best} px", r.rod);
        }
    }
}

// ---- the command line, end to end ----

/// The sweep as a camera at 5 frames/s would take it: every `SWEEP_STEP`-th frame of the
/// simulator's `sweep` scenario up to `SWEEP_END` (the sweep reaches both ends of every rod's
/// travel by frame 2500).
const SWEEP_STEP: &str = "40";
const SWEEP_END: &str = "2600";

fn rodtrack(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_rodtrack"))
        .args(args)
        .output()
        .unwrap();
    eprintln!(
        "$ rodtrack {}\n{}{}",
        args.join(" "),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs rodtrack, which must succeed; returns what it printed (stdout, then stderr).
fn ok(args: &[&str]) -> String {
    let out = rodtrack(args);
    assert!(out.status.success(), "rodtrack {} failed", args.join(" "));
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

fn fresh_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The rows of one camera of a measurement or truth CSV.
fn rows_of_camera(csv: &Path, cam: &str, out: &Path) {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let col = header.split(',').position(|c| c == "camera").unwrap();
    let mut kept = format!("{header}\n");
    for l in lines.filter(|l| l.split(',').nth(col) == Some(cam)) {
        kept.push_str(l);
        kept.push('\n');
    }
    std::fs::write(out, kept).unwrap();
}

/// One rod's line of `rodtrack score --json`: (rod, rows, pos std, pos max, ang std, ang max,
/// gross, coverage).
type RodScore = (u64, u64, f64, f64, f64, f64, u64, f64);

fn score_per_rod(json: &Path) -> Vec<RodScore> {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    v.as_array()
        .unwrap()
        .iter()
        .filter(|e| !e["rod"].is_null())
        .map(|e| {
            let s = &e["stats"];
            let f = |k: &str| s[k].as_f64().unwrap();
            (
                e["rod"].as_u64().unwrap(),
                s["n"].as_u64().unwrap(),
                f("pos_std_mm"),
                f("pos_max_mm"),
                f("ang_std_rad"),
                f("ang_max_rad"),
                s["gross"].as_u64().unwrap(),
                f("coverage"),
            )
        })
        .collect()
}

/// All through the command line: `rodtrack simulate` of the sweep (`--every`, with the camera
/// models as OpenCV files) and of experiment 3 -> `calibrate --auto` -> `track` -> `score`:
/// every rod of both cameras within 0.1 mm (std) and 0.5 mm (max), no gross angle error; and
/// the calibration inputs it saved give the same calibration through `calibrate --inputs`.
#[test]
fn calibrate_auto_end_to_end() {
    let dir = fresh_dir("auto_calibration_e2e");
    let d = |p: &str| dir.join(p).display().to_string();
    let t0 = std::time::Instant::now();
    let out = ok(&[
        "simulate",
        "--scenario",
        "sweep",
        "--out",
        &d("sweep"),
        "--frames",
        SWEEP_END,
        "--every",
        SWEEP_STEP,
        "--seed",
        "1",
    ]);
    assert!(
        out.contains("wrote 65 frames (one in 40) x 2 cameras"),
        "{out}"
    );
    ok(&[
        "simulate",
        "--scenario",
        "exp3",
        "--out",
        &d("rec"),
        "--frames",
        "700",
        "--seed",
        "1",
    ]);
    eprintln!("recordings written in {:.1} s", t0.elapsed().as_secs_f64());
    let t1 = std::time::Instant::now();
    let out = ok(&[
        "calibrate",
        "--auto",
        "--input",
        &d("sweep/cam0"),
        "--input",
        &d("sweep/cam1"),
        "--rods",
        "0-6",
        "--rods",
        "1-7",
        "--opencv-model",
        &d("sweep/cam0_intrinsics.yml"),
        "--opencv-model",
        &d("sweep/cam1_intrinsics.yml"),
        "--out",
        &d("auto.toml"),
    ]);
    eprintln!("calibrate --auto in {:.1} s", t1.elapsed().as_secs_f64());
    assert!(out.contains("rods along image rows"), "{out}");
    assert!(
        !out.contains("doubtful"),
        "a sharp reference frame is not doubtful"
    );
    // Every rod of both cameras is calibrated, with the camera model.
    let cal: toml::Value =
        toml::from_str(&std::fs::read_to_string(dir.join("auto.toml")).unwrap()).unwrap();
    let cams = cal["cameras"].as_array().unwrap();
    assert_eq!(cams.len(), 2);
    for (c, want) in cams.iter().zip([0..7u32, 1..8u32]) {
        let rods: Vec<u32> = c["rods"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["rod"].as_integer().unwrap() as u32)
            .collect();
        assert_eq!(rods, want.collect::<Vec<_>>());
        for r in c["rods"].as_array().unwrap() {
            assert_eq!(r["line_model"].as_str(), Some("camera"));
            let res = &r["residuals"];
            let rms = res["path_rms_px"].as_float().unwrap();
            assert!(rms < 0.5, "path rms {rms} px");
            assert!(res["reference_ncc"].as_float().unwrap() > 0.9);
            // The travel measured from the sweep holds the rod's real travel (+/- h).
            let h = [100.0, 175.0, 57.5, 95.0, 95.0, 57.5, 175.0, 100.0]
                [r["rod"].as_integer().unwrap() as usize];
            let t = r["travel_mm"].as_array().unwrap();
            let (lo, hi) = (t[0].as_float().unwrap(), t[1].as_float().unwrap());
            assert!(
                lo <= -h && lo > -h - 6.0 && hi >= h && hi < h + 6.0,
                "travel {lo}..{hi} for +/-{h}"
            );
        }
    }
    // The inputs it derived reproduce the calibration through the normal path.
    ok(&[
        "calibrate",
        "--inputs",
        &d("auto.cam0.json"),
        "--inputs",
        &d("auto.cam1.json"),
        "--out",
        &d("rerun.toml"),
    ]);
    let auto = std::fs::read_to_string(dir.join("auto.toml")).unwrap();
    let rerun = std::fs::read_to_string(dir.join("rerun.toml")).unwrap();
    if let Some((i, (a, b))) = auto
        .lines()
        .zip(rerun.lines())
        .enumerate()
        .find(|(_, (a, b))| a != b)
    {
        panic!(
            "calibrate --inputs on the saved inputs differs from --auto at line {}: {a} / {b}",
            i + 1
        );
    }
    assert_eq!(auto.lines().count(), rerun.lines().count());
    // Track experiment 3 and score each camera's rows against the truth.
    ok(&[
        "track",
        "--calib",
        &d("auto.toml"),
        "--input",
        &d("rec/cam0"),
        "--input",
        &d("rec/cam1"),
        "--out",
        &d("out.csv"),
    ]);
    for cam in ["0", "1"] {
        // One camera's rows, scored against that camera's truth.
        let measured = dir.join(format!("cam{cam}.csv"));
        let truth = dir.join(format!("truth{cam}.csv"));
        rows_of_camera(&dir.join("out.csv"), cam, &measured);
        rows_of_camera(&dir.join("rec/truth.csv"), cam, &truth);
        let json = dir.join(format!("score{cam}.json"));
        ok(&[
            "score",
            "--truth",
            &truth.display().to_string(),
            "--measured",
            &measured.display().to_string(),
            "--json",
            &json.display().to_string(),
        ]);
        let rows = score_per_rod(&json);
        assert_eq!(rows.len(), 7, "camera {cam}: {rows:?}");
        for (rod, n, pstd, pmax, astd, amax, gross, cov) in rows {
            eprintln!(
                "camera {cam} rod {rod}: {n} rows, position std {pstd:.4} max {pmax:.4} mm, \
                 angle std {astd:.4} max {amax:.4} rad, gross {gross}, coverage {cov:.3}"
            );
            assert!(n >= 600, "camera {cam} rod {rod}: {n} rows");
            assert!(
                pstd <= 0.1,
                "camera {cam} rod {rod}: position std {pstd} mm"
            );
            assert!(
                pmax <= 0.5,
                "camera {cam} rod {rod}: position max {pmax} mm"
            );
            assert_eq!(gross, 0, "camera {cam} rod {rod}: gross errors");
            assert!(
                amax < std::f64::consts::TAU / 32.0,
                "camera {cam} rod {rod}: angle {amax}"
            );
            assert!(cov > 0.95, "camera {cam} rod {rod}: coverage {cov}");
        }
    }
    eprintln!("end to end in {:.1} s", t0.elapsed().as_secs_f64());
    partial_sweeps_and_bad_input_are_reported(&dir);
    opencv_model_files_in_the_inputs(&dir);
}

/// A sweep cut short, or a noisy reference frame, warns for every rod; bad arguments fail
/// with clear messages.
fn partial_sweeps_and_bad_input_are_reported(dir: &Path) {
    let d = |p: &str| dir.join(p).display().to_string();
    // The reference frame with strong noise (sigma 60 DN): every rod's reference is doubtful.
    let noisy = dir.join("noisy");
    std::fs::create_dir_all(&noisy).unwrap();
    for e in std::fs::read_dir(dir.join("sweep/cam0")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, noisy.join(p.file_name().unwrap())).unwrap();
    }
    let mut frame = image::open(noisy.join("000000.png")).unwrap().into_luma8();
    let mut state = 12345u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    for px in frame.pixels_mut() {
        let g = (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos();
        px.0[0] = (px.0[0] as f64 + 60.0 * g).round().clamp(0.0, 255.0) as u8;
    }
    frame.save(noisy.join("000000.png")).unwrap();
    let out = ok(&[
        "calibrate",
        "--auto",
        "--input",
        &d("noisy"),
        "--out",
        &d("noisy.toml"),
    ]);
    // Each rod is warned about, or left out when its reference reads as refused (its angle's
    // zero would be read from a reading the tracker does not trust).
    let warned = rods_reported(&out, "doubtful reference", "the reference frame reads as");
    assert_eq!(warned, 7, "one warning per rod: {out}");
    // The first 10 frames (1.8 s): every rod covered a third of its travel or less.
    let out = ok(&[
        "calibrate",
        "--auto",
        "--input",
        &d("sweep/cam0"),
        "--max-frames",
        "10",
        "--travel-mm",
        "-100,100",
        "--out",
        &d("partial.toml"),
    ]);
    // Each rod is warned about, or left out when its reference reads as refused with the
    // line its few path points give.
    let warned = rods_reported(
        &out,
        "spread them along the whole path",
        "path points follow the rod",
    );
    assert_eq!(warned, 7, "one warning per rod: {out}");
    let fail = |args: &[&str], want: &[&str]| {
        let o = rodtrack(args);
        assert!(!o.status.success(), "rodtrack {} succeeded", args.join(" "));
        let err = String::from_utf8_lossy(&o.stderr);
        for w in want {
            assert!(err.contains(w), "`{w}` not in: {err}");
        }
    };
    fail(
        &[
            "calibrate",
            "--auto",
            "--input",
            &d("sweep/cam0"),
            "--rods",
            "0-5",
            "--out",
            &d("x.toml"),
        ],
        &["--rods names 6 rod(s)", "shows 7 marker(s)"],
    );
    fail(
        &[
            "calibrate",
            "--auto",
            "--input",
            &d("nowhere"),
            "--out",
            &d("x.toml"),
        ],
        &["camera 0", "nowhere"],
    );
    fail(
        &[
            "calibrate",
            "--auto",
            "--input",
            &d("sweep/cam0"),
            "--input",
            &d("sweep/cam1"),
            "--opencv-model",
            &d("sweep/cam0_intrinsics.yml"),
            "--out",
            &d("x.toml"),
        ],
        &["one --opencv-model per --input"],
    );
    fail(
        &[
            "calibrate",
            "--auto",
            "--input",
            &d("sweep/cam0"),
            "--reference-frame",
            "500",
            "--out",
            &d("x.toml"),
        ],
        &["reference frame 500 was not read"],
    );
}

/// `opencv_model_file` in the calibration inputs: the model is read from the FileStorage file
/// (relative to the inputs); errors name the file and the field.
fn opencv_model_files_in_the_inputs(dir: &Path) {
    let d = |p: &str| dir.join(p).display().to_string();
    let text = std::fs::read_to_string(dir.join("auto.cam0.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let inline = v["opencv_model_optional"].clone();
    let o = v.as_object_mut().unwrap();
    o.remove("opencv_model_optional");
    o.insert(
        "opencv_model_file".into(),
        "sweep/cam0_intrinsics.yml".into(),
    );
    std::fs::write(dir.join("file_model.json"), v.to_string()).unwrap();
    ok(&[
        "calibrate",
        "--inputs",
        &d("file_model.json"),
        "--out",
        &d("file_model.toml"),
    ]);
    let cal: toml::Value =
        toml::from_str(&std::fs::read_to_string(dir.join("file_model.toml")).unwrap()).unwrap();
    let cam = &cal["cameras"][0];
    let k = cam["opencv_model"]["camera_matrix"].as_array().unwrap();
    let k_inline = inline["camera_matrix"].as_array().unwrap();
    for (a, b) in k.iter().zip(k_inline) {
        for (x, y) in a.as_array().unwrap().iter().zip(b.as_array().unwrap()) {
            let (x, y) = (x.as_float().unwrap(), y.as_f64().unwrap());
            assert!((x - y).abs() <= 1e-9 * y.abs().max(1.0), "{x} {y}");
        }
    }
    assert_eq!(cam["rods"].as_array().unwrap().len(), 7);
    assert_eq!(cam["rods"][0]["line_model"].as_str(), Some("camera"));
    let stderr_of = |args: &[&str]| {
        let o = rodtrack(args);
        assert!(!o.status.success());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    // Both forms at once.
    let o = v.as_object_mut().unwrap();
    o.insert("opencv_model_optional".into(), inline);
    std::fs::write(dir.join("both.json"), v.to_string()).unwrap();
    let err = stderr_of(&[
        "calibrate",
        "--inputs",
        &d("both.json"),
        "--out",
        &d("x.toml"),
    ]);
    assert!(
        err.contains("both.json") && err.contains("opencv_model_file") && err.contains("not both"),
        "{err}"
    );
    // A model with a rational coefficient rodtrack cannot use.
    let o = v.as_object_mut().unwrap();
    o.remove("opencv_model_optional");
    o.insert("opencv_model_file".into(), "rational.yml".into());
    std::fs::write(dir.join("rational.json"), v.to_string()).unwrap();
    let yml = std::fs::read_to_string(dir.join("sweep/cam0_intrinsics.yml")).unwrap();
    let yml = yml
        .replace("cols: 5", "cols: 8")
        .replace("0e0 ]", "0e0, 1.5e-2, 0., 0. ]");
    std::fs::write(dir.join("rational.yml"), yml).unwrap();
    let err = stderr_of(&[
        "calibrate",
        "--inputs",
        &d("rational.json"),
        "--out",
        &d("x.toml"),
    ]);
    assert!(
        err.contains("rational.yml")
            && err.contains("distortion_coefficients")
            && err.contains("k4 = 0.015"),
        "{err}"
    );
    // A missing file.
    let o = v.as_object_mut().unwrap();
    o.insert("opencv_model_file".into(), "missing.yml".into());
    std::fs::write(dir.join("missing.json"), v.to_string()).unwrap();
    let err = stderr_of(&[
        "calibrate",
        "--inputs",
        &d("missing.json"),
        "--out",
        &d("x.toml"),
    ]);
    assert!(
        err.contains("missing.json") && err.contains("missing.yml"),
        "{err}"
    );
}

/// The lines of `out` that warn about a rod (`warning`), or report it not calibrated for a
/// reason holding `refusal`.
fn rods_reported(out: &str, warning: &str, refusal: &str) -> usize {
    out.lines()
        .filter(|l| l.contains(warning) || (l.contains("not calibrated") && l.contains(refusal)))
        .count()
}
