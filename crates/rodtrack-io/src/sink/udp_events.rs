//! The ball's events in the UDP stream: datagrams of their own, magic `RTEV`, beside the rows'
//! `RTRK` datagrams on the same address. A receiver of rows checks the magic and skips them
//! (the rows' decoder, [`super::decode_udp_packet`], refuses them as a bad magic).
//!
//! One datagram per `write` call (the events decided at one frame set), sent before `write`
//! returns. Layout (version 1), little endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `RTEV` (bytes `52 54 45 56`) |
//! | 4 | 2 | version, u16 = 1 |
//! | 6 | 2 | event count `n`, u16 |
//! | 8 | 4 | sequence number, u32 (per sink, +1 per datagram, wraps) |
//! | 12 | 4 | score of side A after these events, u32 |
//! | 16 | 4 | score of side B, u32 |
//! | 20 | 4 | reserved, 0 |
//! | 24 | 48 x n | events |
//!
//! Each event (48 bytes):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | frame id, u64 (the frame at which it happened) |
//! | 8 | 8 | timestamp, u64 nanoseconds |
//! | 16 | 1 | kind: 0 goal, 1 shot, 2 ball_out, 3 ball_stopped |
//! | 17 | 1 | goal: the side that scored (0 a, 1 b); else 255 |
//! | 18 | 1 | goal: the goal it went into (0 a, 1 b); else 255 |
//! | 19 | 1 | reserved, 0 |
//! | 20 | 4 | shot: the rod (calibration index), `0xFFFF_FFFF` for none; else `0xFFFF_FFFF` |
//! | 24 | 4 | goal: side A's score after it, u32; else 0 |
//! | 28 | 4 | goal: side B's score after it, u32; else 0 |
//! | 32 | 4 | x_mm, f32 (shot, ball_out, ball_stopped; else 0) |
//! | 36 | 4 | y_mm, f32 |
//! | 40 | 4 | shot: speed_mm_s, f32; else 0 |
//! | 44 | 4 | reserved, 0 |

use super::events::EventSink;
use super::udp::{le, Datagrams};
use crate::IoError;
use rodtrack_core::ball::events::{BallEvent, EventKind, Side};
use rodtrack_core::Timestamp;

/// The events datagram's magic.
pub const UDP_EVENTS_MAGIC: [u8; 4] = *b"RTEV";
/// The events datagram's layout version.
pub const UDP_EVENTS_VERSION: u16 = 1;
/// Its header size, bytes.
pub const UDP_EVENTS_HEADER_BYTES: usize = 24;
/// One event's size, bytes.
pub const UDP_EVENT_BYTES: usize = 48;
/// Most events in one datagram (65507-byte UDP payload limit).
pub const UDP_MAX_EVENTS: usize = (65_507 - UDP_EVENTS_HEADER_BYTES) / UDP_EVENT_BYTES;

const NONE_U8: u8 = 255;
const NONE_U32: u32 = u32::MAX;

/// One decoded events datagram.
#[derive(Debug, Clone, PartialEq)]
pub struct UdpEventPacket {
    /// Layout version.
    pub version: u16,
    /// Sequence number.
    pub seq: u32,
    /// The running score after these events, `[side A, side B]`.
    pub score: [u32; 2],
    /// The events (positions and speeds as f32).
    pub events: Vec<BallEvent>,
}

fn side_code(s: Side) -> u8 {
    match s {
        Side::A => 0,
        Side::B => 1,
    }
}

fn side_from_code(c: u8) -> Result<Side, IoError> {
    match c {
        0 => Ok(Side::A),
        1 => Ok(Side::B),
        _ => Err(IoError::Packet(format!("unknown side code {c}"))),
    }
}

/// Encodes `events` with the running score `score` into `out` (cleared first). Non-finite
/// numbers are written as 0. Fails on more than [`UDP_MAX_EVENTS`] events.
pub fn encode_udp_events(
    seq: u32,
    score: [u32; 2],
    events: &[BallEvent],
    out: &mut Vec<u8>,
) -> Result<(), IoError> {
    if events.len() > UDP_MAX_EVENTS {
        return Err(IoError::Packet(format!(
            "{} events in one write, at most {UDP_MAX_EVENTS} fit a datagram",
            events.len()
        )));
    }
    out.clear();
    out.extend_from_slice(&UDP_EVENTS_MAGIC);
    out.extend_from_slice(&UDP_EVENTS_VERSION.to_le_bytes());
    out.extend_from_slice(&(events.len() as u16).to_le_bytes());
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&score[0].to_le_bytes());
    out.extend_from_slice(&score[1].to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    let f = |v: f64| if v.is_finite() { v as f32 } else { 0.0 };
    for e in events {
        let (kind, side, goal, rod, sc, x, y, speed) = match e.kind {
            EventKind::Goal { side, goal, score } => (
                0u8,
                side_code(side),
                side_code(goal),
                NONE_U32,
                score,
                0.0,
                0.0,
                0.0,
            ),
            EventKind::Shot {
                speed_mm_s,
                rod,
                x_mm,
                y_mm,
            } => (
                1,
                NONE_U8,
                NONE_U8,
                rod.unwrap_or(NONE_U32),
                [0, 0],
                x_mm,
                y_mm,
                speed_mm_s,
            ),
            EventKind::BallOut { x_mm, y_mm } => {
                (2, NONE_U8, NONE_U8, NONE_U32, [0, 0], x_mm, y_mm, 0.0)
            }
            EventKind::BallStopped { x_mm, y_mm } => {
                (3, NONE_U8, NONE_U8, NONE_U32, [0, 0], x_mm, y_mm, 0.0)
            }
        };
        out.extend_from_slice(&e.frame.to_le_bytes());
        out.extend_from_slice(&e.timestamp_ns.as_nanos().to_le_bytes());
        out.extend_from_slice(&[kind, side, goal, 0]);
        out.extend_from_slice(&rod.to_le_bytes());
        out.extend_from_slice(&sc[0].to_le_bytes());
        out.extend_from_slice(&sc[1].to_le_bytes());
        for v in [f(x), f(y), f(speed)] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&0u32.to_le_bytes());
    }
    Ok(())
}

/// Decodes an events datagram written by [`encode_udp_events`].
pub fn decode_udp_events(b: &[u8]) -> Result<UdpEventPacket, IoError> {
    if b.len() < UDP_EVENTS_HEADER_BYTES {
        return Err(IoError::Packet(format!(
            "{} bytes, shorter than the {UDP_EVENTS_HEADER_BYTES}-byte events header",
            b.len()
        )));
    }
    if b[0..4] != UDP_EVENTS_MAGIC {
        return Err(IoError::Packet("bad magic (expected RTEV)".into()));
    }
    let version = u16::from_le_bytes(le(b, 4));
    if version != UDP_EVENTS_VERSION {
        return Err(IoError::Packet(format!(
            "events version {version}, this decoder reads {UDP_EVENTS_VERSION}"
        )));
    }
    let n = u16::from_le_bytes(le(b, 6)) as usize;
    let need = UDP_EVENTS_HEADER_BYTES + n * UDP_EVENT_BYTES;
    if b.len() != need {
        return Err(IoError::Packet(format!(
            "{n} events need {need} bytes, got {}",
            b.len()
        )));
    }
    let seq = u32::from_le_bytes(le(b, 8));
    let score = [u32::from_le_bytes(le(b, 12)), u32::from_le_bytes(le(b, 16))];
    let mut events = Vec::with_capacity(n);
    for i in 0..n {
        let at = UDP_EVENTS_HEADER_BYTES + i * UDP_EVENT_BYTES;
        let r = &b[at..at + UDP_EVENT_BYTES];
        let f = |at: usize| f64::from(f32::from_le_bytes(le(r, at)));
        let u = |at: usize| u32::from_le_bytes(le(r, at));
        let (x_mm, y_mm) = (f(32), f(36));
        let kind = match r[16] {
            0 => EventKind::Goal {
                side: side_from_code(r[17])?,
                goal: side_from_code(r[18])?,
                score: [u(24), u(28)],
            },
            1 => EventKind::Shot {
                speed_mm_s: f(40),
                rod: Some(u(20)).filter(|&r| r != NONE_U32),
                x_mm,
                y_mm,
            },
            2 => EventKind::BallOut { x_mm, y_mm },
            3 => EventKind::BallStopped { x_mm, y_mm },
            k => return Err(IoError::Packet(format!("event {i}: unknown kind {k}"))),
        };
        events.push(BallEvent {
            frame: u64::from_le_bytes(le(r, 0)),
            timestamp_ns: Timestamp(u64::from_le_bytes(le(r, 8))),
            kind,
        });
    }
    Ok(UdpEventPacket {
        version,
        seq,
        score,
        events,
    })
}

/// Sends the events, one datagram per `write` call, to a UDP address (the rows' `--udp`
/// address), with the running score (from the goals it sent).
#[derive(Debug)]
pub struct UdpEventSink {
    out: Datagrams,
    score: [u32; 2],
}

impl UdpEventSink {
    /// Sends to `target` (`host:port`) from an ephemeral local port.
    pub fn new(target: &str) -> Result<Self, IoError> {
        Ok(UdpEventSink {
            out: Datagrams::new(target, UDP_EVENTS_HEADER_BYTES + 8 * UDP_EVENT_BYTES)?,
            score: [0, 0],
        })
    }
}

impl EventSink for UdpEventSink {
    fn write(&mut self, events: &[BallEvent]) -> Result<(), IoError> {
        let score = &mut self.score;
        self.out
            .send_chunks(events, UDP_MAX_EVENTS, |seq, chunk, packet| {
                for e in chunk {
                    if let EventKind::Goal { score: s, .. } = e.kind {
                        *score = s;
                    }
                }
                encode_udp_events(seq, *score, chunk, packet)
            })
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::UdpSocket;

    fn sample() -> Vec<BallEvent> {
        let at = |frame: u64, kind| BallEvent {
            frame,
            timestamp_ns: Timestamp(frame * 5_000_000),
            kind,
        };
        vec![
            at(
                10,
                EventKind::Shot {
                    speed_mm_s: 4321.5,
                    rod: Some(3),
                    x_mm: -75.5,
                    y_mm: 20.25,
                },
            ),
            at(
                11,
                EventKind::Shot {
                    speed_mm_s: 2000.0,
                    rod: None,
                    x_mm: 1.0,
                    y_mm: 2.0,
                },
            ),
            at(
                40,
                EventKind::Goal {
                    side: Side::A,
                    goal: Side::B,
                    score: [2, 1],
                },
            ),
            at(
                90,
                EventKind::BallOut {
                    x_mm: 3.0,
                    y_mm: 340.0,
                },
            ),
            at(
                200,
                EventKind::BallStopped {
                    x_mm: -1.5,
                    y_mm: 0.5,
                },
            ),
        ]
    }

    /// Every kind survives the datagram (f32 numbers chosen exact); the rows' decoder refuses
    /// it (a receiver of rows is not confused); a truncated one and a wrong version are
    /// refused.
    #[test]
    fn events_round_trip_and_row_receivers_skip_them() {
        let events = sample();
        let mut b = Vec::new();
        encode_udp_events(7, [2, 1], &events, &mut b).unwrap();
        assert_eq!(
            b.len(),
            UDP_EVENTS_HEADER_BYTES + events.len() * UDP_EVENT_BYTES
        );
        let p = decode_udp_events(&b).unwrap();
        assert_eq!((p.version, p.seq, p.score), (1, 7, [2, 1]));
        assert_eq!(p.events, events);
        let err = super::super::decode_udp_packet(&b).unwrap_err();
        assert!(err.to_string().contains("magic"), "{err}");
        assert!(decode_udp_events(&b[..b.len() - 1]).is_err());
        let mut v2 = b.clone();
        v2[4] = 2;
        assert!(decode_udp_events(&v2).is_err());
    }

    /// A sink sends one datagram per write to a local socket, the running score following
    /// the goals.
    #[test]
    fn the_sink_sends_each_write_with_the_running_score() {
        let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
        rx.set_read_timeout(Some(std::time::Duration::from_secs(5)))
            .unwrap();
        let mut sink = UdpEventSink::new(&rx.local_addr().unwrap().to_string()).unwrap();
        let events = sample();
        sink.write(&events[..2]).unwrap();
        sink.write(&events[2..]).unwrap();
        let mut buf = [0u8; 2048];
        let n = rx.recv(&mut buf).unwrap();
        let a = decode_udp_events(&buf[..n]).unwrap();
        let n = rx.recv(&mut buf).unwrap();
        let b = decode_udp_events(&buf[..n]).unwrap();
        assert_eq!((a.seq, a.score, a.events.len()), (0, [0, 0], 2));
        assert_eq!((b.seq, b.score, b.events.len()), (1, [2, 1], 3));
    }
}
