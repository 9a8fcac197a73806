//! The rods' health in a session's report ([`RodHealth`]): per camera and rod (and per fused
//! rod), the tracker's fresh searches and learnt-state resets, the rows whose turn count was
//! unknown, how often the count was lost and re-anchored, and the conflicts.
//!
//! Collected without a lock or an allocation per frame: the tracker's and the filter's
//! counters are copied into preallocated atomics by the camera's own thread after each frame
//! (`CameraHealth`), the rows are counted by the writing thread as they go to the sink
//! (`CountingSink`), and the report merges both once the run ends.

use rodtrack_core::filter::TurnStats;
use rodtrack_core::{CameraId, CameraPipeline, Measurement, Status};
use rodtrack_io::{IoError, MeasurementSink};
use std::sync::atomic::{AtomicU64, Ordering};

/// What happened to one rod's tracking in a run: one camera's rows of the rod, or the fused
/// ones ([`CameraId::Fused`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RodHealth {
    /// The camera, or [`CameraId::Fused`].
    pub camera: CameraId,
    /// Rod id.
    pub rod: u32,
    /// Fresh searches from the calibration alone (the rod was not `ok` while its marker may
    /// have been in view; see [`rodtrack_core::RodTracker::fresh_searches`]). Cameras only.
    pub fresh_searches: u64,
    /// Fresh searches that reset the tracker's learnt state
    /// ([`rodtrack_core::RodTracker::learnt_resets`]). Cameras only.
    pub learnt_resets: u64,
    /// Rows written with a value (`ok` or `predicted`) whose turn count was unknown
    /// (`turns_known` false).
    pub rows_turns_unknown: u64,
    /// Times the turn count became unknown (a stretch in which it could have slipped).
    pub turns_lost: u64,
    /// Times the filter re-anchored an unknown count by itself (steady tracking).
    pub turns_reanchored: u64,
    /// Times the count was set by the user (`--reanchor`, [`crate::SessionControl`]).
    pub turns_set_by_user: u64,
    /// Rows written with the status `conflict`.
    pub conflicts: u64,
}

impl RodHealth {
    fn new(camera: CameraId, rod: u32) -> RodHealth {
        RodHealth {
            camera,
            rod,
            fresh_searches: 0,
            learnt_resets: 0,
            rows_turns_unknown: 0,
            turns_lost: 0,
            turns_reanchored: 0,
            turns_set_by_user: 0,
            conflicts: 0,
        }
    }

    /// True when every counter is zero (nothing to report).
    pub fn is_quiet(&self) -> bool {
        self.fresh_searches == 0
            && self.learnt_resets == 0
            && self.rows_turns_unknown == 0
            && self.turns_lost == 0
            && self.turns_reanchored == 0
            && self.turns_set_by_user == 0
            && self.conflicts == 0
    }

    /// The non-zero counters, compactly: `3 fresh searches, 1 reset, count lost 1x, ...`.
    pub fn describe(&self) -> String {
        let plural =
            |n: u64, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
        let items = [
            (
                self.fresh_searches,
                plural(self.fresh_searches, "fresh search", "fresh searches"),
            ),
            (
                self.learnt_resets,
                plural(
                    self.learnt_resets,
                    "learnt-state reset",
                    "learnt-state resets",
                ),
            ),
            (
                self.turns_lost,
                format!("turn count lost {}x", self.turns_lost),
            ),
            (
                self.rows_turns_unknown,
                plural(
                    self.rows_turns_unknown,
                    "row with turns unknown",
                    "rows with turns unknown",
                ),
            ),
            (
                self.turns_reanchored,
                format!("re-anchored {}x", self.turns_reanchored),
            ),
            (
                self.turns_set_by_user,
                format!("set by the user {}x", self.turns_set_by_user),
            ),
            (
                self.conflicts,
                plural(self.conflicts, "conflict", "conflicts"),
            ),
        ];
        let parts: Vec<String> = items
            .into_iter()
            .filter(|(n, _)| *n > 0)
            .map(|(_, text)| text)
            .collect();
        parts.join(", ")
    }

    fn set_turns(&mut self, t: TurnStats) {
        self.turns_lost = t.unknown_stretches;
        self.turns_reanchored = t.auto_reanchors;
        self.turns_set_by_user = t.user_reanchors;
    }
}

/// One rod's counters, written by its camera's thread.
#[derive(Debug, Default)]
struct RodSlots {
    rod: u32,
    fresh_searches: AtomicU64,
    learnt_resets: AtomicU64,
    unknown_stretches: AtomicU64,
    auto_reanchors: AtomicU64,
    user_reanchors: AtomicU64,
}

/// One camera's (or the fusion's) counters of every rod, allocated when the session starts.
#[derive(Debug)]
pub(crate) struct CameraHealth {
    camera: CameraId,
    rods: Box<[RodSlots]>,
}

impl CameraHealth {
    pub(crate) fn new(camera: CameraId, rods: impl IntoIterator<Item = u32>) -> CameraHealth {
        CameraHealth {
            camera,
            rods: rods
                .into_iter()
                .map(|rod| RodSlots {
                    rod,
                    ..RodSlots::default()
                })
                .collect(),
        }
    }

    /// Copies the tracker's counters (after each frame, in the camera's thread).
    pub(crate) fn record_tracker(&self, pipe: &CameraPipeline) {
        for (slot, tr) in self.rods.iter().zip(pipe.rods()) {
            slot.fresh_searches
                .store(tr.fresh_searches(), Ordering::Relaxed);
            slot.learnt_resets
                .store(tr.learnt_resets(), Ordering::Relaxed);
        }
    }

    /// Copies the filter's turn-count counters, `stats(rod)` (after each frame).
    pub(crate) fn record_turns(&self, stats: impl Fn(u32) -> TurnStats) {
        for slot in self.rods.iter() {
            let t = stats(slot.rod);
            slot.unknown_stretches
                .store(t.unknown_stretches, Ordering::Relaxed);
            slot.auto_reanchors
                .store(t.auto_reanchors, Ordering::Relaxed);
            slot.user_reanchors
                .store(t.user_reanchors, Ordering::Relaxed);
        }
    }

    fn snapshot(&self) -> impl Iterator<Item = RodHealth> + '_ {
        self.rods.iter().map(|s| {
            let mut h = RodHealth::new(self.camera, s.rod);
            h.fresh_searches = s.fresh_searches.load(Ordering::Relaxed);
            h.learnt_resets = s.learnt_resets.load(Ordering::Relaxed);
            h.set_turns(TurnStats {
                unknown_stretches: s.unknown_stretches.load(Ordering::Relaxed),
                auto_reanchors: s.auto_reanchors.load(Ordering::Relaxed),
                user_reanchors: s.user_reanchors.load(Ordering::Relaxed),
            });
            h
        })
    }
}

/// Per (camera, rod) row counts.
#[derive(Debug, Clone, Copy)]
struct RowCounts {
    camera: CameraId,
    rod: u32,
    turns_unknown: u64,
    conflicts: u64,
}

/// A sink that counts, per camera and rod, the rows it passes on (turn count unknown,
/// conflicts). The table is allocated when the session starts; a (camera, rod) not in it is
/// added once.
pub(crate) struct CountingSink<S> {
    pub(crate) inner: S,
    counts: Vec<RowCounts>,
}

impl<S> CountingSink<S> {
    pub(crate) fn new(inner: S, keys: impl IntoIterator<Item = (CameraId, u32)>) -> Self {
        let mut counts: Vec<RowCounts> = keys
            .into_iter()
            .map(|(camera, rod)| RowCounts {
                camera,
                rod,
                turns_unknown: 0,
                conflicts: 0,
            })
            .collect();
        counts.reserve(16);
        CountingSink { inner, counts }
    }

    fn count(&mut self, m: &Measurement) {
        let i = match self
            .counts
            .iter()
            .position(|c| c.camera == m.camera && c.rod == m.rod)
        {
            Some(i) => i,
            None => {
                self.counts.push(RowCounts {
                    camera: m.camera,
                    rod: m.rod,
                    turns_unknown: 0,
                    conflicts: 0,
                });
                self.counts.len() - 1
            }
        };
        let c = &mut self.counts[i];
        if matches!(m.status, Status::Ok | Status::Predicted) && !m.turns_known {
            c.turns_unknown += 1;
        }
        if m.status == Status::Conflict {
            c.conflicts += 1;
        }
    }
}

impl<S: MeasurementSink> MeasurementSink for CountingSink<S> {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        for m in rows {
            self.count(m);
        }
        self.inner.write(rows)
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.inner.flush()
    }
}

/// Every rod's health: the counters of `cameras` (cameras and the fusion) merged with the rows
/// counted by `sink`, cameras in order, then the fused rods.
pub(crate) fn merge<S>(
    cameras: &[std::sync::Arc<CameraHealth>],
    sink: &CountingSink<S>,
) -> Vec<RodHealth> {
    let mut out: Vec<RodHealth> = cameras.iter().flat_map(|c| c.snapshot()).collect();
    for c in &sink.counts {
        let i = match out
            .iter()
            .position(|h| h.camera == c.camera && h.rod == c.rod)
        {
            Some(i) => i,
            None => {
                out.push(RodHealth::new(c.camera, c.rod));
                out.len() - 1
            }
        };
        out[i].rows_turns_unknown = c.turns_unknown;
        out[i].conflicts = c.conflicts;
    }
    out
}

/// The lines of the run report for the rods with something to report (`rod health:` and one
/// line per camera and rod), or nothing.
pub fn health_lines(rods: &[RodHealth]) -> String {
    let mut s = String::new();
    for h in rods.iter().filter(|h| !h.is_quiet()) {
        if s.is_empty() {
            s.push_str("\n  rods (counters that are not zero):");
        }
        let who = match h.camera {
            CameraId::Camera(c) => format!("camera {c}"),
            CameraId::Fused => "fused".to_string(),
        };
        s.push_str(&format!("\n    {who}, rod {}: {}", h.rod, h.describe()));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_non_zero_counters_are_described() {
        let mut h = RodHealth::new(CameraId::Camera(1), 5);
        assert!(h.is_quiet());
        assert_eq!(health_lines(&[h]), "");
        h.fresh_searches = 3;
        h.turns_lost = 1;
        h.rows_turns_unknown = 51;
        h.turns_reanchored = 2;
        assert_eq!(
            h.describe(),
            "3 fresh searches, turn count lost 1x, 51 rows with turns unknown, re-anchored 2x"
        );
        let lines = health_lines(&[RodHealth::new(CameraId::Fused, 2), h]);
        assert!(
            lines.contains("camera 1, rod 5: 3 fresh searches"),
            "{lines}"
        );
        assert!(!lines.contains("fused"), "{lines}");
    }

    #[test]
    fn the_sink_counts_rows_per_camera_and_rod() {
        let mut sink =
            CountingSink::new(rodtrack_io::VecSink::default(), [(CameraId::Camera(0), 1)]);
        let mut a = Measurement::empty(
            0,
            rodtrack_core::Timestamp(0),
            CameraId::Camera(0),
            1,
            Status::Ok,
        );
        a.turns_known = false;
        let mut b = Measurement::empty(
            0,
            rodtrack_core::Timestamp(0),
            CameraId::Fused,
            1,
            Status::Conflict,
        );
        b.turns_known = false;
        let mut c = Measurement::empty(
            1,
            rodtrack_core::Timestamp(0),
            CameraId::Camera(0),
            1,
            Status::Ok,
        );
        c.turns_known = true;
        sink.write(&[a, b, c]).unwrap_or_else(|e| panic!("{e}"));
        let rods = merge(&[], &sink);
        assert_eq!(rods.len(), 2);
        assert_eq!((rods[0].rows_turns_unknown, rods[0].conflicts), (1, 0));
        // A conflict row has no value: its count is not "unknown", it is a conflict.
        assert_eq!((rods[1].rows_turns_unknown, rods[1].conflicts), (0, 1));
    }
}
