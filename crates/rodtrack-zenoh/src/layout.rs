//! The messages on the network: rows of one camera frame or one fused frame set, in a
//! versioned binary layout (the UDP layout's fields, every value in full precision) or as JSON
//! for scripts. [`decode`] reads both (a binary message starts with `RTZN`, a JSON one with
//! `{`).
//!
//! Binary layout, version 1, little endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `RTZN` (bytes `52 54 5A 4E`) |
//! | 4 | 2 | version, u16 = 1 |
//! | 6 | 1 | kind: 0 camera rows (filtered), 1 camera raw rows (the fusion's input), 2 fused rows, 3 end of a camera's run (no rows) |
//! | 7 | 1 | flags: bit 0 the frame set is complete (every camera present; camera messages: 1) |
//! | 8 | 2 | row count `n`, u16 |
//! | 10 | 2 | reserved, 0 |
//! | 12 | 4 | sequence number, u32 (per publisher, +1 per message, wraps) |
//! | 16 | 8 | frame id, u64 |
//! | 24 | 8 | capture timestamp, u64 ns |
//! | 32 | 8 | cameras present, u64 bit mask (bit `c`: camera index `c`'s frame is in the message's set) |
//! | 40 | 64 x n | rows |
//!
//! Each row, 64 bytes: camera u32 (`0xFFFF_FFFF` = fused) at 0, rod u32 at 4, then f64
//! `position_mm` (8), `angle_rad` (16), `angle_unwrapped_rad` (24), `velocity_mm_s` (32),
//! `angular_velocity_rad_s` (40), `quality` (48), status code u8 (56, the UDP codes), flags u8
//! (57: bit 0 `turns_known`), 6 reserved bytes (0). Every row of a message has the header's
//! frame id and timestamp.

use crate::ZenohError;
use rodtrack_core::{CameraId, Measurement, Status, Timestamp};
use rodtrack_io::sink::{push_row_motion, status_code, status_from_code, UDP_CAMERA_FUSED};

/// Message magic.
pub const MAGIC: [u8; 4] = *b"RTZN";
/// Layout version.
pub const VERSION: u16 = 1;
/// Header size, bytes.
pub const HEADER_BYTES: usize = 40;
/// Row size, bytes.
pub const ROW_BYTES: usize = 64;
/// Header flag: the frame set is complete.
pub const FLAG_COMPLETE: u8 = 1;
/// Row flag: `turns_known`.
pub const ROW_FLAG_TURNS_KNOWN: u8 = 1;
/// Camera value meaning "fused".
pub const CAMERA_FUSED: u32 = UDP_CAMERA_FUSED;
/// Most rows in one message.
pub const MAX_ROWS: usize = u16::MAX as usize;

/// What a message holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A camera's rows through its temporal filter (what `track --out` writes for it).
    CameraRows,
    /// A camera's measured rows before any filter, `bad_frame` rows for a bad frame: the
    /// fusion's input.
    CameraRaw,
    /// The fused rows of a frame set.
    Fused,
    /// A camera node's run ended (no rows): the fusion does not wait for it.
    End,
}

impl Kind {
    fn code(self) -> u8 {
        match self {
            Kind::CameraRows => 0,
            Kind::CameraRaw => 1,
            Kind::Fused => 2,
            Kind::End => 3,
        }
    }
    fn from_code(c: u8) -> Option<Kind> {
        [Kind::CameraRows, Kind::CameraRaw, Kind::Fused, Kind::End]
            .get(c as usize)
            .copied()
    }
    /// The JSON name: `rows`, `raw`, `fused`, `end`.
    pub fn name(self) -> &'static str {
        match self {
            Kind::CameraRows => "rows",
            Kind::CameraRaw => "raw",
            Kind::Fused => "fused",
            Kind::End => "end",
        }
    }
    fn from_name(s: &str) -> Option<Kind> {
        [Kind::CameraRows, Kind::CameraRaw, Kind::Fused, Kind::End]
            .into_iter()
            .find(|k| k.name() == s)
    }
}

/// One message's header fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// What the message holds.
    pub kind: Kind,
    /// Sequence number.
    pub seq: u32,
    /// Frame id.
    pub frame: u64,
    /// Capture timestamp.
    pub timestamp_ns: Timestamp,
    /// Every camera present in the set.
    pub complete: bool,
    /// Bit `c`: camera `c`'s frame is in the set.
    pub cameras: u64,
}

/// A decoded message.
#[derive(Debug, Clone, PartialEq)]
pub struct Message {
    /// Layout version.
    pub version: u16,
    /// The header.
    pub header: Header,
    /// The rows (frame and timestamp from the header).
    pub rows: Vec<Measurement>,
}

/// The bit of `camera` in [`Header::cameras`] (0 for an index over 63).
pub fn camera_bit(camera: u32) -> u64 {
    1u64.checked_shl(camera).unwrap_or(0)
}

/// Encodes `rows` (one frame id and timestamp, those of `header`) into `out`, cleared first.
/// Values are sanitized (no NaN). Fails on more than [`MAX_ROWS`] rows or a row of another
/// frame.
pub fn encode(header: &Header, rows: &[Measurement], out: &mut Vec<u8>) -> Result<(), ZenohError> {
    check_rows(header, rows)?;
    out.clear();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.push(header.kind.code());
    out.push(if header.complete { FLAG_COMPLETE } else { 0 });
    out.extend_from_slice(&(rows.len() as u16).to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    out.extend_from_slice(&header.seq.to_le_bytes());
    out.extend_from_slice(&header.frame.to_le_bytes());
    out.extend_from_slice(&header.timestamp_ns.as_nanos().to_le_bytes());
    out.extend_from_slice(&header.cameras.to_le_bytes());
    for r in rows {
        let r = r.sanitized();
        // The UDP layout's first 48 bytes (its fused camera is ours), then the full quality.
        push_row_motion(&r, out);
        out.extend_from_slice(&r.quality.to_le_bytes());
        let flags = if r.turns_known {
            ROW_FLAG_TURNS_KNOWN
        } else {
            0
        };
        out.extend_from_slice(&[status_code(r.status), flags, 0, 0, 0, 0, 0, 0]);
    }
    Ok(())
}

fn check_rows(header: &Header, rows: &[Measurement]) -> Result<(), ZenohError> {
    if rows.len() > MAX_ROWS {
        return Err(ZenohError::Message(format!(
            "{} rows in one message, at most {MAX_ROWS}",
            rows.len()
        )));
    }
    if let Some(r) = rows
        .iter()
        .find(|r| r.frame != header.frame || r.timestamp_ns != header.timestamp_ns)
    {
        return Err(ZenohError::Message(format!(
            "a row of frame {} ({} ns) in a message of frame {} ({} ns)",
            r.frame,
            r.timestamp_ns.as_nanos(),
            header.frame,
            header.timestamp_ns.as_nanos()
        )));
    }
    Ok(())
}

/// Encodes the message as JSON into `out` (cleared first): `{"version":1,"kind":"fused",
/// "seq":..,"frame":..,"timestamp_ns":..,"complete":true,"cameras":[0,1],"rows":[{..}]}`, each
/// row with the JSON Lines fields (`docs/formats.md`) plus `timestamp_ns`.
pub fn encode_json(
    header: &Header,
    rows: &[Measurement],
    out: &mut Vec<u8>,
) -> Result<(), ZenohError> {
    use std::io::Write;
    check_rows(header, rows)?;
    out.clear();
    let cams: Vec<u32> = (0..64)
        .filter(|c| header.cameras & camera_bit(*c) != 0)
        .collect();
    let w = |e: std::io::Error| ZenohError::Message(e.to_string());
    write!(
        out,
        "{{\"version\":{VERSION},\"kind\":\"{}\",\"seq\":{},\"frame\":{},\"timestamp_ns\":{},\"complete\":{},\"cameras\":{},\"rows\":[",
        header.kind.name(),
        header.seq,
        header.frame,
        header.timestamp_ns.as_nanos(),
        header.complete,
        serde_json::to_string(&cams).map_err(|e| ZenohError::Message(e.to_string()))?
    )
    .map_err(w)?;
    for (i, r) in rows.iter().enumerate() {
        let r = r.sanitized();
        let camera = match r.camera {
            CameraId::Camera(c) => serde_json::Value::from(c),
            CameraId::Fused => serde_json::Value::from("fused"),
        };
        let row = serde_json::json!({
            "frame": r.frame,
            "timestamp_ns": r.timestamp_ns.as_nanos(),
            "camera": camera,
            "rod": r.rod,
            "position_mm": r.position_mm,
            "angle_rad": r.angle_rad,
            "angle_unwrapped_rad": r.angle_unwrapped_rad,
            "velocity_mm_s": r.velocity_mm_s,
            "angular_velocity_rad_s": r.angular_velocity_rad_s,
            "quality": r.quality,
            "status": r.status.name(),
            "turns_known": r.turns_known,
        });
        if i > 0 {
            out.push(b',');
        }
        serde_json::to_writer(&mut *out, &row).map_err(|e| ZenohError::Message(e.to_string()))?;
    }
    out.extend_from_slice(b"]}");
    Ok(())
}

fn le<const N: usize>(b: &[u8], at: usize) -> [u8; N] {
    let mut a = [0u8; N];
    a.copy_from_slice(&b[at..at + N]);
    a
}

/// Decodes a message of either encoding ([`encode`] or [`encode_json`]).
pub fn decode(b: &[u8]) -> Result<Message, ZenohError> {
    match b.first() {
        Some(b'{') => decode_json(b),
        _ => decode_binary(b),
    }
}

fn decode_binary(b: &[u8]) -> Result<Message, ZenohError> {
    let bad = |s: String| Err(ZenohError::Message(s));
    if b.len() < HEADER_BYTES {
        return bad(format!(
            "{} bytes, shorter than the {HEADER_BYTES}-byte header",
            b.len()
        ));
    }
    if b[0..4] != MAGIC {
        return bad("bad magic (expected RTZN or a JSON object)".into());
    }
    let version = u16::from_le_bytes(le(b, 4));
    if version != VERSION {
        return bad(format!("version {version}, this decoder reads {VERSION}"));
    }
    let Some(kind) = Kind::from_code(b[6]) else {
        return bad(format!("unknown kind {}", b[6]));
    };
    let n = u16::from_le_bytes(le(b, 8)) as usize;
    let need = HEADER_BYTES + n * ROW_BYTES;
    if b.len() != need {
        return bad(format!("{n} rows need {need} bytes, got {}", b.len()));
    }
    let header = Header {
        kind,
        seq: u32::from_le_bytes(le(b, 12)),
        frame: u64::from_le_bytes(le(b, 16)),
        timestamp_ns: Timestamp(u64::from_le_bytes(le(b, 24))),
        complete: b[7] & FLAG_COMPLETE != 0,
        cameras: u64::from_le_bytes(le(b, 32)),
    };
    let mut rows = Vec::with_capacity(n);
    for (i, r) in b[HEADER_BYTES..].chunks_exact(ROW_BYTES).enumerate() {
        let cam = u32::from_le_bytes(le(r, 0));
        let f = |at: usize| f64::from_le_bytes(le(r, at));
        let Some(status) = status_from_code(r[56]) else {
            return bad(format!("row {i}: unknown status code {}", r[56]));
        };
        let row = Measurement {
            frame: header.frame,
            timestamp_ns: header.timestamp_ns,
            camera: if cam == CAMERA_FUSED {
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
            quality: f(48),
            status,
            turns_known: r[57] & ROW_FLAG_TURNS_KNOWN != 0,
        };
        if ![
            row.position_mm,
            row.angle_rad,
            row.angle_unwrapped_rad,
            row.velocity_mm_s,
            row.angular_velocity_rad_s,
            row.quality,
        ]
        .iter()
        .all(|v| v.is_finite())
        {
            return bad(format!("row {i}: a value is not a finite number"));
        }
        rows.push(row);
    }
    Ok(Message {
        version,
        header,
        rows,
    })
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonMessage {
    version: u16,
    kind: String,
    seq: u32,
    frame: u64,
    timestamp_ns: u64,
    complete: bool,
    cameras: Vec<u32>,
    rows: Vec<JsonRow>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonRow {
    frame: u64,
    timestamp_ns: u64,
    camera: serde_json::Value,
    rod: u32,
    position_mm: f64,
    angle_rad: f64,
    angle_unwrapped_rad: f64,
    velocity_mm_s: f64,
    angular_velocity_rad_s: f64,
    quality: f64,
    status: String,
    turns_known: bool,
}

fn decode_json(b: &[u8]) -> Result<Message, ZenohError> {
    let bad = |s: String| ZenohError::Message(s);
    let m: JsonMessage = serde_json::from_slice(b).map_err(|e| bad(format!("JSON: {e}")))?;
    if m.version != VERSION {
        return Err(bad(format!(
            "version {}, this decoder reads {VERSION}",
            m.version
        )));
    }
    let kind = Kind::from_name(&m.kind).ok_or_else(|| bad(format!("unknown kind {:?}", m.kind)))?;
    let mut cameras = 0;
    for c in m.cameras {
        cameras |= camera_bit(c);
    }
    let mut rows = Vec::with_capacity(m.rows.len());
    for (i, r) in m.rows.into_iter().enumerate() {
        let camera =
            match &r.camera {
                serde_json::Value::String(s) if s == "fused" => CameraId::Fused,
                v => CameraId::Camera(v.as_u64().and_then(|c| u32::try_from(c).ok()).ok_or_else(
                    || bad(format!("row {i}: camera {v} is not an index or \"fused\"")),
                )?),
            };
        let status = Status::from_name(&r.status)
            .ok_or_else(|| bad(format!("row {i}: unknown status {:?}", r.status)))?;
        rows.push(Measurement {
            frame: r.frame,
            timestamp_ns: Timestamp(r.timestamp_ns),
            camera,
            rod: r.rod,
            position_mm: r.position_mm,
            angle_rad: r.angle_rad,
            angle_unwrapped_rad: r.angle_unwrapped_rad,
            velocity_mm_s: r.velocity_mm_s,
            angular_velocity_rad_s: r.angular_velocity_rad_s,
            quality: r.quality,
            status,
            turns_known: r.turns_known,
        });
    }
    let header = Header {
        kind,
        seq: m.seq,
        frame: m.frame,
        timestamp_ns: Timestamp(m.timestamp_ns),
        complete: m.complete,
        cameras,
    };
    // As in the binary layout, every row is of the header's frame.
    check_rows(&header, &rows)?;
    Ok(Message {
        version: m.version,
        header,
        rows,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn rows() -> Vec<Measurement> {
        (0..3)
            .map(|i| Measurement {
                frame: 42,
                timestamp_ns: Timestamp(210_000_001),
                camera: if i == 2 {
                    CameraId::Fused
                } else {
                    CameraId::Camera(i)
                },
                rod: 7,
                position_mm: 1.0 / 3.0 + f64::from(i),
                angle_rad: 0.1,
                angle_unwrapped_rad: -12.5,
                velocity_mm_s: 1e-9,
                angular_velocity_rad_s: 3.0,
                quality: 0.123_456_789_012_345,
                status: if i == 1 { Status::Conflict } else { Status::Ok },
                turns_known: i != 1,
            })
            .collect()
    }

    fn header() -> Header {
        Header {
            kind: Kind::Fused,
            seq: 9,
            frame: 42,
            timestamp_ns: Timestamp(210_000_001),
            complete: false,
            cameras: 0b10,
        }
    }

    #[test]
    fn binary_and_json_round_trip_every_bit() {
        let (h, r) = (header(), rows());
        let mut out = Vec::new();
        encode(&h, &r, &mut out).unwrap();
        assert_eq!(out.len(), HEADER_BYTES + 3 * ROW_BYTES);
        let m = decode(&out).unwrap();
        assert_eq!((m.header, &m.rows), (h, &r));
        encode_json(&h, &r, &mut out).unwrap();
        let m = decode(&out).unwrap();
        assert_eq!((m.header, &m.rows), (h, &r));
    }

    #[test]
    fn bad_messages_are_refused_by_reason() {
        let mut out = Vec::new();
        encode(&header(), &rows(), &mut out).unwrap();
        let msg = |b: &[u8]| decode(b).unwrap_err().to_string();
        assert!(msg(&out[..10]).contains("shorter"));
        assert!(msg(&out[..out.len() - 1]).contains("need"));
        let mut v = out.clone();
        v[4] = 9;
        assert!(msg(&v).contains("version 9"));
        let mut v = out.clone();
        v[HEADER_BYTES + 56] = 200;
        assert!(msg(&v).contains("status code 200"));
        let mut v = out.clone();
        v[HEADER_BYTES + 8..HEADER_BYTES + 16].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(msg(&v).contains("finite"));
        assert!(msg(b"{\"version\":1}").contains("JSON"));
        let mut json = Vec::new();
        encode_json(&header(), &rows(), &mut json).unwrap();
        let mut v: serde_json::Value = serde_json::from_slice(&json).unwrap();
        v["rows"][1]["frame"] = 41.into();
        assert!(msg(v.to_string().as_bytes()).contains("frame 41"));
        let mut other = rows();
        other[1].frame = 43;
        assert!(encode(&header(), &other, &mut out)
            .unwrap_err()
            .to_string()
            .contains("frame 43"));
    }
}
