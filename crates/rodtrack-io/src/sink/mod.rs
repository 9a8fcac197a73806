//! Measurement sinks: CSV, JSON Lines, UDP, in memory, and several at once.
//!
//! Writers flush when asked, when dropped, and when a write fails (so that what was written
//! before the failure is on disk). A pipeline calls [`MeasurementSink::write`] once per frame
//! set (all rods of all cameras for one frame), or, with
//! [`crate::runtime::WriteMode::PerCamera`], once per camera frame as soon as it is measured
//! and once more for the set's fused rows.

mod ball;
mod csv;
mod events;
mod fan_out;
mod jsonl;
mod udp;
mod udp_ball;
mod udp_events;

pub use self::csv::{parse_measurements_csv, read_measurements_csv, CsvSink};
pub use ball::{BallCsvSink, BallJsonlSink, BallSink, BallVecSink};
pub use events::{parse_event_json, read_events_jsonl, EventJsonlSink, EventSink, EventVecSink};
pub(crate) use fan_out::first_error;
pub use fan_out::{BallMultiSink, EventMultiSink, FanOut, MultiSink};
pub use jsonl::{parse_measurement_json, read_measurements_jsonl, JsonlSink};
pub use udp::{
    decode_udp_packet, encode_udp_packet, push_row_motion, status_code, status_from_code,
    UdpPacket, UdpSink, UDP_CAMERA_FUSED, UDP_DEFAULT_ADDR, UDP_FLAG_TURNS_KNOWN, UDP_HEADER_BYTES,
    UDP_MAGIC, UDP_MAX_ROWS, UDP_ROW_BYTES, UDP_VERSION,
};
pub use udp_ball::{
    decode_udp_ball, encode_udp_ball, UdpBallPacket, UdpBallSink, UDP_BALL_HEADER_BYTES,
    UDP_BALL_MAGIC, UDP_BALL_ROW_BYTES, UDP_BALL_VERSION, UDP_MAX_BALL_ROWS,
};
pub use udp_events::{
    decode_udp_events, encode_udp_events, UdpEventPacket, UdpEventSink, UDP_EVENTS_HEADER_BYTES,
    UDP_EVENTS_MAGIC, UDP_EVENTS_VERSION, UDP_EVENT_BYTES, UDP_MAX_EVENTS,
};

use crate::IoError;
#[cfg(test)]
use rodtrack_core::Status;
use rodtrack_core::{CameraId, Measurement};
use std::fmt::Write as _;

/// Where measurement rows go.
pub trait MeasurementSink: Send {
    /// Writes rows (a pipeline passes one frame set, or one camera's frame, per call).
    /// Non-finite values are written as 0 with a status that says so
    /// ([`Measurement::sanitized`]).
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
///
/// The text is `format!("{v:.d$}")`'s (the exact value of `v` correctly rounded, ties to
/// even); finite values below 2^53 with at most 9 decimals (every column's) are formatted by
/// exact integer arithmetic, several times faster, the others through `format!`.
pub(crate) fn push_fixed(out: &mut String, v: f64, d: usize) {
    if push_fixed_exact(out, v, d) {
        return;
    }
    let start = out.len();
    let _ = write!(out, "{v:.d$}");
    if out[start..].starts_with('-') && out[start + 1..].bytes().all(|b| b == b'0' || b == b'.') {
        out.remove(start);
    }
}

const POW10: [u64; 10] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
    1_000_000_000,
];

/// [`push_fixed`] by exact arithmetic: `v = m 2^e` exactly, so `v 10^d = m 10^d 2^e` is an
/// exact integer (`m 10^d < 2^83`) shifted right by `-e`, rounded half to even on the exact
/// remainder. False (nothing written) outside its range.
fn push_fixed_exact(out: &mut String, v: f64, d: usize) -> bool {
    let Some(&scale) = POW10.get(d) else {
        return false;
    };
    // 2^53: below it the exponent `e` is at most 0.
    if !v.is_finite() || v.abs() >= 9_007_199_254_740_992.0 {
        return false;
    }
    let bits = v.to_bits();
    let negative = bits >> 63 == 1;
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1u64 << 52) - 1);
    let (m, e) = if biased == 0 {
        (fraction, -1074)
    } else {
        (fraction | (1u64 << 52), biased - 1075)
    };
    let p = u128::from(m) * u128::from(scale);
    let n: u128 = if e >= 0 {
        p << e
    } else {
        let s = e.unsigned_abs();
        if s >= 128 {
            // v 10^d < 2^83 / 2^128: rounds to 0, far from a tie.
            0
        } else {
            let q = p >> s;
            let r = p & ((1u128 << s) - 1);
            let half = 1u128 << (s - 1);
            if r > half || (r == half && q & 1 == 1) {
                q + 1
            } else {
                q
            }
        }
    };
    if negative && n != 0 {
        out.push('-');
    }
    let scale = u128::from(scale);
    let _ = write!(out, "{}", n / scale);
    if d > 0 {
        out.push('.');
        let mut f = n % scale;
        let mut digits = [b'0'; 9];
        for k in (0..d).rev() {
            digits[k] = b'0' + (f % 10) as u8;
            f /= 10;
        }
        for &b in &digits[..d] {
            out.push(char::from(b));
        }
    }
    true
}

/// Appends one CSV line (with its `\n`): [`fields`] joined by commas, without the
/// intermediate strings.
pub(crate) fn push_csv_row(out: &mut String, m: &Measurement) {
    use decimals::*;
    let m = m.sanitized();
    let _ = write!(out, "{},", m.frame);
    push_fixed(out, m.timestamp_s(), TIMESTAMP_S);
    let _ = write!(out, ",{},{},", m.camera, m.rod);
    for (v, decimals) in [
        (m.position_mm, POSITION_MM),
        (m.angle_rad, ANGLE_RAD),
        (m.angle_unwrapped_rad, ANGLE_RAD),
        (m.velocity_mm_s, VELOCITY_MM_S),
        (m.angular_velocity_rad_s, ANGULAR_VELOCITY_RAD_S),
        (m.quality, QUALITY),
    ] {
        push_fixed(out, v, decimals);
        out.push(',');
    }
    out.push_str(m.status.name());
    out.push_str(if m.turns_known { ",true\n" } else { ",false\n" });
}

/// The row's numbers formatted as in files, in [`rodtrack_core::measurement::OUTPUT_COLUMNS`]
/// order (after sanitizing), with the camera as its Display, the status as its name and
/// `turns_known` as `true` or `false`.
pub(crate) fn fields(m: &Measurement, out: &mut [String; 12]) {
    use decimals::*;
    let m = m.sanitized();
    for s in out.iter_mut() {
        s.clear();
    }
    let _ = write!(out[0], "{}", m.frame);
    push_fixed(&mut out[1], m.timestamp_s(), TIMESTAMP_S);
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
    out[11].push_str(if m.turns_known { "true" } else { "false" });
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

    /// `push_fixed` as it was: `format!` and the minus sign removed on zero.
    fn reference(v: f64, d: usize) -> String {
        let mut s = format!("{v:.d$}");
        if s.starts_with('-') && s[1..].bytes().all(|b| b == b'0' || b == b'.') {
            s.remove(0);
        }
        s
    }

    fn check(v: f64, d: usize) {
        let mut s = String::new();
        push_fixed(&mut s, v, d);
        assert_eq!(
            s,
            reference(v, d),
            "{v:e} ({:#x}) with {d} decimals",
            v.to_bits()
        );
    }

    #[test]
    fn fixed_matches_format_on_ties_and_edges() {
        for d in 0..=10 {
            for v in [
                0.0,
                -0.0,
                0.5,
                1.5,
                2.5,
                -2.5,
                0.125,
                0.375,
                -0.625,
                1.0625,
                0.25,
                0.35,
                0.45,
                1e-9,
                5e-10,
                -5e-10,
                4.9999999e-10,
                1.23456789e-5,
                123456.789,
                9.5,
                10.5,
                f64::MIN_POSITIVE,
                5e-324,
                -5e-324,
                4503599627370495.5,
                4503599627370496.5,
                9007199254740991.0,
                9007199254740992.0,
                1e16,
                -1e300,
                0.1,
                0.2,
                0.3,
                2.675,
                1.005,
                1.0005,
                999.99995,
                0.99999995,
                -0.00005,
                0.00005,
                std::f64::consts::TAU,
            ] {
                check(v, d);
            }
            // Every exact tie k / 2^j with few bits: ties to even must agree.
            for j in 1..=12 {
                for k in -300i32..300 {
                    check(f64::from(k) / f64::from(1u32 << j), d);
                }
            }
        }
    }

    #[test]
    fn fixed_matches_format_on_random_values() {
        // xorshift: random bit patterns (all magnitudes) and decimal-looking values (near ties).
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for _ in 0..200_000 {
            let bits = next();
            let v = f64::from_bits(bits);
            let d = (next() % 10) as usize;
            if v.is_finite() {
                check(v, d);
            }
            let scaled = (next() % 2_000_000_000) as f64 - 1e9;
            let v = scaled / POW10[(next() % 10) as usize] as f64;
            check(v, d);
            // Magnitudes of the columns: mm, rad, s, mm/s.
            let v = (f64::from_bits(0x3ff0_0000_0000_0000 | (next() >> 12)) - 1.5)
                * [1e-3, 1.0, 300.0, 5e4][(next() % 4) as usize];
            check(v, d);
        }
    }

    #[test]
    fn csv_row_is_the_fields_joined() {
        let mut fs: [String; 12] = Default::default();
        let mut line = String::new();
        for (k, status) in [Status::Ok, Status::Occluded, Status::BadFrame]
            .into_iter()
            .enumerate()
        {
            let mut m = Measurement::empty(
                1234 + k as u64,
                rodtrack_core::Timestamp::from_secs_f64(6.17 + k as f64),
                if k == 1 {
                    CameraId::Fused
                } else {
                    CameraId::Camera(1)
                },
                3,
                status,
            );
            m.position_mm = -12.345_65;
            m.angle_rad = std::f64::consts::FRAC_PI_2;
            m.angle_unwrapped_rad = -7.853_981_633_974_483;
            m.velocity_mm_s = if k == 2 { f64::NAN } else { 1234.5678 };
            m.angular_velocity_rad_s = -0.000_01;
            m.quality = 0.95;
            fields(&m, &mut fs);
            line.clear();
            push_csv_row(&mut line, &m);
            assert_eq!(line, fs.join(",") + "\n");
        }
    }

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
