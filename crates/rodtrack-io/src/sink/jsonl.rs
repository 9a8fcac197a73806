//! JSON Lines measurement files: one object per row with the CSV column names, e.g.
//! `{"frame":12,"timestamp_s":0.060000000,"camera":0,"rod":3,"position_mm":-12.5000,
//! "angle_rad":1.570796,"angle_unwrapped_rad":7.853982,"velocity_mm_s":0.000,
//! "angular_velocity_rad_s":0.0000,"quality":0.9500,"status":"ok","turns_known":true}`.
//! `camera` is a number (`0`, `1`, like `rod`) for a camera's rows and the string `"fused"`
//! for fused rows (the reader accepts a camera index as a string too). `turns_known` is a
//! boolean; the reader takes a row without it (a file written before it existed) as `true`.

use super::csv::TextOut;
use super::{fields, parse_camera, MeasurementSink};
use crate::IoError;
use rodtrack_core::measurement::OUTPUT_COLUMNS;
use rodtrack_core::time::{Timestamp, MAX_TIMESTAMP_S};
use rodtrack_core::{Measurement, Status};
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes measurement rows as JSON Lines; flushing as [`super::CsvSink`].
pub struct JsonlSink<W: Write + Send = File> {
    out: TextOut<W>,
    line: String,
    fields: [String; 12],
    flush_each_write: bool,
}

impl JsonlSink<File> {
    /// Creates (truncates) a JSON Lines file.
    pub fn create(path: &Path) -> Result<Self, IoError> {
        let f = File::create(path).map_err(|e| IoError::file(path, "cannot create", e))?;
        Ok(JsonlSink::new(f, path))
    }
}

impl<W: Write + Send> JsonlSink<W> {
    /// Writes JSON Lines to `writer`; `name` is used in error messages.
    pub fn new(writer: W, name: impl Into<PathBuf>) -> Self {
        JsonlSink {
            out: TextOut::new(writer, name.into()),
            line: String::with_capacity(320),
            fields: Default::default(),
            flush_each_write: true,
        }
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

impl<W: Write + Send> MeasurementSink for JsonlSink<W> {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        for m in rows {
            fields(m, &mut self.fields);
            self.line.clear();
            self.line.push('{');
            for (i, (name, value)) in OUTPUT_COLUMNS.iter().zip(&self.fields).enumerate() {
                if i > 0 {
                    self.line.push(',');
                }
                self.line.push('"');
                self.line.push_str(name);
                self.line.push_str("\":");
                // `camera`: a number for a camera's rows, the string "fused" for fused rows.
                let quoted = *name == "status" || (*name == "camera" && value == "fused");
                if quoted {
                    self.line.push('"');
                }
                self.line.push_str(value);
                if quoted {
                    self.line.push('"');
                }
            }
            self.line.push_str("}\n");
            self.out.write_all(self.line.as_bytes())?;
        }
        if self.flush_each_write {
            self.out.flush()?;
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.out.flush()
    }
}

/// Parses one JSON Lines object (`camera` as string or number); `path` and `line` are used in
/// error messages. Returns the row and its optional `visible` field.
pub fn parse_measurement_json(
    text: &str,
    path: &Path,
    line: usize,
) -> Result<(Measurement, Option<bool>), IoError> {
    let err = |column: &str, reason: String| IoError::Parse {
        path: path.to_path_buf(),
        line,
        column: column.to_string(),
        reason,
    };
    let v: serde_json::Value =
        serde_json::from_str(text).map_err(|e| err("(row)", e.to_string()))?;
    let obj = v
        .as_object()
        .ok_or_else(|| err("(row)", "not a JSON object".into()))?;
    let get = |k: &str| obj.get(k).ok_or_else(|| err(k, "missing".into()));
    let num = |k: &str| -> Result<f64, IoError> {
        get(k)?
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| err(k, "not a finite number".into()))
    };
    let time = |k: &str| -> Result<Timestamp, IoError> {
        get(k)?
            .as_f64()
            .and_then(Timestamp::try_from_secs_f64)
            .ok_or_else(|| {
                err(
                    k,
                    format!("not a time in seconds (finite, 0 to {MAX_TIMESTAMP_S:e})"),
                )
            })
    };
    let uint = |k: &str| -> Result<u64, IoError> {
        get(k)?
            .as_u64()
            .ok_or_else(|| err(k, "not an unsigned integer".into()))
    };
    let camera = match get("camera")? {
        serde_json::Value::String(s) => parse_camera(s),
        serde_json::Value::Number(n) => n
            .as_u64()
            .and_then(|n| u32::try_from(n).ok())
            .map(rodtrack_core::CameraId::Camera),
        _ => None,
    }
    .ok_or_else(|| err("camera", "not a camera index or \"fused\"".into()))?;
    let status = get("status")?
        .as_str()
        .and_then(Status::from_name)
        .ok_or_else(|| err("status", "not a status name".into()))?;
    let rod = u32::try_from(uint("rod")?).map_err(|_| err("rod", "too large".into()))?;
    let visible = match obj.get("visible") {
        None | Some(serde_json::Value::Null) => None,
        Some(serde_json::Value::Bool(b)) => Some(*b),
        Some(_) => return Err(err("visible", "not a boolean".into())),
    };
    let turns_known = match obj.get("turns_known") {
        None | Some(serde_json::Value::Null) => true,
        Some(serde_json::Value::Bool(b)) => *b,
        Some(_) => return Err(err("turns_known", "not a boolean".into())),
    };
    Ok((
        Measurement {
            frame: uint("frame")?,
            timestamp_ns: time("timestamp_s")?,
            camera,
            rod,
            position_mm: num("position_mm")?,
            angle_rad: num("angle_rad")?,
            angle_unwrapped_rad: num("angle_unwrapped_rad")?,
            velocity_mm_s: num("velocity_mm_s")?,
            angular_velocity_rad_s: num("angular_velocity_rad_s")?,
            quality: num("quality")?,
            status,
            turns_known,
        },
        visible,
    ))
}

/// Reads a JSON Lines measurement file (blank lines skipped).
pub fn read_measurements_jsonl(path: &Path) -> Result<Vec<(Measurement, Option<bool>)>, IoError> {
    let text = std::fs::read_to_string(path).map_err(|e| IoError::file(path, "cannot read", e))?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| parse_measurement_json(l, path, i + 1))
        .collect()
}
