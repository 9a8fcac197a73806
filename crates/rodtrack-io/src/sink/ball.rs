//! Ball sinks: where [`BallRow`]s go (CSV file, memory).

use crate::IoError;
use rodtrack_core::ball::BallRow;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Where ball rows go.
pub trait BallSink: Send {
    /// Writes rows (in frame order, cameras in index order within a frame).
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError>;
    /// Pushes buffered rows to their destination.
    fn flush(&mut self) -> Result<(), IoError>;
}

/// Ball rows as CSV: [`BallRow::CSV_HEADER`], one [`BallRow::csv_line`] per row.
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
    out: BufWriter<W>,
    name: PathBuf,
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
            out: BufWriter::new(writer),
            name: name.into(),
            line: String::with_capacity(128),
        };
        writeln!(s.out, "{}", BallRow::CSV_HEADER)
            .map_err(|e| IoError::file(&s.name, "cannot write", e))?;
        Ok(s)
    }

    /// Flushes and returns the writer.
    pub fn into_inner(self) -> Result<W, IoError> {
        let name = self.name;
        self.out
            .into_inner()
            .map_err(|e| IoError::file(&name, "cannot write", e.into_error()))
    }
}

impl<W: Write + Send> BallSink for BallCsvSink<W> {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        for r in rows {
            self.line.clear();
            self.line.push_str(&r.sanitized().csv_line());
            self.line.push('\n');
            self.out
                .write_all(self.line.as_bytes())
                .map_err(|e| IoError::file(&self.name, "cannot write", e))?;
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.out
            .flush()
            .map_err(|e| IoError::file(&self.name, "cannot write", e))
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
    fn flush(&mut self) -> Result<(), IoError> {
        (**self).flush()
    }
}
