//! Ball sinks: where [`BallRow`]s go (CSV file, memory).

use super::csv::TextOut;
use crate::IoError;
use rodtrack_core::ball::BallRow;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Where ball rows go.
pub trait BallSink: Send {
    /// Writes rows (in frame order, cameras in index order within a frame).
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError>;
    /// Writes rows with each row's position standard deviation per axis, mm
    /// ([`rodtrack_core::ball::BallTracker::row_sigma_mm`]; infinite for a `lost` row, NaN
    /// where not known, as for `fused` rows): what fusing cameras elsewhere weighs them by.
    /// A sink that does not carry it writes the rows alone (the default).
    fn write_sigma(&mut self, rows: &[BallRow], sigma_mm: &[f64]) -> Result<(), IoError> {
        let _ = sigma_mm;
        self.write(rows)
    }
    /// Pushes buffered rows to their destination.
    fn flush(&mut self) -> Result<(), IoError>;
}

/// Ball rows as CSV: [`BallRow::CSV_HEADER`], one [`BallRow::csv_line`] per row. Each `write`
/// is flushed to the writer, as [`crate::CsvSink`] does by default: a crash loses nothing
/// already written.
///
/// ```
/// use rodtrack_core::ball::{BallRow, BallStatus};
/// use rodtrack_io::{BallCsvSink, BallSink};
/// let mut sink = BallCsvSink::new(Vec::new(), "ball.csv")?;
/// let row = BallRow {
///     frame: 3,
///     timestamp_ns: rodtrack_core::Timestamp(15_000_000),
///     camera: rodtrack_core::CameraId::Camera(1),
///     x_mm: 10.0, y_mm: -5.0, vx_mm_s: 0.0, vy_mm_s: 0.0, quality: 1.0,
///     status: BallStatus::Ok,
/// };
/// sink.write(&[row])?;
/// let text = String::from_utf8(sink.into_inner()?).unwrap();
/// assert_eq!(text.lines().nth(1), Some("3,0.015000,1,10.000,-5.000,0.0,0.0,1.000,ok"));
/// # Ok::<(), rodtrack_io::IoError>(())
/// ```
pub struct BallCsvSink<W: Write + Send> {
    out: TextOut<W>,
    line: String,
}

impl BallCsvSink<File> {
    /// Creates (truncates) a CSV file and writes the header.
    pub fn create(path: &Path) -> Result<Self, IoError> {
        let f = File::create(path).map_err(|e| IoError::file(path, "cannot create", e))?;
        BallCsvSink::new(f, path)
    }
}

impl<W: Write + Send> BallCsvSink<W> {
    /// CSV into `writer`; `name` names it in errors. Writes the header now.
    pub fn new(writer: W, name: impl Into<PathBuf>) -> Result<Self, IoError> {
        let mut s = BallCsvSink {
            out: TextOut::new(writer, name.into()),
            line: String::with_capacity(1024),
        };
        s.out.write_all(BallRow::CSV_HEADER.as_bytes())?;
        s.out.write_all(b"\n")?;
        s.out.flush()?;
        Ok(s)
    }

    /// Flushes and returns the writer.
    pub fn into_inner(self) -> Result<W, IoError> {
        self.out.into_inner()
    }
}

impl<W: Write + Send> BallSink for BallCsvSink<W> {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        // All rows formatted first, then one copy into the writer and one flush.
        self.line.clear();
        for r in rows {
            r.sanitized().push_csv(&mut self.line);
            self.line.push('\n');
        }
        self.out.write_all(self.line.as_bytes())?;
        self.out.flush()
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.out.flush()
    }
}

/// Ball rows as JSON Lines: one [`BallRow::push_json`] object per line, the CSV's columns.
/// Each `write` is flushed to the writer: a crash loses nothing already written.
///
/// ```
/// use rodtrack_core::ball::{BallRow, BallStatus};
/// use rodtrack_io::{BallJsonlSink, BallSink};
/// let mut sink = BallJsonlSink::new(Vec::new(), "ball.jsonl");
/// let mut row = BallRow::lost(3, rodtrack_core::Timestamp(15_000_000), rodtrack_core::CameraId::Fused);
/// row.x_mm = 10.0;
/// row.status = BallStatus::Predicted;
/// sink.write(&[row])?;
/// let text = String::from_utf8(sink.into_inner()?).unwrap();
/// assert_eq!(
///     text,
///     "{\"frame\":3,\"timestamp_s\":0.015000,\"camera\":\"fused\",\"x_mm\":10.000,\"y_mm\":0.000,\"vx_mm_s\":0.0,\"vy_mm_s\":0.0,\"quality\":0.000,\"status\":\"predicted\"}\n"
/// );
/// # Ok::<(), rodtrack_io::IoError>(())
/// ```
pub struct BallJsonlSink<W: Write + Send> {
    out: TextOut<W>,
    line: String,
}

impl BallJsonlSink<File> {
    /// Creates (truncates) a JSON Lines file.
    pub fn create(path: &Path) -> Result<Self, IoError> {
        let f = File::create(path).map_err(|e| IoError::file(path, "cannot create", e))?;
        Ok(BallJsonlSink::new(f, path))
    }
}

impl<W: Write + Send> BallJsonlSink<W> {
    /// JSON Lines into `writer`; `name` names it in errors.
    pub fn new(writer: W, name: impl Into<PathBuf>) -> Self {
        BallJsonlSink {
            out: TextOut::new(writer, name.into()),
            line: String::with_capacity(1024),
        }
    }

    /// Flushes and returns the writer.
    pub fn into_inner(self) -> Result<W, IoError> {
        self.out.into_inner()
    }
}

impl<W: Write + Send> BallSink for BallJsonlSink<W> {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        self.line.clear();
        for r in rows {
            r.sanitized().push_json(&mut self.line);
            self.line.push('\n');
        }
        self.out.write_all(self.line.as_bytes())?;
        self.out.flush()
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.out.flush()
    }
}

/// Ball rows kept in memory, shared with its clones (give one to a session, read the other).
///
/// ```
/// use rodtrack_io::{BallSink, BallVecSink};
/// let sink = BallVecSink::default();
/// let mut writer = sink.clone();
/// writer.flush()?;
/// assert!(sink.rows().is_empty());
/// # Ok::<(), rodtrack_io::IoError>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct BallVecSink {
    rows: Arc<Mutex<Vec<BallRow>>>,
}

impl BallVecSink {
    /// A copy of the rows written so far.
    pub fn rows(&self) -> Vec<BallRow> {
        self.rows.lock().map(|r| r.clone()).unwrap_or_default()
    }
}

impl BallSink for BallVecSink {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        if let Ok(mut v) = self.rows.lock() {
            v.extend(rows.iter().map(|r| r.sanitized()));
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

impl<S: BallSink + ?Sized> BallSink for Box<S> {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        (**self).write(rows)
    }
    fn write_sigma(&mut self, rows: &[BallRow], sigma_mm: &[f64]) -> Result<(), IoError> {
        (**self).write_sigma(rows, sigma_mm)
    }
    fn flush(&mut self) -> Result<(), IoError> {
        (**self).flush()
    }
}
