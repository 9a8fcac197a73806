//! Low-latency UDP stream for a control program: one datagram per `write` call and frame id,
//! sent (`send_to` returned) before `write` returns. The runtime writes one frame set per call
//! ([`crate::runtime::WriteMode::Set`], `rodtrack track` by default, live or not), or each
//! camera's rows of a frame as soon as they are measured and then the set's fused rows
//! ([`crate::runtime::WriteMode::PerCamera`], `rodtrack track --write camera`): rows carry
//! their camera, so a receiver can take either.
//!
//! Layout (version 2), all little endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `RTRK` (bytes `52 54 52 4B`) |
//! | 4 | 2 | version, u16 = 2 |
//! | 6 | 2 | row count `n`, u16 |
//! | 8 | 4 | sequence number, u32 (per sink, +1 per datagram, wraps) |
//! | 12 | 4 | reserved, 0 |
//! | 16 | 8 | frame id, u64 |
//! | 24 | 8 | timestamp, u64 nanoseconds (`timestamp_s` of the set's first row) |
//! | 32 | 56 x n | rows |
//!
//! Each row (56 bytes):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | camera, u32 (`0xFFFF_FFFF` = fused) |
//! | 4 | 4 | rod, u32 |
//! | 8 | 8 | position_mm, f64 |
//! | 16 | 8 | angle_rad, f64 |
//! | 24 | 8 | angle_unwrapped_rad, f64 |
//! | 32 | 8 | velocity_mm_s, f64 |
//! | 40 | 8 | angular_velocity_rad_s, f64 |
//! | 48 | 4 | quality, f32 |
//! | 52 | 1 | status code: 0 ok, 1 not_found, 2 occluded, 3 out_of_view, 4 predicted, 5 lost, 6 bad_frame, 7 conflict |
//! | 53 | 1 | flags: bit 0 `turns_known`; the other bits 0 |
//! | 54 | 2 | reserved, 0 |
//!
//! Version 2 added the flags byte (version 1 had 3 reserved bytes there) and status 7; the
//! decoder reads both, a version 1 row as `turns_known = true`.
//!
//! 8 rods x (2 cameras + fused) = 24 rows make 1376 bytes, one Ethernet frame.

use super::{first_error, MeasurementSink};
use crate::IoError;
use rodtrack_core::{CameraId, Measurement, Status};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};

/// Datagram magic.
pub const UDP_MAGIC: [u8; 4] = *b"RTRK";
/// Layout version.
pub const UDP_VERSION: u16 = 2;
/// Bit of a row's flags byte (offset 53): [`Measurement::turns_known`].
pub const UDP_FLAG_TURNS_KNOWN: u8 = 1;
/// Header size, bytes.
pub const UDP_HEADER_BYTES: usize = 32;
/// Row size, bytes.
pub const UDP_ROW_BYTES: usize = 56;
/// Camera value meaning "fused".
pub const UDP_CAMERA_FUSED: u32 = u32::MAX;
/// Most rows in one datagram (65507-byte UDP payload limit).
pub const UDP_MAX_ROWS: usize = (65_507 - UDP_HEADER_BYTES) / UDP_ROW_BYTES;
/// Default destination.
pub const UDP_DEFAULT_ADDR: &str = "127.0.0.1:9870";

const STATUSES: [Status; 8] = [
    Status::Ok,
    Status::NotFound,
    Status::Occluded,
    Status::OutOfView,
    Status::Predicted,
    Status::Lost,
    Status::BadFrame,
    Status::Conflict,
];

/// The status code of the UDP layout.
pub fn status_code(s: Status) -> u8 {
    STATUSES.iter().position(|x| *x == s).unwrap_or(0) as u8
}

/// The status for a UDP status code.
pub fn status_from_code(c: u8) -> Option<Status> {
    STATUSES.get(c as usize).copied()
}

/// One decoded datagram.
#[derive(Debug, Clone, PartialEq)]
pub struct UdpPacket {
    /// Layout version.
    pub version: u16,
    /// Sequence number.
    pub seq: u32,
    /// Frame id of the set.
    pub frame: u64,
    /// Timestamp of the set, ns.
    pub timestamp_ns: u64,
    /// The rows (frame and timestamp taken from the header).
    pub rows: Vec<Measurement>,
}

/// Appends the first 48 bytes of a row that the UDP layout and the network's layout share:
/// camera u32 ([`UDP_CAMERA_FUSED`] for fused), rod u32, then f64 `position_mm`, `angle_rad`,
/// `angle_unwrapped_rad`, `velocity_mm_s`, `angular_velocity_rad_s`, little endian. `r` is
/// expected sanitized.
pub fn push_row_motion(r: &Measurement, out: &mut Vec<u8>) {
    let cam = match r.camera {
        CameraId::Camera(c) => c,
        CameraId::Fused => UDP_CAMERA_FUSED,
    };
    out.extend_from_slice(&cam.to_le_bytes());
    out.extend_from_slice(&r.rod.to_le_bytes());
    for v in [
        r.position_mm,
        r.angle_rad,
        r.angle_unwrapped_rad,
        r.velocity_mm_s,
        r.angular_velocity_rad_s,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// Encodes rows of one frame set into `out` (cleared first). Frame id and timestamp come from
/// the first row. Values are sanitized. Fails on more than [`UDP_MAX_ROWS`] rows.
pub fn encode_udp_packet(seq: u32, rows: &[Measurement], out: &mut Vec<u8>) -> Result<(), IoError> {
    if rows.len() > UDP_MAX_ROWS {
        return Err(IoError::Packet(format!(
            "{} rows in one frame set, at most {UDP_MAX_ROWS} fit a datagram",
            rows.len()
        )));
    }
    out.clear();
    let (frame, ts) = rows
        .first()
        .map(|r| {
            let r = r.sanitized();
            (r.frame, r.timestamp_ns.as_nanos())
        })
        .unwrap_or((0, 0));
    out.extend_from_slice(&UDP_MAGIC);
    out.extend_from_slice(&UDP_VERSION.to_le_bytes());
    out.extend_from_slice(&(rows.len() as u16).to_le_bytes());
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&frame.to_le_bytes());
    out.extend_from_slice(&ts.to_le_bytes());
    for r in rows {
        let r = r.sanitized();
        push_row_motion(&r, out);
        out.extend_from_slice(&(r.quality as f32).to_le_bytes());
        let flags = if r.turns_known {
            UDP_FLAG_TURNS_KNOWN
        } else {
            0
        };
        out.extend_from_slice(&[status_code(r.status), flags, 0, 0]);
    }
    Ok(())
}

/// `N` bytes of `b` at `at` (the caller checked the length).
pub(super) fn le<const N: usize>(b: &[u8], at: usize) -> [u8; N] {
    let mut a = [0u8; N];
    a.copy_from_slice(&b[at..at + N]);
    a
}

/// Decodes a datagram written by [`encode_udp_packet`] (used by tests and clients).
pub fn decode_udp_packet(b: &[u8]) -> Result<UdpPacket, IoError> {
    if b.len() < UDP_HEADER_BYTES {
        return Err(IoError::Packet(format!(
            "{} bytes, shorter than the {UDP_HEADER_BYTES}-byte header",
            b.len()
        )));
    }
    if b[0..4] != UDP_MAGIC {
        return Err(IoError::Packet("bad magic (expected RTRK)".into()));
    }
    let version = u16::from_le_bytes(le(b, 4));
    if version != 1 && version != UDP_VERSION {
        return Err(IoError::Packet(format!(
            "version {version}, this decoder reads 1 to {UDP_VERSION}"
        )));
    }
    let n = u16::from_le_bytes(le(b, 6)) as usize;
    let need = UDP_HEADER_BYTES + n * UDP_ROW_BYTES;
    if b.len() != need {
        return Err(IoError::Packet(format!(
            "{n} rows need {need} bytes, got {}",
            b.len()
        )));
    }
    let seq = u32::from_le_bytes(le(b, 8));
    let frame = u64::from_le_bytes(le(b, 16));
    let timestamp_ns = u64::from_le_bytes(le(b, 24));
    let mut rows = Vec::with_capacity(n);
    for i in 0..n {
        let r =
            &b[UDP_HEADER_BYTES + i * UDP_ROW_BYTES..UDP_HEADER_BYTES + (i + 1) * UDP_ROW_BYTES];
        let cam = u32::from_le_bytes(le(r, 0));
        let f = |at: usize| f64::from_le_bytes(le(r, at));
        let status = status_from_code(r[52])
            .ok_or_else(|| IoError::Packet(format!("row {i}: unknown status code {}", r[52])))?;
        rows.push(Measurement {
            frame,
            timestamp_ns: crate::Timestamp(timestamp_ns),
            camera: if cam == UDP_CAMERA_FUSED {
                CameraId::Fused
            } else {
                CameraId::Camera(cam)
            },
            rod: u32::from_le_bytes(le(r, 4)),
            position_mm: f(8),
            angle_rad: f(16),
            angle_unwrapped_rad: f(24),
            velocity_mm_s: f(32),
            angular_velocity_rad_s: f(40),
            quality: f64::from(f32::from_le_bytes(le(r, 48))),
            status,
            turns_known: version == 1 || r[53] & UDP_FLAG_TURNS_KNOWN != 0,
        });
    }
    Ok(UdpPacket {
        version,
        seq,
        frame,
        timestamp_ns,
        rows,
    })
}

/// A UDP socket on an ephemeral local port of `target`'s address family, and `target`
/// (`host:port`) resolved: what the row and the event senders send from and to.
pub(crate) fn udp_socket_to(target: &str) -> Result<(UdpSocket, SocketAddr), IoError> {
    let net = |e| IoError::Net {
        addr: target.to_string(),
        source: e,
    };
    let addr = target
        .to_socket_addrs()
        .map_err(net)?
        .next()
        .ok_or_else(|| net(std::io::Error::other("address resolves to nothing")))?;
    let local: SocketAddr = if addr.is_ipv4() {
        SocketAddr::from(([0, 0, 0, 0], 0))
    } else {
        SocketAddr::from(([0u16; 8], 0))
    };
    let socket = UdpSocket::bind(local).map_err(net)?;
    Ok((socket, addr))
}

/// Numbered datagrams to one UDP address: what the row, ball and event senders share.
#[derive(Debug)]
pub(crate) struct Datagrams {
    socket: UdpSocket,
    target: SocketAddr,
    seq: u32,
    packet: Vec<u8>,
}

impl Datagrams {
    /// Sends to `target` (`host:port`) from an ephemeral local port; `capacity` bytes of packet
    /// buffer made now.
    pub(crate) fn new(target: &str, capacity: usize) -> Result<Self, IoError> {
        let (socket, target) = udp_socket_to(target)?;
        Ok(Datagrams {
            socket,
            target,
            seq: 0,
            packet: Vec::with_capacity(capacity),
        })
    }

    /// The destination.
    pub(crate) fn target(&self) -> SocketAddr {
        self.target
    }

    /// Sends `items` in chunks of at most `max`, one datagram each, `encode(sequence number,
    /// chunk, packet)` making it (the number +1 per datagram, wrapping). Every chunk is sent
    /// even after an error; the first error is returned.
    pub(crate) fn send_chunks<T>(
        &mut self,
        items: &[T],
        max: usize,
        mut encode: impl FnMut(u32, &[T], &mut Vec<u8>) -> Result<(), IoError>,
    ) -> Result<(), IoError> {
        first_error(items.chunks(max.max(1)).map(|chunk| {
            let sent = encode(self.seq, chunk, &mut self.packet).and_then(|()| {
                self.socket
                    .send_to(&self.packet, self.target)
                    .map(|_| ())
                    .map_err(|e| IoError::Net {
                        addr: self.target.to_string(),
                        source: e,
                    })
            });
            self.seq = self.seq.wrapping_add(1);
            sent
        }))
    }
}

/// Sends one datagram per `write` call (per frame id within it) to a UDP address (default
/// [`UDP_DEFAULT_ADDR`]).
///
/// A `write` call with rows of several frames sends one datagram per run of rows with the same
/// frame id. Nothing is buffered, so `flush` does nothing.
#[derive(Debug)]
pub struct UdpSink {
    out: Datagrams,
}

impl UdpSink {
    /// Sends to `target` (`host:port`) from an ephemeral local port.
    pub fn new(target: &str) -> Result<Self, IoError> {
        Ok(UdpSink {
            out: Datagrams::new(target, 2048)?,
        })
    }

    /// The destination.
    pub fn target(&self) -> SocketAddr {
        self.out.target()
    }
}

impl MeasurementSink for UdpSink {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        first_error(
            rows.chunk_by(|a, b| a.frame == b.frame)
                .map(|group| self.out.send_chunks(group, UDP_MAX_ROWS, encode_udp_packet)),
        )
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}
