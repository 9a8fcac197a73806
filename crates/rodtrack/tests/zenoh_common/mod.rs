//! What the camera network's tests share: the binary, a scratch folder, a simulated two-camera
//! calibration, free ports and the system clock.
#![allow(dead_code, clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub const BIN: &str = env!("CARGO_BIN_EXE_rodtrack");

pub fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

pub fn run_ok(args: &[&str]) {
    let out = Command::new(BIN).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "rodtrack {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A simulated table (exp3) and its two-camera calibration.
pub fn calibration(t: &Path) -> PathBuf {
    calibration_of(t, "exp3", &["--frames", "20"])
}

/// A simulated table (`scenario`, with `simulate`'s options `extra`) and its two-camera
/// calibration.
pub fn calibration_of(t: &Path, scenario: &str, extra: &[&str]) -> PathBuf {
    let rec = t.join("rec").display().to_string();
    let mut args = vec!["simulate", "--scenario", scenario, "--out", &rec];
    args.extend_from_slice(extra);
    run_ok(&args);
    let calib = t.join("c.toml");
    run_ok(&[
        "calibrate",
        "--inputs",
        &format!("{rec}/cam0.json"),
        "--inputs",
        &format!("{rec}/cam1.json"),
        "--out",
        &calib.display().to_string(),
    ]);
    calib
}

/// Camera nodes of cameras 0 and 1 (`--camera cam<k>`, input `input(k)`) publishing on zenoh
/// and connected to `port`, with the options `extra`; stderr in `t/cam<k>.err`.
pub fn camera_nodes(
    t: &Path,
    calib: &str,
    port: u16,
    input: impl Fn(u32) -> String,
    extra: &[&str],
) -> Vec<Proc> {
    (0..2u32)
        .map(|cam| {
            let mut args: Vec<String> = [
                "track",
                "--calib",
                calib,
                "--camera",
                &format!("cam{cam}"),
                "--input",
                &input(cam),
                "--publish",
                "zenoh",
                "--zenoh-connect",
                &format!("tcp/127.0.0.1:{port}"),
            ]
            .map(String::from)
            .to_vec();
            args.extend(extra.iter().map(|s| s.to_string()));
            Proc::start(&args, t.join(format!("cam{cam}.err")))
        })
        .collect()
}

/// Waits for every camera node to end by itself (at most `limit` each), gives the fusion node
/// half a second for the last messages, then stops it (Ctrl-C): its log.
pub fn end_run(nodes: &mut [Proc], fusion: &mut Proc, limit: Duration) -> String {
    for n in nodes.iter_mut() {
        n.wait(limit);
    }
    std::thread::sleep(Duration::from_millis(500));
    fusion.interrupt(Duration::from_secs(10))
}

/// A zenoh session of the test's own on `tcp/127.0.0.1:<port>`, multicast scouting off:
/// `mode` `connect` or `listen`.
pub fn test_session(mode: &str, port: u16) -> rodtrack_zenoh::zenoh::Session {
    use rodtrack_zenoh::zenoh::{self, Wait};
    let mut config = zenoh::Config::default();
    config
        .insert_json5(
            &format!("{mode}/endpoints"),
            &format!("[\"tcp/127.0.0.1:{port}\"]"),
        )
        .unwrap();
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    zenoh::open(config).wait().unwrap()
}

/// The messages on `key` as text, as they come.
pub fn collect_text(
    session: &rodtrack_zenoh::zenoh::Session,
    key: &str,
) -> std::sync::Arc<std::sync::Mutex<Vec<String>>> {
    use rodtrack_zenoh::zenoh::Wait;
    let seen: std::sync::Arc<std::sync::Mutex<Vec<String>>> = Default::default();
    let s = seen.clone();
    session
        .declare_subscriber(key)
        .callback(move |sample| {
            let text = String::from_utf8(sample.payload().to_bytes().to_vec()).unwrap();
            s.lock().unwrap().push(text);
        })
        .background()
        .wait()
        .unwrap();
    seen
}

pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

pub fn unix_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as u64
}

/// A `rodtrack` process whose stderr goes to a file, killed when dropped (a failed test
/// leaves none behind).
pub struct Proc {
    child: Option<Child>,
    stderr: PathBuf,
}

impl Proc {
    pub fn start(args: &[String], stderr: PathBuf) -> Proc {
        let child = Command::new(BIN)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&stderr).unwrap())
            .spawn()
            .unwrap();
        Proc {
            child: Some(child),
            stderr,
        }
    }
    /// Whether it has ended (or was waited for).
    pub fn ended(&mut self) -> bool {
        self.child
            .as_mut()
            .is_none_or(|c| c.try_wait().unwrap().is_some())
    }
    pub fn pid(&self) -> u32 {
        self.child.as_ref().unwrap().id()
    }
    /// Ctrl-C, then waits (at most `limit`) for a clean end.
    pub fn interrupt(&mut self, limit: Duration) -> String {
        let st = Command::new("kill")
            .args(["-INT", &self.pid().to_string()])
            .status()
            .unwrap();
        assert!(st.success());
        self.wait(limit)
    }
    /// Waits (at most `limit`) for the process to end by itself; it must succeed.
    pub fn wait(&mut self, limit: Duration) -> String {
        let mut child = self.child.take().unwrap();
        let until = Instant::now() + limit;
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if Instant::now() > until {
                let _ = child.kill();
                let _ = child.wait();
                panic!(
                    "a rodtrack process did not end within {limit:?}:\n{}",
                    self.log()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let log = self.log();
        assert!(status.success(), "rodtrack ended with {status}:\n{log}");
        log
    }
    /// Kills it at once (SIGKILL: a crash, nothing sent at the end).
    pub fn kill(&mut self) {
        let mut c = self.child.take().unwrap();
        c.kill().unwrap();
        c.wait().unwrap();
    }
    pub fn log(&self) -> String {
        std::fs::read_to_string(&self.stderr).unwrap_or_default()
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
