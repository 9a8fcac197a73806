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
    let rec = t.join("rec").display().to_string();
    run_ok(&[
        "simulate",
        "--scenario",
        "exp3",
        "--frames",
        "20",
        "--out",
        &rec,
    ]);
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
