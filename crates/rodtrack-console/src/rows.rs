//! The plots' rows ring: the tracking side writes, the console reads, neither waits for the
//! other and neither takes a lock.
//!
//! Each row is packed into one 32-byte slot of four atomic words (two slots fill a cache line;
//! relaxed atomic stores and loads are plain moves). Publishers claim sequence numbers
//! (`claimed`), write their slots, and make them visible in order (`published`); the console
//! copies the published rows it has not sent yet, then drops the ones a publisher may have
//! overwritten meanwhile (those more than [`ROW_CAPACITY`] behind `claimed`), the way a
//! sequence lock's reader retries.

use crate::ROW_CAPACITY;
use rodtrack_core::{Measurement, Status};
use std::sync::atomic::{fence, AtomicU64, Ordering};
use std::time::Instant;

/// What the plots use of a measurement row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PlotRow {
    pub timestamp_s: f64,
    pub angle_unwrapped_rad: f64,
    pub position_mm: f32,
    pub angle_rad: f32,
    pub quality: f32,
    /// Rod index (saturated at `u16::MAX`).
    pub rod: u16,
    /// Camera index (saturated at `i8::MAX`), -1 for fused rows.
    pub camera: i8,
    /// [`status_code`] of the row's status.
    pub status: u8,
    /// The row's turn count is known ([`Measurement::turns_known`]).
    pub turns_known: bool,
}

/// The bit of the packed status byte that holds `turns_known` (status codes are below it).
const TURNS_KNOWN_BIT: u64 = 0x80;

/// The status as the page knows it.
pub(crate) fn status_code(s: Status) -> u8 {
    match s {
        Status::Ok => 0,
        Status::NotFound => 1,
        Status::Occluded => 2,
        Status::OutOfView => 3,
        Status::Predicted => 4,
        Status::Lost => 5,
        Status::BadFrame => 6,
        Status::Conflict => 7,
    }
}

impl PlotRow {
    pub(crate) fn new(m: &Measurement) -> PlotRow {
        PlotRow {
            timestamp_s: m.timestamp_s(),
            angle_unwrapped_rad: m.angle_unwrapped_rad,
            position_mm: m.position_mm as f32,
            angle_rad: m.angle_rad as f32,
            quality: m.quality as f32,
            rod: u16::try_from(m.rod).unwrap_or(u16::MAX),
            camera: match m.camera {
                rodtrack_core::CameraId::Camera(c) => i8::try_from(c).unwrap_or(i8::MAX),
                rodtrack_core::CameraId::Fused => -1,
            },
            status: status_code(m.status),
            turns_known: m.turns_known,
        }
    }

    fn pack(&self) -> [u64; 4] {
        [
            self.timestamp_s.to_bits(),
            self.angle_unwrapped_rad.to_bits(),
            self.position_mm.to_bits() as u64 | (self.angle_rad.to_bits() as u64) << 32,
            self.quality.to_bits() as u64
                | (self.rod as u64) << 32
                | (self.camera as u8 as u64) << 48
                | ((self.status as u64 & !TURNS_KNOWN_BIT)
                    | if self.turns_known { TURNS_KNOWN_BIT } else { 0 })
                    << 56,
        ]
    }

    fn unpack(w: [u64; 4]) -> PlotRow {
        PlotRow {
            timestamp_s: f64::from_bits(w[0]),
            angle_unwrapped_rad: f64::from_bits(w[1]),
            position_mm: f32::from_bits(w[2] as u32),
            angle_rad: f32::from_bits((w[2] >> 32) as u32),
            quality: f32::from_bits(w[3] as u32),
            rod: (w[3] >> 32) as u16,
            camera: (w[3] >> 48) as u8 as i8,
            status: ((w[3] >> 56) & !TURNS_KNOWN_BIT) as u8,
            turns_known: (w[3] >> 56) & TURNS_KNOWN_BIT != 0,
        }
    }
}

const _: () = assert!(std::mem::size_of::<RowRing>() == 64);

/// One row's slot.
#[derive(Debug, Default)]
#[repr(align(32))]
struct Slot([AtomicU64; 4]);

/// The rows ring: row `seq` lives in slot `seq % ROW_CAPACITY` until it is overwritten by row
/// `seq + ROW_CAPACITY`. Everything a publisher touches besides the slots is on this one line,
/// written by the tracking side only (the console reads it a few dozen times per second).
#[derive(Debug)]
#[repr(align(64))]
pub(crate) struct RowRing {
    /// Rows claimed by publishers (the next row's sequence number).
    claimed: AtomicU64,
    /// Rows written: every row before this sequence number is in its slot.
    published: AtomicU64,
    /// `publish` calls, their total and longest time, ns (updated by the publisher whose turn
    /// it is to publish, so plain loads and stores).
    calls: AtomicU64,
    total_ns: AtomicU64,
    max_ns: AtomicU64,
    slots: Box<[Slot]>,
}

impl RowRing {
    /// The ring, allocated and touched once (faulting its pages in while publishing would
    /// happen on the tracking thread).
    pub(crate) fn new() -> RowRing {
        RowRing {
            claimed: AtomicU64::new(0),
            published: AtomicU64::new(0),
            calls: AtomicU64::new(0),
            total_ns: AtomicU64::new(0),
            max_ns: AtomicU64::new(0),
            slots: (0..ROW_CAPACITY).map(|_| Slot::default()).collect(),
        }
    }

    /// Appends rows (the tracking side; any number of threads). Never waits for the console; a
    /// publisher waits only for another publisher that claimed rows before it to finish writing
    /// them. `t0` is when the publish call started: the call's time is accounted for here.
    pub(crate) fn publish(&self, rows: &[Measurement], t0: Instant) {
        let n = rows.len() as u64;
        let start = self.claimed.fetch_add(n, Ordering::Relaxed);
        // Orders the claim before the slots' stores, as the console's acquire fence sees them.
        fence(Ordering::Release);
        // Only the last ROW_CAPACITY rows of a huge call survive: write only those.
        let skip = rows.len().saturating_sub(ROW_CAPACITY);
        for (seq, m) in (start + skip as u64..).zip(&rows[skip..]) {
            let slot = &self.slots[(seq % ROW_CAPACITY as u64) as usize];
            for (w, v) in slot.0.iter().zip(PlotRow::new(m).pack()) {
                w.store(v, Ordering::Relaxed);
            }
        }
        // In claim order: wait for the publishers that claimed earlier rows.
        while self.published.load(Ordering::Acquire) != start {
            std::thread::yield_now();
        }
        // Our turn: no other publisher gets here before `published` moves on.
        let ns = t0.elapsed().as_nanos() as u64;
        let h = self;
        h.calls
            .store(h.calls.load(Ordering::Relaxed) + 1, Ordering::Relaxed);
        h.total_ns
            .store(h.total_ns.load(Ordering::Relaxed) + ns, Ordering::Relaxed);
        if ns > h.max_ns.load(Ordering::Relaxed) {
            h.max_ns.store(ns, Ordering::Relaxed);
        }
        h.published.store(start + n, Ordering::Release);
    }

    /// The rows published so far (the next row's sequence number).
    pub(crate) fn published(&self) -> u64 {
        self.published.load(Ordering::Acquire)
    }

    /// (calls, total ns, longest ns) of [`RowRing::publish`].
    pub(crate) fn spent(&self) -> (u64, u64, u64) {
        let h = self;
        (
            h.calls.load(Ordering::Relaxed),
            h.total_ns.load(Ordering::Relaxed),
            h.max_ns.load(Ordering::Relaxed),
        )
    }

    /// The console's side: appends to `out` the published rows from sequence `from` on (at most
    /// `max`) that are still in the ring, and returns the sequence number after the last one
    /// (rows already overwritten are skipped: the returned cursor is then further on than
    /// `from + ` the rows added).
    pub(crate) fn read(&self, from: u64, max: usize, out: &mut Vec<PlotRow>) -> u64 {
        let cap = ROW_CAPACITY as u64;
        let published = self.published();
        let from = from.max(published.saturating_sub(cap));
        let to = published.min(from.saturating_add(max as u64));
        if to <= from {
            return from.max(to);
        }
        let first = out.len();
        for seq in from..to {
            let slot = &self.slots[(seq % cap) as usize];
            out.push(PlotRow::unpack([
                slot.0[0].load(Ordering::Relaxed),
                slot.0[1].load(Ordering::Relaxed),
                slot.0[2].load(Ordering::Relaxed),
                slot.0[3].load(Ordering::Relaxed),
            ]));
        }
        // Rows a publisher may have started overwriting while they were copied are dropped.
        fence(Ordering::Acquire);
        let intact_from = self.claimed.load(Ordering::Relaxed).saturating_sub(cap);
        if intact_from > from {
            let lost = (intact_from - from).min(to - from) as usize;
            out.drain(first..first + lost);
        }
        to
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rodtrack_core::CameraId;

    fn rows(t: f64, n: u32) -> Vec<Measurement> {
        (0..n)
            .map(|rod| {
                Measurement::empty(
                    1,
                    rodtrack_core::Timestamp::from_secs_f64(t),
                    CameraId::Camera(0),
                    rod,
                    Status::Ok,
                )
            })
            .collect()
    }

    fn times(v: &[PlotRow]) -> Vec<f64> {
        v.iter().map(|r| r.timestamp_s).collect()
    }

    #[test]
    fn rows_are_packed_losslessly_enough() {
        let mut m = Measurement::empty(
            1,
            rodtrack_core::Timestamp::from_secs_f64(12.345678),
            CameraId::Camera(3),
            7,
            Status::Occluded,
        );
        m.position_mm = -12.5;
        m.angle_rad = 1.25;
        m.angle_unwrapped_rad = 1234.5678;
        m.quality = 0.75;
        let r = PlotRow::new(&m);
        assert_eq!(PlotRow::unpack(r.pack()), r);
        assert!(!r.turns_known);
        m.status = Status::Conflict;
        m.turns_known = true;
        let k = PlotRow::unpack(PlotRow::new(&m).pack());
        assert_eq!((k.status, k.turns_known), (7, true));
        assert_eq!(
            (r.timestamp_s, r.angle_unwrapped_rad, r.rod, r.camera),
            (m.timestamp_s(), 1234.5678, 7, 3)
        );
        let fused = Measurement::empty(
            1,
            rodtrack_core::Timestamp::from_secs_f64(0.0),
            CameraId::Fused,
            70_000,
            Status::BadFrame,
        );
        let f = PlotRow::unpack(PlotRow::new(&fused).pack());
        assert_eq!((f.camera, f.rod, f.status), (-1, u16::MAX, 6));
    }

    #[test]
    fn rows_are_read_in_order_from_a_cursor() {
        let ring = RowRing::new();
        ring.publish(&rows(1.0, 3), Instant::now());
        ring.publish(&rows(2.0, 2), Instant::now());
        let mut out = Vec::new();
        assert_eq!(ring.read(0, 4, &mut out), 4);
        assert_eq!(ring.read(4, 100, &mut out), 5);
        assert_eq!(times(&out), [1.0, 1.0, 1.0, 2.0, 2.0]);
        assert_eq!(ring.read(5, 100, &mut out), 5);
        assert_eq!(out.len(), 5);
        assert_eq!(ring.spent().0, 2);
    }

    #[test]
    fn the_ring_keeps_the_newest_rows() {
        let ring = RowRing::new();
        let cap = ROW_CAPACITY as u64;
        let batch = |t0: f64, n: usize| -> Vec<Measurement> {
            (0..n)
                .map(|i| {
                    Measurement::empty(
                        1,
                        rodtrack_core::Timestamp::from_secs_f64(t0 + i as f64),
                        CameraId::Fused,
                        0,
                        Status::Ok,
                    )
                })
                .collect()
        };
        ring.publish(&batch(0.0, ROW_CAPACITY - 1), Instant::now());
        ring.publish(&batch(1e6, 3), Instant::now());
        assert_eq!(ring.published(), cap + 2);
        let mut out = Vec::new();
        // A reader left behind starts at the oldest row still there.
        assert_eq!(ring.read(0, ROW_CAPACITY, &mut out), cap + 2);
        assert_eq!(out.len(), ROW_CAPACITY);
        assert_eq!(out.first().map(|r| r.timestamp_s), Some(2.0));
        // The record's seconds: whole nanoseconds times 1e-9 (1000002.0000000001 here).
        let last_s = rodtrack_core::Timestamp::from_secs_f64(1e6 + 2.0).as_secs_f64();
        assert_eq!(out.last().map(|r| r.timestamp_s), Some(last_s));
        // More than the ring holds at once: the last ROW_CAPACITY.
        ring.publish(&batch(0.0, ROW_CAPACITY + 5), Instant::now());
        out.clear();
        assert_eq!(ring.read(0, 1, &mut out), 2 * cap + 7 - cap + 1);
        assert_eq!(times(&out), [5.0]);
    }

    #[test]
    fn rows_being_overwritten_are_dropped() {
        let ring = RowRing::new();
        ring.publish(&rows(1.0, 8), Instant::now());
        // A publisher has claimed (and may be writing) the slots of rows 0..3.
        ring.claimed
            .fetch_add(ROW_CAPACITY as u64 - 8 + 3, Ordering::Relaxed);
        let mut out = Vec::new();
        assert_eq!(ring.read(0, 100, &mut out), 8);
        assert_eq!(out.len(), 5);
    }

    #[test]
    fn publishers_on_several_threads_lose_no_rows() {
        let ring = RowRing::new();
        std::thread::scope(|s| {
            for t in 0..4 {
                let ring = &ring;
                s.spawn(move || {
                    for _ in 0..500 {
                        ring.publish(&rows(t as f64, 3), Instant::now());
                    }
                });
            }
        });
        let mut out = Vec::new();
        assert_eq!(ring.read(0, usize::MAX, &mut out), 4 * 500 * 3);
        for t in 0..4 {
            assert_eq!(
                out.iter().filter(|r| r.timestamp_s == t as f64).count(),
                1500
            );
        }
        assert_eq!(ring.spent().0, 2000);
    }
}
