//! The outputs of a session: files (CSV, JSON Lines, standard output) and the UDP stream,
//! opened before any file is truncated.
//!
//! ```no_run
//! use rodtrack_sdk::{check_out_is_not_an_input, open_sinks, RowFormat};
//! let out = std::path::Path::new("rows.jsonl");
//! check_out_is_not_an_input(out, &["table.toml".as_ref()])?;
//! let sink = open_sinks(out, RowFormat::from_path(out), None)?;
//! # Ok::<(), rodtrack_sdk::SdkError>(())
//! ```

use crate::SdkError;
use rodtrack_io::{CsvSink, IoError, JsonlSink, MultiSink, UdpSink};
use std::path::Path;

/// The file format of the rows.
///
/// ```
/// use rodtrack_sdk::RowFormat;
/// assert_eq!(RowFormat::from_path("rows.jsonl".as_ref()), RowFormat::Jsonl);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RowFormat {
    /// Comma-separated values with a header line.
    Csv,
    /// One JSON object per line.
    Jsonl,
}

impl RowFormat {
    /// The format of `out` from its extension: `.jsonl` and `.json` are JSON Lines, the rest
    /// CSV.
    ///
    /// ```
    /// use rodtrack_sdk::RowFormat;
    /// assert_eq!(RowFormat::from_path("rows.json".as_ref()), RowFormat::Jsonl);
    /// assert_eq!(RowFormat::from_path("rows.csv".as_ref()), RowFormat::Csv);
    /// assert_eq!(RowFormat::from_path("-".as_ref()), RowFormat::Csv);
    /// ```
    pub fn from_path(out: &Path) -> RowFormat {
        if out.extension().is_some_and(|e| e == "jsonl" || e == "json") {
            RowFormat::Jsonl
        } else {
            RowFormat::Csv
        }
    }
}

/// Opens the file sink (`-`: standard output) and the UDP sink. The UDP address is checked
/// (and its socket opened) first: the output file is created, truncating an existing one,
/// only when every other sink is open.
///
/// ```no_run
/// use rodtrack_sdk::{open_sinks, RowFormat};
/// let sink = open_sinks("rows.csv".as_ref(), RowFormat::Csv, Some("127.0.0.1:9870"))?;
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn open_sinks(out: &Path, format: RowFormat, udp: Option<&str>) -> Result<MultiSink, SdkError> {
    let io = |source: IoError| SdkError::Io {
        context: "opening the outputs".into(),
        source,
    };
    let udp = udp.map(UdpSink::new).transpose().map_err(io)?;
    let mut sink = MultiSink::new();
    let jsonl = format == RowFormat::Jsonl;
    if out.as_os_str() == "-" {
        let stdout = std::io::stdout();
        if jsonl {
            sink.push(Box::new(JsonlSink::new(stdout, "standard output")));
        } else {
            sink.push(Box::new(
                CsvSink::new(stdout, "standard output").map_err(io)?,
            ));
        }
    } else if jsonl {
        sink.push(Box::new(JsonlSink::create(out).map_err(io)?));
    } else {
        sink.push(Box::new(CsvSink::create(out).map_err(io)?));
    }
    if let Some(u) = udp {
        sink.push(Box::new(u));
    }
    Ok(sink)
}

/// Refuses an output path that is one of the run's own input files (the calibration, ...):
/// it would be truncated before being read.
///
/// ```
/// use rodtrack_sdk::check_out_is_not_an_input;
/// let dir = std::env::temp_dir().join(format!("rodtrack-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let cal = dir.join("table.toml");
/// std::fs::write(&cal, "").unwrap();
/// assert!(check_out_is_not_an_input(&cal, &[&cal]).is_err());
/// assert!(check_out_is_not_an_input(&dir.join("rows.csv"), &[&cal]).is_ok());
/// assert!(check_out_is_not_an_input("-".as_ref(), &[&cal]).is_ok());
/// std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn check_out_is_not_an_input(out: &Path, inputs: &[&Path]) -> Result<(), SdkError> {
    if out.as_os_str() == "-" {
        return Ok(());
    }
    let Ok(o) = out.canonicalize() else {
        return Ok(()); // Does not exist yet: not an input.
    };
    for i in inputs {
        if i.canonicalize().is_ok_and(|c| c == o) {
            return Err(SdkError::Invalid(format!(
                "--out {} is the input file {}: refusing to overwrite it",
                out.display(),
                i.display()
            )));
        }
    }
    Ok(())
}

/// True when `e` is a write to a pipe whose reader has gone.
///
/// ```
/// use rodtrack_io::IoError;
/// let write_error = |kind| IoError::File {
///     path: "-".into(),
///     action: "cannot write",
///     source: std::io::Error::from(kind),
/// };
/// assert!(rodtrack_sdk::is_broken_pipe(&write_error(std::io::ErrorKind::BrokenPipe)));
/// assert!(!rodtrack_sdk::is_broken_pipe(&write_error(std::io::ErrorKind::StorageFull)));
/// ```
pub fn is_broken_pipe(e: &IoError) -> bool {
    let mut cur: Option<&(dyn std::error::Error + 'static)> = Some(e);
    while let Some(err) = cur {
        if let Some(io) = err.downcast_ref::<std::io::Error>() {
            if io.kind() == std::io::ErrorKind::BrokenPipe {
                return true;
            }
        }
        cur = err.source();
    }
    false
}
