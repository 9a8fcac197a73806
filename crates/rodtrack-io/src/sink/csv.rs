//! CSV measurement files: writer and reader.
//!
//! Format: a header line exactly [`CSV_COLUMNS`] and [`TURNS_KNOWN_COLUMN`] joined by commas,
//! then one line per row; `camera` is a camera index or `fused`, `status` a status name,
//! `turns_known` `true` or `false`; numbers in fixed notation with the decimals of
//! [`super::decimals`]; `\n` line ends. The reader also accepts files without the
//! `turns_known` column (written before it existed: read as `true`), extra columns (a
//! `visible` column of `true`/`false`/`1`/`0` is returned, others are ignored), columns in
//! any order, and `\r\n` line ends.

use super::{parse_camera, push_csv_row, MeasurementSink};
use crate::IoError;
use rodtrack_core::measurement::{CSV_COLUMNS, OUTPUT_COLUMNS, TURNS_KNOWN_COLUMN};
use rodtrack_core::time::{Timestamp, MAX_TIMESTAMP_S};
use rodtrack_core::{Measurement, Status};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// A buffered writer that flushes on drop, with the name used in error messages.
pub(crate) struct TextOut<W: Write> {
    out: Option<BufWriter<W>>,
    pub(crate) name: PathBuf,
}

impl<W: Write> TextOut<W> {
    pub(crate) fn new(w: W, name: PathBuf) -> Self {
        TextOut {
            out: Some(BufWriter::new(w)),
            name,
        }
    }
    /// Writes; on failure flushes what it can and names the file.
    pub(crate) fn write_all(&mut self, bytes: &[u8]) -> Result<(), IoError> {
        let Some(out) = self.out.as_mut() else {
            return Ok(());
        };
        out.write_all(bytes).map_err(|e| {
            let _ = out.flush();
            IoError::file(&self.name, "cannot write", e)
        })
    }
    pub(crate) fn flush(&mut self) -> Result<(), IoError> {
        match self.out.as_mut() {
            Some(out) => out
                .flush()
                .map_err(|e| IoError::file(&self.name, "cannot write", e)),
            None => Ok(()),
        }
    }
    pub(crate) fn into_inner(mut self) -> Result<W, IoError> {
        let name = self.name.clone();
        match self.out.take() {
            Some(out) => out
                .into_inner()
                .map_err(|e| IoError::file(name, "cannot write", e.into_error())),
            None => Err(IoError::file(
                name,
                "cannot write",
                std::io::Error::other("writer already taken"),
            )),
        }
    }
}

impl<W: Write> Drop for TextOut<W> {
    fn drop(&mut self) {
        if let Some(out) = self.out.as_mut() {
            let _ = out.flush();
        }
    }
}

/// Writes measurement rows as CSV.
///
/// By default every `write` call is flushed to the writer (one system call per frame set), so
/// that a crash loses nothing already written; [`CsvSink::set_flush_each_write`] turns this off
/// for offline runs. Flushes on drop and after a failed write.
pub struct CsvSink<W: Write + Send = File> {
    out: TextOut<W>,
    line: String,
    flush_each_write: bool,
}

impl CsvSink<File> {
    /// Creates (truncates) a CSV file and writes the header.
    pub fn create(path: &Path) -> Result<Self, IoError> {
        let f = File::create(path).map_err(|e| IoError::file(path, "cannot create", e))?;
        CsvSink::new(f, path)
    }
}

impl<W: Write + Send> CsvSink<W> {
    /// Writes CSV to `writer`; `name` is used in error messages. Writes the header now.
    pub fn new(writer: W, name: impl Into<PathBuf>) -> Result<Self, IoError> {
        let mut s = CsvSink {
            out: TextOut::new(writer, name.into()),
            line: String::with_capacity(4096),
            flush_each_write: true,
        };
        let header = OUTPUT_COLUMNS.join(",") + "\n";
        s.out.write_all(header.as_bytes())?;
        s.out.flush()?;
        Ok(s)
    }

    /// Whether each `write` call is flushed (default true).
    pub fn set_flush_each_write(&mut self, on: bool) {
        self.flush_each_write = on;
    }

    /// Flushes and returns the writer.
    pub fn into_inner(self) -> Result<W, IoError> {
        self.out.into_inner()
    }
}

impl<W: Write + Send> MeasurementSink for CsvSink<W> {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        // All rows formatted first, then one copy into the writer.
        self.line.clear();
        for m in rows {
            push_csv_row(&mut self.line, m);
        }
        self.out.write_all(self.line.as_bytes())?;
        if self.flush_each_write {
            self.out.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), IoError> {
        self.out.flush()
    }
}

/// Reads a measurement or ground-truth CSV file (see the module documentation).
pub fn read_measurements_csv(path: &Path) -> Result<Vec<(Measurement, Option<bool>)>, IoError> {
    let text = std::fs::read_to_string(path).map_err(|e| IoError::file(path, "cannot read", e))?;
    parse_measurements_csv(&text, path)
}

fn parse_bool(s: &str) -> Option<bool> {
    match s {
        "true" | "1" | "True" | "TRUE" => Some(true),
        "false" | "0" | "False" | "FALSE" => Some(false),
        _ => None,
    }
}

/// Parses CSV text; `path` is only used in error messages.
pub fn parse_measurements_csv(
    text: &str,
    path: &Path,
) -> Result<Vec<(Measurement, Option<bool>)>, IoError> {
    let err = |line: usize, column: &str, reason: String| IoError::Parse {
        path: path.to_path_buf(),
        line,
        column: column.to_string(),
        reason,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((hline, header)) = lines.next() else {
        return Err(err(
            1,
            "header",
            "empty file (expected a header line)".into(),
        ));
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut idx = [0usize; 11];
    for (k, col) in CSV_COLUMNS.iter().enumerate() {
        idx[k] = names.iter().position(|n| n == col).ok_or_else(|| {
            err(
                hline + 1,
                col,
                format!(
                    "missing column (header must have: {})",
                    CSV_COLUMNS.join(",")
                ),
            )
        })?;
    }
    let visible_idx = names.iter().position(|n| *n == "visible");
    let turns_idx = names.iter().position(|n| *n == TURNS_KNOWN_COLUMN);
    let mut rows = Vec::new();
    for (i, line) in lines {
        let ln = i + 1;
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != names.len() {
            return Err(err(
                ln,
                "(row)",
                format!("{} fields, header has {}", f.len(), names.len()),
            ));
        }
        let num = |k: usize| -> Result<f64, IoError> {
            let s = f[idx[k]];
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| err(ln, CSV_COLUMNS[k], format!("`{s}` is not a finite number")))
        };
        let time = |k: usize| -> Result<Timestamp, IoError> {
            let s = f[idx[k]];
            s.parse::<f64>()
                .ok()
                .and_then(Timestamp::try_from_secs_f64)
                .ok_or_else(|| {
                    err(
                        ln,
                        CSV_COLUMNS[k],
                        format!(
                            "`{s}` is not a time in seconds (finite, 0 to {MAX_TIMESTAMP_S:e})"
                        ),
                    )
                })
        };
        let frame = f[idx[0]].parse::<u64>().map_err(|_| {
            err(
                ln,
                "frame",
                format!("`{}` is not a frame number", f[idx[0]]),
            )
        })?;
        let camera = parse_camera(f[idx[2]]).ok_or_else(|| {
            err(
                ln,
                "camera",
                format!("`{}` is not a camera index or `fused`", f[idx[2]]),
            )
        })?;
        let rod = f[idx[3]]
            .parse::<u32>()
            .map_err(|_| err(ln, "rod", format!("`{}` is not a rod id", f[idx[3]])))?;
        let status = Status::from_name(f[idx[10]]).ok_or_else(|| {
            err(
                ln,
                "status",
                format!("`{}` is not a status name", f[idx[10]]),
            )
        })?;
        let m = Measurement {
            frame,
            timestamp_ns: time(1)?,
            camera,
            rod,
            position_mm: num(4)?,
            angle_rad: num(5)?,
            angle_unwrapped_rad: num(6)?,
            velocity_mm_s: num(7)?,
            angular_velocity_rad_s: num(8)?,
            quality: num(9)?,
            status,
            turns_known: match turns_idx {
                None => true,
                Some(k) => parse_bool(f[k]).ok_or_else(|| {
                    err(
                        ln,
                        TURNS_KNOWN_COLUMN,
                        format!("`{}` is not true/false/1/0", f[k]),
                    )
                })?,
            },
        };
        let visible =
            match visible_idx {
                None => None,
                Some(v) => Some(parse_bool(f[v]).ok_or_else(|| {
                    err(ln, "visible", format!("`{}` is not true/false/1/0", f[v]))
                })?),
            };
        rows.push((m, visible));
    }
    Ok(rows)
}
