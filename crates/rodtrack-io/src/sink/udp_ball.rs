//! The ball's rows in the UDP stream: datagrams of their own, magic `RTBL`, beside the rods'
//! `RTRK` datagrams (and the events' `RTEV`) on the same address. A receiver of rows checks the
//! magic and skips them (the rows' decoder, [`super::decode_udp_packet`], refuses them as a bad
//! magic).
//!
//! One datagram per `write` call (a frame set's rows: each camera's, then the fused one), sent
//! before `write` returns. Layout (version 1), little endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `RTBL` (bytes `52 54 42 4C`) |
//! | 4 | 2 | version, u16 = 1 |
//! | 6 | 2 | row count `n`, u16 |
//! | 8 | 4 | sequence number, u32 (per sink, +1 per datagram, wraps) |
//! | 12 | 4 | reserved, 0 |
//! | 16 | 64 x n | rows |
//!
//! Each row (64 bytes):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | frame id, u64 |
//! | 8 | 8 | timestamp, u64 nanoseconds (capture) |
//! | 16 | 4 | camera, u32 (`0xFFFF_FFFF` = fused) |
//! | 20 | 1 | status code: 0 ok, 1 predicted, 2 lost, 3 conflict |
//! | 21 | 3 | reserved, 0 |
//! | 24 | 8 | x_mm, f64 (table frame) |
//! | 32 | 8 | y_mm, f64 |
//! | 40 | 8 | vx_mm_s, f64 |
//! | 48 | 8 | vy_mm_s, f64 |
//! | 56 | 4 | quality, f32 |
//! | 60 | 4 | reserved, 0 |
//!
//! Non-finite numbers are written as 0 (as in the CSV: [`BallRow::sanitized`]).

use super::ball::BallSink;
use super::udp::{le, Datagrams, UDP_CAMERA_FUSED};
use crate::IoError;
use rodtrack_core::ball::{BallRow, BallStatus};
use rodtrack_core::{CameraId, Timestamp};

/// The ball datagram's magic.
pub const UDP_BALL_MAGIC: [u8; 4] = *b"RTBL";
/// The ball datagram's layout version.
pub const UDP_BALL_VERSION: u16 = 1;
/// Its header size, bytes.
pub const UDP_BALL_HEADER_BYTES: usize = 16;
/// One ball row's size, bytes.
pub const UDP_BALL_ROW_BYTES: usize = 64;
/// Most ball rows in one datagram (65507-byte UDP payload limit).
pub const UDP_MAX_BALL_ROWS: usize = (65_507 - UDP_BALL_HEADER_BYTES) / UDP_BALL_ROW_BYTES;

const BALL_STATUSES: [BallStatus; 4] = [
    BallStatus::Ok,
    BallStatus::Predicted,
    BallStatus::Lost,
    BallStatus::Conflict,
];

/// One decoded ball datagram.
#[derive(Debug, Clone, PartialEq)]
pub struct UdpBallPacket {
    /// Layout version.
    pub version: u16,
    /// Sequence number.
    pub seq: u32,
    /// The rows.
    pub rows: Vec<BallRow>,
}

/// Encodes `rows` into `out` (cleared first). Fails on more than [`UDP_MAX_BALL_ROWS`] rows.
pub fn encode_udp_ball(seq: u32, rows: &[BallRow], out: &mut Vec<u8>) -> Result<(), IoError> {
    if rows.len() > UDP_MAX_BALL_ROWS {
        return Err(IoError::Packet(format!(
            "{} ball rows in one write, at most {UDP_MAX_BALL_ROWS} fit a datagram",
            rows.len()
        )));
    }
    out.clear();
    out.extend_from_slice(&UDP_BALL_MAGIC);
    out.extend_from_slice(&UDP_BALL_VERSION.to_le_bytes());
    out.extend_from_slice(&(rows.len() as u16).to_le_bytes());
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    for r in rows {
        let r = r.sanitized();
        let camera = match r.camera {
            CameraId::Camera(c) => c,
            CameraId::Fused => UDP_CAMERA_FUSED,
        };
        let status = BALL_STATUSES
            .iter()
            .position(|s| *s == r.status)
            .unwrap_or(0) as u8;
        out.extend_from_slice(&r.frame.to_le_bytes());
        out.extend_from_slice(&r.timestamp_ns.as_nanos().to_le_bytes());
        out.extend_from_slice(&camera.to_le_bytes());
        out.extend_from_slice(&[status, 0, 0, 0]);
        for v in [r.x_mm, r.y_mm, r.vx_mm_s, r.vy_mm_s] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&(r.quality as f32).to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
    }
    Ok(())
}

/// Decodes a ball datagram written by [`encode_udp_ball`].
pub fn decode_udp_ball(b: &[u8]) -> Result<UdpBallPacket, IoError> {
    if b.len() < UDP_BALL_HEADER_BYTES {
        return Err(IoError::Packet(format!(
            "{} bytes, shorter than the {UDP_BALL_HEADER_BYTES}-byte ball header",
            b.len()
        )));
    }
    if b[0..4] != UDP_BALL_MAGIC {
        return Err(IoError::Packet("bad magic (expected RTBL)".into()));
    }
    let version = u16::from_le_bytes(le(b, 4));
    if version != UDP_BALL_VERSION {
        return Err(IoError::Packet(format!(
            "ball version {version}, this decoder reads {UDP_BALL_VERSION}"
        )));
    }
    let n = u16::from_le_bytes(le(b, 6)) as usize;
    let need = UDP_BALL_HEADER_BYTES + n * UDP_BALL_ROW_BYTES;
    if b.len() != need {
        return Err(IoError::Packet(format!(
            "{n} ball rows need {need} bytes, got {}",
            b.len()
        )));
    }
    let seq = u32::from_le_bytes(le(b, 8));
    let mut rows = Vec::with_capacity(n);
    for i in 0..n {
        let at = UDP_BALL_HEADER_BYTES + i * UDP_BALL_ROW_BYTES;
        let r = &b[at..at + UDP_BALL_ROW_BYTES];
        let f = |at: usize| f64::from_le_bytes(le(r, at));
        let camera = match u32::from_le_bytes(le(r, 16)) {
            UDP_CAMERA_FUSED => CameraId::Fused,
            c => CameraId::Camera(c),
        };
        let status = *BALL_STATUSES
            .get(usize::from(r[20]))
            .ok_or_else(|| IoError::Packet(format!("ball row {i}: unknown status {}", r[20])))?;
        rows.push(BallRow {
            frame: u64::from_le_bytes(le(r, 0)),
            timestamp_ns: Timestamp(u64::from_le_bytes(le(r, 8))),
            camera,
            x_mm: f(24),
            y_mm: f(32),
            vx_mm_s: f(40),
            vy_mm_s: f(48),
            quality: f64::from(f32::from_le_bytes(le(r, 56))),
            status,
        });
    }
    Ok(UdpBallPacket { version, seq, rows })
}

/// Sends the ball's rows, one datagram per `write` call, to a UDP address (the rows' `--udp`
/// address).
#[derive(Debug)]
pub struct UdpBallSink {
    out: Datagrams,
}

impl UdpBallSink {
    /// Sends to `target` (`host:port`) from an ephemeral local port.
    pub fn new(target: &str) -> Result<Self, IoError> {
        Ok(UdpBallSink {
            out: Datagrams::new(target, UDP_BALL_HEADER_BYTES + 8 * UDP_BALL_ROW_BYTES)?,
        })
    }
}

impl BallSink for UdpBallSink {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        self.out
            .send_chunks(rows, UDP_MAX_BALL_ROWS, encode_udp_ball)
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::UdpSocket;

    fn sample() -> Vec<BallRow> {
        let row = |camera, status, x_mm: f64| BallRow {
            frame: 12,
            timestamp_ns: Timestamp(60_000_000),
            camera,
            x_mm,
            y_mm: -40.125,
            vx_mm_s: 1500.5,
            vy_mm_s: -20.0,
            quality: 0.75,
            status,
        };
        vec![
            row(CameraId::Camera(0), BallStatus::Ok, 100.0625),
            row(CameraId::Camera(1), BallStatus::Predicted, 99.5),
            row(CameraId::Fused, BallStatus::Conflict, 100.25),
        ]
    }

    /// Every field survives the datagram (quality chosen exact in f32); a non-finite number
    /// goes out as 0; the rods' decoder refuses it; a truncated one, a wrong version and an
    /// unknown status are refused.
    #[test]
    fn ball_rows_round_trip_and_row_receivers_skip_them() {
        let rows = sample();
        let mut b = Vec::new();
        encode_udp_ball(7, &rows, &mut b).unwrap();
        assert_eq!(b.len(), UDP_BALL_HEADER_BYTES + 3 * UDP_BALL_ROW_BYTES);
        let p = decode_udp_ball(&b).unwrap();
        assert_eq!((p.version, p.seq), (1, 7));
        assert_eq!(p.rows, rows);
        let err = super::super::decode_udp_packet(&b).unwrap_err();
        assert!(err.to_string().contains("magic"), "{err}");
        assert!(decode_udp_ball(&b[..b.len() - 1]).is_err());
        let mut v2 = b.clone();
        v2[4] = 2;
        assert!(decode_udp_ball(&v2).is_err());
        let mut bad = b.clone();
        bad[UDP_BALL_HEADER_BYTES + 20] = 9;
        assert!(decode_udp_ball(&bad)
            .unwrap_err()
            .to_string()
            .contains("status 9"));
        let mut nan = rows[0];
        nan.x_mm = f64::NAN;
        encode_udp_ball(8, &[nan], &mut b).unwrap();
        let p = decode_udp_ball(&b).unwrap();
        assert!(p.rows[0].x_mm.is_finite());
    }

    /// A sink sends one datagram per write to a local socket, numbered.
    #[test]
    fn the_sink_sends_each_write() {
        let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
        rx.set_read_timeout(Some(std::time::Duration::from_secs(5)))
            .unwrap();
        let mut sink = UdpBallSink::new(&rx.local_addr().unwrap().to_string()).unwrap();
        let rows = sample();
        sink.write(&rows[..1]).unwrap();
        sink.write(&rows[1..]).unwrap();
        let mut buf = [0u8; 2048];
        let n = rx.recv(&mut buf).unwrap();
        let a = decode_udp_ball(&buf[..n]).unwrap();
        let n = rx.recv(&mut buf).unwrap();
        let b = decode_udp_ball(&buf[..n]).unwrap();
        assert_eq!((a.seq, a.rows.len()), (0, 1));
        assert_eq!((b.seq, b.rows.as_slice()), (1, &rows[1..]));
    }
}
