//! Hostile calibration inputs, calibration files, sidecars and arguments (issue "hostile
//! input"): each is refused with exit code 2 and a message naming the file, field, rod or
//! camera, before anything sized by it is allocated, and no existing file is truncated by a
//! run that then fails on its arguments. Runs that could allocate without bound run under an
//! address-space limit, so that a regression fails the test instead of the machine.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use serde_json::Value;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;

mod common;
use common::Fixture;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_rodtrack");
const FRAMES: u64 = 6;
/// Address-space limit for runs that must not allocate much, KiB (4 GiB).
const VMEM_KB: u64 = 4 << 20;

fn rodtrack(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("cannot run rodtrack")
}

/// `rodtrack args` with the address space limited to [`VMEM_KB`].
fn rodtrack_limited(args: &[&str]) -> Output {
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg(format!("ulimit -v {VMEM_KB}; exec \"$0\" \"$@\""))
        .arg(BIN)
        .args(args);
    cmd.output().expect("cannot run rodtrack")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn assert_error(o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(2), "expected exit code 2:\n{e}");
    for n in needles {
        assert!(e.contains(n), "message lacks `{n}`:\n{e}");
    }
    assert!(!e.contains("panicked"), "{e}");
    assert!(
        !e.contains("rod 4294967295"),
        "a camera error named as a rod:\n{e}"
    );
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| common::recording("bad_arguments", "", "static", FRAMES))
}

/// Camera 0's calibration inputs, changed by `edit`, written beside the original.
fn inputs_with(name: &str, edit: impl FnOnce(&mut Value)) -> PathBuf {
    let f = fixture();
    let mut v: Value =
        serde_json::from_str(&std::fs::read_to_string(f.dir.join("cam0.json")).unwrap()).unwrap();
    edit(&mut v);
    let p = f.dir.join(format!("{name}.json"));
    std::fs::write(&p, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    p
}

fn calibrate(inputs: &Path) -> Output {
    let out = inputs.with_extension("toml");
    rodtrack_limited(&[
        "calibrate",
        "--inputs",
        inputs.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
}

fn track_args(calib: &Path, input: &Path, out: &Path) -> Vec<String> {
    vec![
        "track".into(),
        "--calib".into(),
        calib.display().to_string(),
        "--input".into(),
        input.display().to_string(),
        "--out".into(),
        out.display().to_string(),
    ]
}

fn track(calib: &Path, input: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut a = track_args(calib, input, out);
    a.extend(extra.iter().map(|s| s.to_string()));
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    rodtrack(&a)
}

#[test]
fn duplicate_rod_ids_in_inputs_are_refused() {
    let p = inputs_with("dup_rods", |v| v["rods"][2]["rod"] = 0.into());
    assert_error(&calibrate(&p), &["dup_rods.json", "rod 0", "twice"]);
}

#[test]
fn duplicate_rod_ids_in_a_calibration_file_are_refused() {
    let f = fixture();
    let text = std::fs::read_to_string(&f.calib).unwrap();
    assert!(text.contains("\nrod = 1\n"));
    let c = f.dir.join("dup_rods_calib.toml");
    std::fs::write(&c, text.replacen("\nrod = 1\n", "\nrod = 0\n", 1)).unwrap();
    let o = track(&c, &f.dir.join("cam0"), &f.dir.join("x.csv"), &[]);
    assert_error(&o, &["dup_rods_calib.toml", "rod 0", "twice"]);
}

#[test]
fn huge_travel_is_refused_before_calibrating() {
    for (i, t) in [1e20, 1e10, 1e8].into_iter().enumerate() {
        let p = inputs_with(&format!("travel{i}"), |v| {
            v["rods"][1]["travel_mm"] = serde_json::json!([-t, t]);
        });
        let start = Instant::now();
        let o = calibrate(&p);
        assert_error(&o, &[&format!("travel{i}.json"), "rod 1", "travel_mm"]);
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "travel {t}: refused only after {:?}",
            start.elapsed()
        );
    }
}

#[test]
fn auto_rod_range_is_refused_before_allocating() {
    let f = fixture();
    let o = rodtrack_limited(&[
        "calibrate",
        "--auto",
        "--input",
        f.dir.join("cam0").to_str().unwrap(),
        "--rods",
        "0-4294967295",
        "--out",
        f.dir.join("auto.toml").to_str().unwrap(),
    ]);
    assert_error(&o, &["--rods"]);
}

#[test]
fn camera_fields_name_the_camera_and_come_first() {
    let p = inputs_with("fps0", |v| v["fps"] = 0.into());
    let start = Instant::now();
    let o = calibrate(&p);
    assert_error(&o, &["fps0.json", "camera 0", "fps"]);
    assert!(
        start.elapsed() < Duration::from_secs(2),
        "{:?}",
        start.elapsed()
    );

    let p = inputs_with("ref99", |v| {
        v["reference_frames"]["reference_frame"] = 99.into()
    });
    assert_error(
        &calibrate(&p),
        &["ref99.json", "reference_frames.reference_frame", "99"],
    );

    let p = inputs_with("rodmax", |v| v["rods"][0]["rod"] = u32::MAX.into());
    let o = calibrate(&p);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("rodmax.json") && e.contains("at most"), "{e}");

    let p = inputs_with("norods", |v| v["rods"] = serde_json::json!([]));
    assert_error(
        &calibrate(&p),
        &["norods.json", "camera 0", "rods", "empty"],
    );
}

#[test]
fn a_bad_udp_address_leaves_the_output_file_alone() {
    let f = fixture();
    let out = f.dir.join("precious.csv");
    std::fs::write(&out, "rows from yesterday\n").unwrap();
    let o = track(
        &f.calib,
        &f.dir.join("cam0"),
        &out,
        &["--udp", "not an address"],
    );
    assert_error(&o, &["not an address"]);
    assert_eq!(
        std::fs::read_to_string(&out).unwrap(),
        "rows from yesterday\n"
    );
}

#[test]
fn out_equal_to_calib_is_refused() {
    let f = fixture();
    let c = f.dir.join("same.toml");
    std::fs::copy(&f.calib, &c).unwrap();
    let before = std::fs::read(&c).unwrap();
    let o = track(&c, &f.dir.join("cam0"), &c, &[]);
    assert_error(&o, &["same.toml", "--out"]);
    assert_eq!(std::fs::read(&c).unwrap(), before);
}

/// Camera 0's frames with a `timestamps.csv` of these times.
fn with_timestamps(name: &str, times: &[&str]) -> PathBuf {
    let f = fixture();
    let d = f.dir.join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    for e in std::fs::read_dir(f.dir.join("cam0")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, d.join(p.file_name().unwrap())).unwrap();
    }
    let mut csv = "frame,timestamp_s\n".to_string();
    for (i, t) in times.iter().enumerate() {
        csv.push_str(&format!("{i},{t}\n"));
    }
    std::fs::write(d.join("timestamps.csv"), csv).unwrap();
    d
}

#[test]
fn timestamps_that_cannot_be_a_capture_clock_are_refused() {
    let f = fixture();
    let cases: [(&str, [&str; FRAMES as usize], &str); 3] = [
        (
            "ts_decreasing",
            ["0.00", "0.01", "0.02", "0.015", "0.04", "0.05"],
            "line 5",
        ),
        ("ts_equal", ["1", "1", "1", "1", "1", "1"], "same time"),
        (
            "ts_huge",
            ["0", "0.005", "1e300", "0.02", "0.025", "0.03"],
            "1e300",
        ),
    ];
    for (name, times, needle) in cases {
        let d = with_timestamps(name, &times);
        let o = track(&f.calib, &d, &f.dir.join(format!("{name}.csv")), &[]);
        assert_error(&o, &["timestamps.csv", needle]);
    }
}

#[test]
fn a_run_in_which_every_frame_is_bad_fails() {
    let f = fixture();
    let d = f.dir.join("all_bad");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    for i in 0..3 {
        let mut pgm = b"P5\n64 48\n255\n".to_vec();
        pgm.resize(pgm.len() + 64 * 48, 128);
        std::fs::write(d.join(format!("{i:06}.pgm")), pgm).unwrap();
    }
    let out = f.dir.join("all_bad.csv");
    let o = track(&f.calib, &d, &out, &[]);
    let e = stderr(&o);
    assert_ne!(o.status.code(), Some(0), "{e}");
    assert!(e.contains("every frame"), "{e}");
    // The rows are written all the same.
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.lines()
            .skip(1)
            .all(|l| l.split(',').nth(10) == Some("bad_frame")),
        "{text}"
    );
    assert_eq!(text.lines().count(), 1 + 3 * 7);
}

#[test]
fn out_dash_writes_to_standard_output() {
    let f = fixture();
    let cwd = f.dir.join("dash");
    let _ = std::fs::create_dir_all(&cwd);
    let o = Command::new(BIN)
        .current_dir(&cwd)
        .args(["track", "--calib"])
        .arg(&f.calib)
        .arg("--input")
        .arg(f.dir.join("cam0"))
        .args(["--out", "-"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!cwd.join("-").exists(), "a file named `-` was made");
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.starts_with("frame,timestamp_s,"), "{text}");
    assert_eq!(text.lines().count() as u64, 1 + 7 * FRAMES, "{text}");
}

#[test]
fn a_broken_pipe_stops_the_run() {
    let f = fixture();
    let mut child = Command::new(BIN)
        .args(["track", "--calib"])
        .arg(&f.calib)
        .args([
            "--input",
            "sim://static?camera=0&frames=5000",
            "--out",
            "/dev/stdout",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 16];
    child
        .stdout
        .as_mut()
        .unwrap()
        .read_exact(&mut first)
        .unwrap();
    drop(child.stdout.take());
    let start = Instant::now();
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    let status = child.wait().unwrap();
    assert!(
        start.elapsed() < Duration::from_secs(3),
        "went on for {:?} after the reader had gone",
        start.elapsed()
    );
    assert!(!status.success());
    let pipe_lines = err.lines().filter(|l| l.contains("Broken pipe")).count();
    assert!(
        pipe_lines <= 2,
        "{pipe_lines} lines about the broken pipe:\n{err}"
    );
}

#[test]
fn os_errors_are_printed_once() {
    let f = fixture();
    let o = track(
        &f.calib,
        &f.dir.join("cam0"),
        &f.dir.join("no_such_dir").join("o.csv"),
        &[],
    );
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert_eq!(e.matches("os error 2").count(), 1, "{e}");
}
