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
    // The status is the 11th column (the turn count's flag follows it).
    let ok = lines
        .iter()
        .filter(|l| l.split(',').nth(10) == Some("ok"))
        .count();
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

/// `track --console`: the console takes the live frames' buffers from the runtime (the frame
/// hook swaps them, no copy). A client connected to the live view gets frames while the live
/// simulator runs in real time, and the measurements are those of the same run without the
/// console: a swapped buffer goes back to the runtime's pool and later frames are whole.
#[test]
fn track_with_the_console_serves_live_frames_and_measures_the_same() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    const LIVE_FRAMES: usize = 500;
    let (t, calib) = simulate_and_calibrate("runtime_console", 2, 2);
    let inputs: Vec<String> = (0..2)
        .map(|c| format!("sim://exp3?camera={c}&frames={LIVE_FRAMES}&seed=1&realtime=1"))
        .collect();
    let out = t.join("console.csv");
    let mut child = Command::new(BIN)
        .args(["track", "--calib", &calib.display().to_string()])
        .args(["--input", &inputs[0], "--input", &inputs[1]])
        .args(["--out", &out.display().to_string()])
        .args(["--console", "127.0.0.1:0"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut addr = None;
    let mut line = String::new();
    while stderr.read_line(&mut line).unwrap() > 0 {
        if let Some(url) = line.trim().strip_prefix("web console: http://") {
            addr = Some(url.trim_end_matches('/').to_string());
            break;
        }
        line.clear();
    }
    let addr = addr.expect("track printed no console address");
    // Drain the rest of stderr (progress) so the child never blocks on it.
    let drain = std::thread::spawn(move || {
        let mut rest = String::new();
        let _ = std::io::Read::read_to_string(&mut stderr, &mut rest);
        rest
    });
    let stream = std::net::TcpStream::connect(&addr).unwrap();
    stream
        .set_read_timeout(Some(std::time::Duration::from_millis(200)))
        .unwrap();
    let (mut ws, _) =
        tungstenite::client::client(format!("ws://{addr}/ws").as_str(), stream).unwrap();
    let mut frames = 0usize;
    loop {
        match ws.read() {
            Ok(tungstenite::Message::Binary(_)) => frames += 1,
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                if child.try_wait().unwrap().is_some() {
                    break;
                }
            }
            Err(_) => break,
        }
    }
    let status = child.wait().unwrap();
    let rest = drain.join().unwrap();
    assert!(status.success(), "track --console failed: {rest}");
    // 2.5 s at 3 live frames per camera per second: about 15, if the machine keeps up.
    assert!(frames >= 4, "{frames} live frames received");
    let with_console = std::fs::read(&out).unwrap();
    let plain: Vec<String> = (0..2)
        .map(|c| format!("sim://exp3?camera={c}&frames={LIVE_FRAMES}&seed=1"))
        .collect();
    let without = track(&calib, &plain, &t.join("plain.csv"));
    // A real-time run writes each camera's rows as soon as they are measured, so the cameras'
    // rows of one frame set may come in another order: the rows are compared as sets.
    let sorted = |bytes: &[u8]| {
        let mut lines: Vec<String> = String::from_utf8_lossy(bytes)
            .lines()
            .map(str::to_string)
            .collect();
        lines.sort();
        lines
    };
    let (a, b) = (sorted(&with_console), sorted(&without));
    assert_eq!(a.len(), 1 + LIVE_FRAMES * (7 + 7 + 8));
    assert!(
        a == b,
        "measurements with the console's live view differ from those without"
    );
}
