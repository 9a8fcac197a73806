//! The ball's messages on the network (`.../cam/<camera>/ball`, `.../fused/ball`): a frame's
//! ball rows with each camera row's position uncertainty, which the fusion node weighs the
//! cameras by. A versioned binary layout (the UDP stream's ball rows, `RTBL`, plus the
//! uncertainty) with a JSON variant for scripts; [`decode_ball`] reads both (a binary message
//! starts with `RTZB`, a JSON one with `{`). No zenoh in it.
//!
//! Binary layout, version 1, little endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `RTZB` (bytes `52 54 5A 42`) |
//! | 4 | 2 | version, u16 = 1 |
//! | 6 | 2 | row count `n`, u16 |
//! | 8 | 4 | sequence number, u32 (per publisher, +1 per message, wraps) |
//! | 12 | 4 | reserved, 0 |
//! | 16 | 72 x n | rows |
//!
//! Each row, 72 bytes: the 64 bytes of a ball row of the UDP stream (frame id, capture
//! timestamp ns, camera with `0xFFFF_FFFF` = fused, status code, `x_mm`, `y_mm`, `vx_mm_s`,
//! `vy_mm_s`, quality: docs/formats.md), then `sigma_mm`, f64 at 64: the position's standard
//! deviation per axis, mm; 0 when not given (a `lost` row, a fused row).
//!
//! JSON: `{"version":1,"kind":"ball","seq":N,"rows":[{...}]}`, each row the JSON Lines ball
//! row's fields plus `"timestamp_ns"` and `"sigma_mm"` (0 when not given).

use crate::ZenohError;
use rodtrack_core::ball::{BallRow, BallStatus};
use rodtrack_core::{CameraId, Timestamp};
use rodtrack_io::sink::{decode_udp_ball, encode_udp_ball, UDP_BALL_HEADER_BYTES};

/// Message magic.
pub const BALL_MAGIC: [u8; 4] = *b"RTZB";
/// Layout version.
pub const BALL_VERSION: u16 = 1;
/// Header size, bytes.
pub const BALL_HEADER_BYTES: usize = 16;
/// Row size, bytes.
pub const BALL_ROW_BYTES: usize = 72;
/// The UDP stream's ball row inside it, bytes.
const UDP_ROW_BYTES: usize = 64;

/// A decoded ball message.
#[derive(Debug, Clone, PartialEq)]
pub struct BallMessage {
    /// Layout version.
    pub version: u16,
    /// Sequence number.
    pub seq: u32,
    /// The rows, each with its `sigma_mm` (0 when not given).
    pub rows: Vec<(BallRow, f64)>,
}

/// The wire's uncertainty: a finite positive value, else 0 ("not given").
fn wire_sigma(s: f64) -> f64 {
    if s.is_finite() && s > 0.0 {
        s
    } else {
        0.0
    }
}

/// Encodes `rows` with their uncertainties `sigma_mm` (one per row; a missing one is not
/// given) into `out`, cleared first. `scratch` holds the UDP rows on the way.
pub fn encode_ball(
    seq: u32,
    rows: &[BallRow],
    sigma_mm: &[f64],
    scratch: &mut Vec<u8>,
    out: &mut Vec<u8>,
) -> Result<(), ZenohError> {
    if rows.len() > u16::MAX as usize {
        return Err(ZenohError::Invalid(format!(
            "{} ball rows in one message, at most {}",
            rows.len(),
            u16::MAX
        )));
    }
    encode_udp_ball(seq, rows, scratch).map_err(|e| ZenohError::Invalid(e.to_string()))?;
    out.clear();
    out.extend_from_slice(&BALL_MAGIC);
    out.extend_from_slice(&scratch[4..UDP_BALL_HEADER_BYTES]);
    for (i, r) in scratch[UDP_BALL_HEADER_BYTES..]
        .chunks_exact(UDP_ROW_BYTES)
        .enumerate()
    {
        out.extend_from_slice(r);
        let s = wire_sigma(sigma_mm.get(i).copied().unwrap_or(0.0));
        out.extend_from_slice(&s.to_le_bytes());
    }
    Ok(())
}

/// Encodes the JSON variant into `out`, cleared first.
pub fn encode_ball_json(seq: u32, rows: &[BallRow], sigma_mm: &[f64], out: &mut Vec<u8>) {
    let mut s = format!("{{\"version\":{BALL_VERSION},\"kind\":\"ball\",\"seq\":{seq},\"rows\":[");
    for (i, r) in rows.iter().enumerate() {
        if i > 0 {
            s.push(',');
        }
        r.sanitized().push_json(&mut s);
        // The row's object, closed by push_json: its last brace reopened for two fields.
        s.pop();
        let sigma = wire_sigma(sigma_mm.get(i).copied().unwrap_or(0.0));
        s.push_str(&format!(
            ",\"timestamp_ns\":{},\"sigma_mm\":{sigma}}}",
            r.timestamp_ns.as_nanos()
        ));
    }
    s.push_str("]}");
    out.clear();
    out.extend_from_slice(s.as_bytes());
}

/// Decodes a ball message (binary or JSON).
pub fn decode_ball(b: &[u8]) -> Result<BallMessage, ZenohError> {
    let bad = |what: String| ZenohError::Invalid(format!("ball message: {what}"));
    if b.first() == Some(&b'{') {
        return decode_json(b).map_err(bad);
    }
    if b.len() < BALL_HEADER_BYTES {
        return Err(bad(format!(
            "{} bytes, shorter than the {BALL_HEADER_BYTES}-byte header",
            b.len()
        )));
    }
    if b[0..4] != BALL_MAGIC {
        return Err(bad("bad magic (expected RTZB)".into()));
    }
    let n = u16::from_le_bytes([b[6], b[7]]) as usize;
    let need = BALL_HEADER_BYTES + n * BALL_ROW_BYTES;
    if b.len() != need {
        return Err(bad(format!("{n} rows need {need} bytes, got {}", b.len())));
    }
    // The UDP ball datagram inside: its header, then each row without its uncertainty.
    let mut udp = Vec::with_capacity(UDP_BALL_HEADER_BYTES + n * UDP_ROW_BYTES);
    udp.extend_from_slice(b"RTBL");
    udp.extend_from_slice(&b[4..BALL_HEADER_BYTES]);
    let mut sigmas = Vec::with_capacity(n);
    for r in b[BALL_HEADER_BYTES..].chunks_exact(BALL_ROW_BYTES) {
        udp.extend_from_slice(&r[..UDP_ROW_BYTES]);
        let mut s = [0u8; 8];
        s.copy_from_slice(&r[UDP_ROW_BYTES..]);
        sigmas.push(wire_sigma(f64::from_le_bytes(s)));
    }
    let p = decode_udp_ball(&udp).map_err(|e| bad(e.to_string()))?;
    Ok(BallMessage {
        version: p.version,
        seq: p.seq,
        rows: p.rows.into_iter().zip(sigmas).collect(),
    })
}

fn decode_json(b: &[u8]) -> Result<BallMessage, String> {
    let v: serde_json::Value = serde_json::from_slice(b).map_err(|e| format!("JSON: {e}"))?;
    let num = |o: &serde_json::Value, k: &str| -> Result<f64, String> {
        o.get(k)
            .and_then(serde_json::Value::as_f64)
            .ok_or_else(|| format!("field '{k}' missing or not a number"))
    };
    let version = num(&v, "version")? as u16;
    if version != BALL_VERSION {
        return Err(format!(
            "version {version}, this decoder reads {BALL_VERSION}"
        ));
    }
    if v.get("kind").and_then(serde_json::Value::as_str) != Some("ball") {
        return Err("field 'kind' is not \"ball\"".into());
    }
    let seq = num(&v, "seq")? as u32;
    let list = v
        .get("rows")
        .and_then(serde_json::Value::as_array)
        .ok_or("field 'rows' missing or not a list")?;
    let mut rows = Vec::with_capacity(list.len());
    for (i, o) in list.iter().enumerate() {
        let at = |e: String| format!("row {i}: {e}");
        let camera = match o.get("camera") {
            Some(serde_json::Value::String(s)) if s == "fused" => CameraId::Fused,
            Some(c) => CameraId::Camera(
                c.as_u64()
                    .and_then(|c| u32::try_from(c).ok())
                    .ok_or_else(|| at(format!("camera {c} is neither an index nor \"fused\"")))?,
            ),
            None => return Err(at("field 'camera' missing".into())),
        };
        let status = match o.get("status").and_then(serde_json::Value::as_str) {
            Some("ok") => BallStatus::Ok,
            Some("predicted") => BallStatus::Predicted,
            Some("lost") => BallStatus::Lost,
            Some("conflict") => BallStatus::Conflict,
            s => return Err(at(format!("unknown status {s:?}"))),
        };
        let frame = o
            .get("frame")
            .and_then(serde_json::Value::as_u64)
            .ok_or_else(|| at("field 'frame' missing or not a frame id".into()))?;
        let timestamp_ns = o
            .get("timestamp_ns")
            .and_then(serde_json::Value::as_u64)
            .ok_or_else(|| at("field 'timestamp_ns' missing or not a time".into()))?;
        let row = BallRow {
            frame,
            timestamp_ns: Timestamp(timestamp_ns),
            camera,
            x_mm: num(o, "x_mm").map_err(at)?,
            y_mm: num(o, "y_mm").map_err(at)?,
            vx_mm_s: num(o, "vx_mm_s").map_err(at)?,
            vy_mm_s: num(o, "vy_mm_s").map_err(at)?,
            quality: num(o, "quality").map_err(at)?,
            status,
        };
        rows.push((row, wire_sigma(num(o, "sigma_mm").map_err(at)?)));
    }
    Ok(BallMessage { version, seq, rows })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn rows() -> Vec<BallRow> {
        let r = |camera, status, x_mm: f64| BallRow {
            frame: 77,
            timestamp_ns: Timestamp(385_000_123),
            camera,
            x_mm,
            y_mm: -12.25,
            vx_mm_s: 1500.5,
            vy_mm_s: -20.0,
            quality: 0.75,
            status,
        };
        vec![
            r(CameraId::Camera(0), BallStatus::Ok, 101.125),
            r(CameraId::Camera(1), BallStatus::Lost, 0.0),
            r(CameraId::Fused, BallStatus::Ok, 101.5),
        ]
    }

    #[test]
    fn binary_round_trip_keeps_every_value_and_the_uncertainty() {
        let (mut scratch, mut out) = (Vec::new(), Vec::new());
        let sigma = [0.3125, f64::INFINITY, f64::NAN];
        encode_ball(9, &rows(), &sigma, &mut scratch, &mut out).unwrap();
        assert_eq!(out.len(), BALL_HEADER_BYTES + 3 * BALL_ROW_BYTES);
        assert_eq!(&out[..4], b"RTZB");
        let m = decode_ball(&out).unwrap();
        assert_eq!((m.version, m.seq), (1, 9));
        let got: Vec<BallRow> = m.rows.iter().map(|r| r.0).collect();
        assert_eq!(got, rows());
        let s: Vec<f64> = m.rows.iter().map(|r| r.1).collect();
        assert_eq!(
            s,
            [0.3125, 0.0, 0.0],
            "infinite and NaN are sent as 'not given'"
        );
    }

    #[test]
    fn json_round_trip_at_the_files_precision() {
        let mut out = Vec::new();
        encode_ball_json(4, &rows(), &[0.5, 0.0, 0.0], &mut out);
        let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
        assert_eq!(v["rows"][2]["camera"], "fused");
        let m = decode_ball(&out).unwrap();
        assert_eq!(m.seq, 4);
        assert_eq!(m.rows.len(), 3);
        assert_eq!(m.rows[0].0.timestamp_ns, Timestamp(385_000_123));
        assert!((m.rows[0].0.x_mm - 101.125).abs() < 1e-3);
        assert_eq!(m.rows[1].0.status, BallStatus::Lost);
        assert_eq!(m.rows[0].1, 0.5);
    }

    #[test]
    fn malformed_messages_are_refused_saying_why() {
        let (mut scratch, mut out) = (Vec::new(), Vec::new());
        encode_ball(1, &rows(), &[], &mut scratch, &mut out).unwrap();
        let e = decode_ball(&out[..out.len() - 1]).unwrap_err().to_string();
        assert!(e.contains("3 rows need"), "{e}");
        let mut bad = out.clone();
        bad[0] = b'X';
        assert!(decode_ball(&bad).unwrap_err().to_string().contains("magic"));
        // A rods' message is not a ball message.
        bad[..4].copy_from_slice(b"RTZN");
        assert!(decode_ball(&bad).is_err());
        let mut status = out.clone();
        status[BALL_HEADER_BYTES + 20] = 9;
        let e = decode_ball(&status).unwrap_err().to_string();
        assert!(e.contains("unknown status"), "{e}");
        let e = decode_ball(br#"{"version":1,"kind":"ball","seq":1,"rows":[{"camera":0}]}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("row 0"), "{e}");
        let e = decode_ball(br#"{"version":2,"kind":"ball","seq":1,"rows":[]}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("version 2"), "{e}");
    }
}
