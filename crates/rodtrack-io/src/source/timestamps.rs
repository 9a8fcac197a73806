//! The `timestamps.csv` sidecar (`frame,timestamp_s`) and bounded reads of small text files.

use crate::IoError;
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

/// The largest sidecar read (64 MiB: about two million frames).
pub const MAX_SIDECAR_BYTES: u64 = 64 << 20;

/// The latest capture time accepted, seconds (about the year 2286 on a Unix-epoch clock; a
/// nanosecond counter in a `u64` ends at 1.8e10 s).
pub use rodtrack_core::time::MAX_TIMESTAMP_S;

/// Reads a whole file of at most `max` bytes; refuses a path that is not a regular file
/// (without opening it) and a longer file (without reading it).
pub fn read_capped(path: &Path, max: u64) -> Result<Vec<u8>, IoError> {
    let mut out = Vec::new();
    read_capped_into(path, max, &mut out)?;
    Ok(out)
}

/// [`read_capped`] into a buffer the caller keeps (cleared first; left empty on error).
pub fn read_capped_into(path: &Path, max: u64, out: &mut Vec<u8>) -> Result<(), IoError> {
    out.clear();
    if let Some(kind) = super::naming::not_a_regular_file(path) {
        return Err(IoError::NotAFile {
            path: path.to_path_buf(),
            kind,
        });
    }
    let f = std::fs::File::open(path).map_err(|e| IoError::file(path, "cannot open", e))?;
    let len = f
        .metadata()
        .map_err(|e| IoError::file(path, "cannot read", e))?
        .len();
    if len > max {
        return Err(IoError::FileTooLarge {
            path: path.to_path_buf(),
            len,
            max,
        });
    }
    out.reserve(len as usize);
    // The file may grow meanwhile: never read more than the cap.
    f.take(max + 1)
        .read_to_end(out)
        .map_err(|e| IoError::file(path, "cannot read", e))?;
    if out.len() as u64 > max {
        let len = out.len() as u64;
        out.clear();
        return Err(IoError::FileTooLarge {
            path: path.to_path_buf(),
            len,
            max,
        });
    }
    Ok(())
}

/// Reads a timestamps sidecar (see [`parse_timestamps_csv`]); warnings are dropped.
pub fn read_timestamps_csv(path: &Path) -> Result<HashMap<u64, f64>, IoError> {
    read_timestamps_csv_noting(path, &mut Vec::new())
}

/// Reads a timestamps sidecar (at most [`MAX_SIDECAR_BYTES`]); see [`parse_timestamps_csv`].
pub fn read_timestamps_csv_noting(
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<HashMap<u64, f64>, IoError> {
    let bytes = read_capped(path, MAX_SIDECAR_BYTES)?;
    let text = String::from_utf8(bytes).map_err(|e| IoError::Parse {
        path: path.to_path_buf(),
        line: 0,
        column: "timestamp_s".into(),
        reason: format!("not UTF-8 text: {e}"),
    })?;
    parse_timestamps_csv(path, &text, warnings)
}

/// Parses a timestamps sidecar: CSV with columns `frame,timestamp_s` (a header line is
/// optional; other columns after these two are ignored). Returns frame id -> seconds.
///
/// Refuses, naming `path` and the line, what cannot be a capture clock: a time that is not
/// finite, negative or after [`MAX_TIMESTAMP_S`]; a frame listed twice; a time earlier than
/// the previous frame's (in frame id order); every time equal (with more than one frame).
/// Equal times of consecutive frames are a warning.
pub fn parse_timestamps_csv(
    path: &Path,
    text: &str,
    warnings: &mut Vec<String>,
) -> Result<HashMap<u64, f64>, IoError> {
    let err = |line: usize, column: &str, reason: String| IoError::Parse {
        path: path.to_path_buf(),
        line,
        column: column.into(),
        reason,
    };
    // (frame, time, line)
    let mut entries: Vec<(u64, f64, usize)> = Vec::new();
    let mut frame_col = 0usize;
    let mut time_col = 1usize;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if i == 0 && fields.iter().any(|f| f.parse::<f64>().is_err()) {
            // Header: find the columns by name.
            let find = |name: &str| fields.iter().position(|f| *f == name);
            match (find("frame"), find("timestamp_s")) {
                (Some(f), Some(t)) => {
                    frame_col = f;
                    time_col = t;
                }
                _ => {
                    let shown: String = line.chars().take(80).collect();
                    return Err(err(
                        1,
                        "header",
                        format!("expected columns `frame,timestamp_s`, got `{shown}`"),
                    ));
                }
            }
            continue;
        }
        let get = |col: usize, name: &str| -> Result<&str, IoError> {
            fields
                .get(col)
                .copied()
                .ok_or_else(|| err(i + 1, name, "missing value".into()))
        };
        let frame_s = get(frame_col, "frame")?;
        let shown = |s: &str| s.chars().take(40).collect::<String>();
        let frame: u64 = frame_s.parse().map_err(|_| {
            err(
                i + 1,
                "frame",
                format!("`{}` is not a frame number", shown(frame_s)),
            )
        })?;
        let t_s = get(time_col, "timestamp_s")?;
        let t: f64 = t_s
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite() && *t >= 0.0 && *t <= MAX_TIMESTAMP_S)
            .ok_or_else(|| {
                err(
                    i + 1,
                    "timestamp_s",
                    format!(
                        "`{}` is not a capture time in seconds (finite, 0 to {MAX_TIMESTAMP_S:e})",
                        shown(t_s)
                    ),
                )
            })?;
        entries.push((frame, t, i + 1));
    }
    entries.sort_by_key(|e| e.0);
    let mut equal = 0usize;
    for w in entries.windows(2) {
        let ((f0, t0, l0), (f1, t1, l1)) = (w[0], w[1]);
        if f0 == f1 {
            return Err(err(
                l1,
                "frame",
                format!("frame {f1} is listed twice (also on line {l0})"),
            ));
        }
        if t1 < t0 {
            return Err(err(
                l1,
                "timestamp_s",
                format!(
                    "frame {f1} at {t1} s is earlier than frame {f0} at {t0} s (line {l0}): \
                     not a capture clock"
                ),
            ));
        }
        if t1 == t0 {
            equal += 1;
        }
    }
    if entries.len() > 1 && equal == entries.len() - 1 {
        return Err(err(
            entries[0].2,
            "timestamp_s",
            format!(
                "all {} frames have the same time ({} s): not a capture clock",
                entries.len(),
                entries[0].1
            ),
        ));
    }
    if equal > 0 {
        warnings.push(format!(
            "{}: {equal} frame(s) have the same time as the frame before",
            path.display()
        ));
    }
    Ok(entries.into_iter().map(|(f, t, _)| (f, t)).collect())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn parse(text: &str) -> Result<(HashMap<u64, f64>, Vec<String>), String> {
        let mut w = Vec::new();
        parse_timestamps_csv(Path::new("t.csv"), text, &mut w)
            .map(|m| (m, w))
            .map_err(|e| e.to_string())
    }

    #[test]
    fn a_capture_clock_is_read() {
        let (m, w) = parse("frame,timestamp_s\n0,0.0\n1,0.005\n2,0.005\n3,0.015\n").unwrap();
        assert_eq!(m.len(), 4);
        assert_eq!(m[&3], 0.015);
        assert_eq!(w.len(), 1, "{w:?}");
    }

    #[test]
    fn what_cannot_be_a_capture_clock_is_refused_with_file_and_line() {
        let e = parse("frame,timestamp_s\n0,0.01\n1,0.02\n2,0.015\n").unwrap_err();
        assert!(e.contains("t.csv: line 4") && e.contains("earlier"), "{e}");
        let e = parse("frame,timestamp_s\n0,1\n1,1\n2,1\n").unwrap_err();
        assert!(
            e.contains("t.csv: line 2") && e.contains("same time"),
            "{e}"
        );
        let e = parse("frame,timestamp_s\n0,0\n1,1e300\n").unwrap_err();
        assert!(e.contains("line 3") && e.contains("1e300"), "{e}");
        let e = parse("0,0\n0,1\n").unwrap_err();
        assert!(e.contains("line 2") && e.contains("twice"), "{e}");
    }
}
