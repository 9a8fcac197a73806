//! Measurement sinks: CSV, JSON Lines, UDP, in memory, and several at once.
//!
//! Writers flush when asked, when dropped, and when a write fails (so that what was written
//! before the failure is on disk). A pipeline calls [`MeasurementSink::write`] once per frame
//! set (all rods of all cameras for one frame).

mod csv;
mod jsonl;
mod udp;

pub use self::csv::{parse_measurements_csv, read_measurements_csv, CsvSink};
pub use jsonl::{parse_measurement_json, read_measurements_jsonl, JsonlSink};
pub use udp::{
    decode_udp_packet, encode_udp_packet, status_code, status_from_code, UdpPacket, UdpSink,
    UDP_CAMERA_FUSED, UDP_DEFAULT_ADDR, UDP_HEADER_BYTES, UDP_MAGIC, UDP_MAX_ROWS, UDP_ROW_BYTES,
    UDP_VERSION,
};

use crate::IoError;
use rodtrack_core::{CameraId, Measurement};
use std::fmt::Write as _;

/// Where measurement rows go.
pub trait MeasurementSink: Send {
    /// Writes rows (a pipeline passes one frame set per call). Non-finite values are written
    /// as 0 with a status that says so ([`Measurement::sanitized`]).
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError>;
    /// Pushes buffered rows to their destination.
    fn flush(&mut self) -> Result<(), IoError>;
}

impl<S: MeasurementSink + ?Sized> MeasurementSink for Box<S> {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        (**self).write(rows)
    }
    fn flush(&mut self) -> Result<(), IoError> {
        (**self).flush()
    }
}

/// Keeps rows in memory (tests, library use).
#[derive(Debug, Default, Clone)]
pub struct VecSink {
    /// The rows written, sanitized.
    pub rows: Vec<Measurement>,
    /// Number of `write` calls.
    pub writes: usize,
}

impl MeasurementSink for VecSink {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        self.rows.extend(rows.iter().map(|r| r.sanitized()));
        self.writes += 1;
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

/// Writes to several sinks; every sink gets every call even when an earlier one fails, and the
/// first error is returned.
#[derive(Default)]
pub struct MultiSink {
    /// The sinks.
    pub sinks: Vec<Box<dyn MeasurementSink>>,
}

impl MultiSink {
    /// An empty set of sinks.
    pub fn new() -> Self {
        MultiSink::default()
    }
    /// Adds a sink.
    pub fn push(&mut self, sink: Box<dyn MeasurementSink>) {
        self.sinks.push(sink);
    }
}

impl MeasurementSink for MultiSink {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        let mut first = Ok(());
        for s in &mut self.sinks {
            if let Err(e) = s.write(rows) {
                if first.is_ok() {
                    first = Err(e);
                }
            }
        }
        first
    }
    fn flush(&mut self) -> Result<(), IoError> {
        let mut first = Ok(());
        for s in &mut self.sinks {
            if let Err(e) = s.flush() {
                if first.is_ok() {
                    first = Err(e);
                }
            }
        }
        first
    }
}

/// Decimal places written per column (CSV and JSON Lines).
pub mod decimals {
    /// `timestamp_s`: nanoseconds.
    pub const TIMESTAMP_S: usize = 9;
    /// `position_mm`.
    pub const POSITION_MM: usize = 4;
    /// `angle_rad`, `angle_unwrapped_rad`.
    pub const ANGLE_RAD: usize = 6;
    /// `velocity_mm_s`.
    pub const VELOCITY_MM_S: usize = 3;
    /// `angular_velocity_rad_s`.
    pub const ANGULAR_VELOCITY_RAD_S: usize = 4;
    /// `quality`.
    pub const QUALITY: usize = 4;
}

/// Appends `v` with `d` decimals, without a minus sign on a value that rounds to zero.
pub(crate) fn push_fixed(out: &mut String, v: f64, d: usize) {
    let start = out.len();
    let _ = write!(out, "{v:.d$}");
    if out[start..].starts_with('-') && out[start + 1..].bytes().all(|b| b == b'0' || b == b'.') {
        out.remove(start);
    }
}

/// The row's numbers formatted as in files, in [`rodtrack_core::measurement::CSV_COLUMNS`]
/// order (after sanitizing), with the camera as its Display and the status as its name.
pub(crate) fn fields(m: &Measurement, out: &mut [String; 11]) {
    use decimals::*;
    let m = m.sanitized();
    for s in out.iter_mut() {
        s.clear();
    }
    let _ = write!(out[0], "{}", m.frame);
    push_fixed(&mut out[1], m.timestamp_s, TIMESTAMP_S);
    let _ = write!(out[2], "{}", m.camera);
    let _ = write!(out[3], "{}", m.rod);
    push_fixed(&mut out[4], m.position_mm, POSITION_MM);
    push_fixed(&mut out[5], m.angle_rad, ANGLE_RAD);
    push_fixed(&mut out[6], m.angle_unwrapped_rad, ANGLE_RAD);
    push_fixed(&mut out[7], m.velocity_mm_s, VELOCITY_MM_S);
    push_fixed(
        &mut out[8],
        m.angular_velocity_rad_s,
        ANGULAR_VELOCITY_RAD_S,
    );
    push_fixed(&mut out[9], m.quality, QUALITY);
    out[10].push_str(m.status.name());
}

/// Parses a camera column: a camera index or `fused`.
pub(crate) fn parse_camera(s: &str) -> Option<CameraId> {
    if s == "fused" {
        Some(CameraId::Fused)
    } else {
        s.parse().ok().map(CameraId::Camera)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_has_no_negative_zero() {
        let mut s = String::new();
        push_fixed(&mut s, -0.00001, 4);
        assert_eq!(s, "0.0000");
        s.clear();
        push_fixed(&mut s, -1.26, 1);
        assert_eq!(s, "-1.3");
        s.clear();
        push_fixed(&mut s, -0.0, 2);
        assert_eq!(s, "0.00");
    }
}
