//! Helpers shared by the tests and the speed example: temporary folders, frame patterns and
//! encoding with the `ffmpeg` command-line tool (Debian package `ffmpeg`).

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// A temporary folder removed on drop (also when a test fails).
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// A new empty folder named after `name` and the process id.
    pub fn new(name: &str) -> TempDir {
        let p = std::env::temp_dir().join(format!("rodtrack-video-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).expect("create temporary folder");
        TempDir(p)
    }
    /// A path inside the folder.
    pub fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `n` frames of `w` x `h` 8-bit samples: a moving gradient plus a hash, so that every frame
/// and pixel differ (hard for a lossy codec, exact for a lossless one).
pub fn noisy_frames(w: usize, h: usize, n: usize) -> Vec<Vec<u8>> {
    (0..n)
        .map(|k| {
            (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    let hash =
                        (x.wrapping_mul(7919) ^ y.wrapping_mul(104_729) ^ k.wrapping_mul(31))
                            .wrapping_mul(2_654_435_761)
                            >> 13;
                    ((x * 3 + y * 5 + k * 7 + (hash & 0x3f)) & 0xff) as u8
                })
                .collect()
        })
        .collect()
}

/// `n` smooth frames (a moving blurred bar on a gradient): what a camera sees, compressible.
pub fn smooth_frames(w: usize, h: usize, n: usize) -> Vec<Vec<u8>> {
    (0..n)
        .map(|k| {
            (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    let bar = (x as f64 - (10.0 + 2.0 * k as f64)).abs();
                    let v =
                        40.0 + 100.0 * y as f64 / h as f64 + if bar < 6.0 { 100.0 } else { 0.0 };
                    v.round().clamp(0.0, 255.0) as u8
                })
                .collect()
        })
        .collect()
}

/// Whether the `ffmpeg` tool runs.
pub fn have_ffmpeg() -> bool {
    Command::new("ffmpeg")
        .arg("-version")
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
}

/// Panics with a clear message when `ffmpeg` is missing (the `video` feature's tests need it).
pub fn require_ffmpeg() {
    assert!(
        have_ffmpeg(),
        "the `ffmpeg` command-line tool is missing: apt-get install ffmpeg (see .ci/video.sh)"
    );
}

/// Writes `frames` (each `w * h * bytes_per_pixel` bytes of `in_pix_fmt`) as raw video and
/// encodes them with `ffmpeg`, `args` being the output options, into `out`.
pub fn encode(
    frames: &[Vec<u8>],
    w: usize,
    h: usize,
    in_pix_fmt: &str,
    fps: u32,
    args: &[&str],
    out: &Path,
) {
    let raw = out.with_extension("input.raw");
    std::fs::write(&raw, frames.concat()).expect("write raw frames");
    let status = Command::new("ffmpeg")
        .args([
            "-y",
            "-hide_banner",
            "-loglevel",
            "error",
            "-f",
            "rawvideo",
            "-pix_fmt",
        ])
        .arg(in_pix_fmt)
        .args([
            "-s",
            &format!("{w}x{h}"),
            "-framerate",
            &fps.to_string(),
            "-i",
        ])
        .arg(&raw)
        .args(args)
        .arg(out)
        .status()
        .expect("run ffmpeg");
    let _ = std::fs::remove_file(&raw);
    assert!(
        status.success(),
        "ffmpeg {args:?} -> {} failed",
        out.display()
    );
}
