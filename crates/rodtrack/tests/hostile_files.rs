//! Hostile frame files (issue "hostile input"): tiny files that claim huge images, a symlink to
//! `/dev/zero`, a 20 GB sparse file, a FIFO. Each sits beside five good frames; the run must
//! end by itself, never abort, report the file, and stay within twice the documented memory
//! budget (`docs/robustness.md`, [`rodtrack_io::runtime::track_memory_budget`]). The peak
//! resident size is read from `/proc/<pid>/status` (`VmHWM`) while the child runs.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use rodtrack_io::runtime::track_memory_budget;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;

mod common;
use common::Fixture;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_rodtrack");
const GOOD: u64 = 5;
/// A run over six frames takes well under a second; a blocked or swapping run is stopped.
const TIMEOUT: Duration = Duration::from_secs(60);

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| common::recording("hostile_files", "sim", "static", GOOD))
}

/// The five good frames of camera 0 in a new folder.
fn folder(name: &str) -> PathBuf {
    let f = fixture();
    let d = f.dir.join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    for e in std::fs::read_dir(f.dir.join("sim").join("cam0")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, d.join(p.file_name().unwrap())).unwrap();
    }
    d
}

struct Run {
    code: Option<i32>,
    stderr: String,
    peak_rss_bytes: u64,
    out: PathBuf,
}

fn vm_hwm_bytes(pid: u32) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Tracks `input` (raw rows) and polls the child's peak resident size until it ends.
fn track(input: &Path, name: &str) -> Run {
    let f = fixture();
    let out = f.dir.join(format!("{name}.csv"));
    let stderr_path = f.dir.join(format!("{name}.stderr"));
    let mut child = Command::new(BIN)
        .args(["track", "--raw", "--calib"])
        .arg(&f.calib)
        .arg("--input")
        .arg(input)
        .arg("--out")
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&stderr_path).unwrap())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let mut peak = 0;
    let status = loop {
        if let Some(h) = vm_hwm_bytes(child.id()) {
            peak = peak.max(h);
        }
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "{name}: still running after {TIMEOUT:?} (peak {} MiB)",
                peak >> 20
            );
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    Run {
        code: status.code(),
        stderr: std::fs::read_to_string(&stderr_path).unwrap(),
        peak_rss_bytes: peak,
        out,
    }
}

/// Frame ids and statuses of the rows.
fn rows(csv: &Path) -> Vec<(u64, String)> {
    let text = std::fs::read_to_string(csv).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].parse().unwrap(), f[10].to_string())
        })
        .collect()
}

/// The budget of one 1440x1080 Bayer camera (the fixture's).
fn budget() -> u64 {
    track_memory_budget(&[(1440, 1080, 1)], 4) as u64
}

/// Runs `make(folder)` then tracks: the run goes on with the good frames, names the file, and
/// stays under twice the budget. `frame5_rows`: whether frame 5 is in the output (bad) or
/// skipped.
fn check(name: &str, make: impl FnOnce(&Path) -> PathBuf, needle: &str, frame5_rows: bool) {
    let d = folder(name);
    let file = make(&d);
    let r = track(&d, name);
    let fname = file.file_name().unwrap().to_string_lossy().into_owned();
    eprintln!(
        "{name}: exit {:?}, peak RSS {:.1} MiB (budget {:.1} MiB)",
        r.code,
        r.peak_rss_bytes as f64 / 1048576.0,
        budget() as f64 / 1048576.0
    );
    assert_eq!(r.code, Some(0), "{name}: the run must go on:\n{}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
    assert!(
        r.stderr.contains(&fname) && r.stderr.contains(needle),
        "{name}: message lacks `{fname}` / `{needle}`:\n{}",
        r.stderr
    );
    assert!(
        r.peak_rss_bytes <= 2 * budget(),
        "{name}: peak RSS {} MiB over twice the budget ({} MiB)",
        r.peak_rss_bytes >> 20,
        budget() >> 20
    );
    let rows = rows(&r.out);
    for id in 0..GOOD {
        assert!(
            rows.iter().any(|(f, s)| *f == id && s == "ok"),
            "{name}: frame {id} has no ok row"
        );
    }
    let bad: Vec<&String> = rows
        .iter()
        .filter(|(f, _)| *f == GOOD)
        .map(|r| &r.1)
        .collect();
    if frame5_rows {
        assert!(!bad.is_empty(), "{name}: frame {GOOD} has no rows");
        assert!(bad.iter().all(|s| *s == "bad_frame"), "{name}: {bad:?}");
    } else {
        assert!(bad.is_empty(), "{name}: a skipped file gave rows: {bad:?}");
    }
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

fn png_chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let mut body = kind.to_vec();
    body.extend_from_slice(data);
    out.extend_from_slice(&body);
    out.extend_from_slice(&crc32(&body).to_be_bytes());
}

/// A small valid-looking PNG whose header claims `w x h` grey 8-bit; its data is a short zlib
/// stream of zeros (the first rows).
fn png_claiming(w: u32, h: u32) -> Vec<u8> {
    let mut p = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    png_chunk(&mut p, b"IHDR", &ihdr);
    // zlib, one stored block of 600 zero bytes.
    let raw = vec![0u8; 600];
    let mut z = vec![0x78, 0x01, 0x01];
    z.extend_from_slice(&(raw.len() as u16).to_le_bytes());
    z.extend_from_slice(&(!(raw.len() as u16)).to_le_bytes());
    z.extend_from_slice(&raw);
    let (mut a, mut b) = (1u32, 0u32);
    for &x in &raw {
        a = (a + u32::from(x)) % 65521;
        b = (b + a) % 65521;
    }
    z.extend_from_slice(&((b << 16) | a).to_be_bytes());
    png_chunk(&mut p, b"IDAT", &z);
    png_chunk(&mut p, b"IEND", &[]);
    p
}

/// A little-endian baseline TIFF whose header claims `w x h` grey 8-bit, one strip.
fn tiff_claiming(w: u32, h: u32) -> Vec<u8> {
    let mut t = b"II*\0".to_vec();
    t.extend_from_slice(&8u32.to_le_bytes());
    let entries: [(u16, u16, u32); 9] = [
        (256, 4, w),   // ImageWidth
        (257, 4, h),   // ImageLength
        (258, 3, 8),   // BitsPerSample
        (259, 3, 1),   // Compression: none
        (262, 3, 1),   // Photometric: black is zero
        (273, 4, 200), // StripOffsets
        (277, 3, 1),   // SamplesPerPixel
        (278, 4, h),   // RowsPerStrip
        (279, 4, 100), // StripByteCounts
    ];
    t.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, kind, value) in entries {
        t.extend_from_slice(&tag.to_le_bytes());
        t.extend_from_slice(&kind.to_le_bytes());
        t.extend_from_slice(&1u32.to_le_bytes());
        if kind == 3 {
            t.extend_from_slice(&(value as u16).to_le_bytes());
            t.extend_from_slice(&[0, 0]);
        } else {
            t.extend_from_slice(&value.to_le_bytes());
        }
    }
    t.extend_from_slice(&0u32.to_le_bytes());
    t.resize(300, 0);
    t
}

#[test]
fn pgm_header_claiming_2e9_squared_does_not_abort() {
    check(
        "pgm_2e9",
        |d| {
            let p = d.join("000005.pgm");
            std::fs::write(&p, b"P5\n2000000000 2000000000\n255\n\0").unwrap();
            p
        },
        "wrong frame size",
        true,
    );
}

#[test]
fn pgm_header_claiming_60000_squared_stays_in_budget() {
    check(
        "pgm_60000",
        |d| {
            let p = d.join("000005.pgm");
            std::fs::write(&p, b"P5\n60000 60000\n255\n\0\0\0\0\0\0").unwrap();
            p
        },
        "wrong frame size",
        true,
    );
}

#[test]
fn png_claiming_65535_squared_stays_in_budget() {
    check(
        "png_65535",
        |d| {
            let p = d.join("000005.png");
            std::fs::write(&p, png_claiming(65535, 65535)).unwrap();
            p
        },
        "wrong frame size",
        true,
    );
}

#[test]
fn tiff_claiming_100000_squared_stays_in_budget() {
    check(
        "tiff_100000",
        |d| {
            let p = d.join("000005.tif");
            std::fs::write(&p, tiff_claiming(100_000, 100_000)).unwrap();
            p
        },
        "wrong frame size",
        true,
    );
}

#[test]
fn sparse_20_gb_file_is_not_read() {
    check(
        "sparse",
        |d| {
            let p = d.join("000005.pgm");
            let f = std::fs::File::create(&p).unwrap();
            f.set_len(20 << 30).unwrap();
            p
        },
        "too large",
        true,
    );
}

#[test]
fn symlink_to_dev_zero_is_skipped() {
    check(
        "dev_zero",
        |d| {
            let p = d.join("000005.png");
            std::os::unix::fs::symlink("/dev/zero", &p).unwrap();
            p
        },
        "not a regular file",
        false,
    );
}

#[test]
fn fifo_is_skipped() {
    check(
        "fifo",
        |d| {
            let p = d.join("000005.png");
            let o = Command::new("mkfifo").arg(&p).output().expect("mkfifo");
            assert!(o.status.success());
            p
        },
        "not a regular file",
        false,
    );
}
