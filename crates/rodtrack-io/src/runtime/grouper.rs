//! The output stage: frames of the cameras grouped into frame sets, the fusion, the writes to
//! the sink and the latency statistics.

use super::config::{CameraRowsFn, FrameSetInfo, FusionFn, Grouping, PipelineConfig, WriteMode};
use super::latency::{LatencyHistogram, StageHistograms};
use super::report::{CameraStats, PipelineCounters, PipelineReport};
use crate::frame::{FrameMeta, Timestamp};
use crate::sink::MeasurementSink;
use crossbeam_channel::Sender;
use rodtrack_core::Measurement;
use std::collections::VecDeque;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;

/// When a frame passed each point of the pipeline.
#[derive(Debug, Clone, Copy)]
pub(super) struct Stamps {
    /// The source returned it (and, paced, its release time came).
    pub(super) available: Instant,
    /// Its processing started.
    pub(super) started: Instant,
    /// Its processing (and the camera's filter) ended.
    pub(super) processed: Instant,
    /// The output stage took its rows.
    pub(super) entered: Instant,
}

/// One camera's processed frame.
pub(super) struct Part {
    pub(super) meta: FrameMeta,
    /// Rows of the processing stage (the fusion's input).
    pub(super) rows: Vec<Measurement>,
    /// Rows of the camera's filter, written instead of `rows` (`None`: no filter).
    pub(super) filtered: Option<Vec<Measurement>>,
    pub(super) stamps: Stamps,
}

impl Part {
    /// The rows to write.
    fn output(&self) -> &[Measurement] {
        self.filtered.as_deref().unwrap_or(&self.rows)
    }
}

struct Pending {
    key: u64,
    created: Instant,
    parts: Vec<Option<Part>>,
}

/// The output stage: grouping, fusion, writes, latency.
pub(super) struct Grouper {
    config: PipelineConfig,
    n: usize,
    /// Per camera, the newest key it delivered.
    latest: Vec<Option<u64>>,
    /// Per camera, whether it ended.
    pub(super) ended: Vec<bool>,
    /// Pending sets in key order (a handful at most).
    pending: VecDeque<Pending>,
    last_emitted: Option<u64>,
    fusion: Option<FusionFn>,
    camera_rows: Option<CameraRowsFn>,
    info: FrameSetInfo,
    out: Vec<Measurement>,
    raw: Vec<Measurement>,
    fused: Vec<Measurement>,
    latency: LatencyHistogram,
    set_latency: LatencyHistogram,
    set_last_latency: LatencyHistogram,
    stages: StageHistograms,
    counters: Arc<PipelineCounters>,
    first_sink_error: Option<String>,
    vec_tx: Sender<Vec<Measurement>>,
    /// Recycled per-set part vectors.
    free_parts: Vec<Vec<Option<Part>>>,
}

impl Grouper {
    pub(super) fn new(
        config: PipelineConfig,
        n: usize,
        fusion: Option<FusionFn>,
        camera_rows: Option<CameraRowsFn>,
        counters: &Arc<PipelineCounters>,
        vec_tx: Sender<Vec<Measurement>>,
    ) -> Self {
        Grouper {
            config,
            n,
            latest: vec![None; n],
            ended: vec![false; n],
            pending: VecDeque::with_capacity(16),
            last_emitted: None,
            fusion,
            camera_rows,
            info: FrameSetInfo {
                frame_id: 0,
                timestamp_ns: Timestamp(0),
                frames: Vec::with_capacity(n),
                complete: false,
            },
            out: Vec::with_capacity(64),
            raw: Vec::with_capacity(64),
            fused: Vec::with_capacity(16),
            latency: LatencyHistogram::new(),
            set_latency: LatencyHistogram::new(),
            set_last_latency: LatencyHistogram::new(),
            stages: StageHistograms::default(),
            counters: counters.clone(),
            first_sink_error: None,
            vec_tx,
            free_parts: Vec::new(),
        }
    }

    fn tolerance(&self) -> u64 {
        match self.config.grouping {
            Grouping::FrameId => 0,
            Grouping::Timestamp { window_ns } => window_ns,
        }
    }

    fn key_of(&self, meta: &FrameMeta) -> u64 {
        match self.config.grouping {
            Grouping::FrameId => meta.frame_id,
            Grouping::Timestamp { .. } => meta.timestamp_ns.as_nanos(),
        }
    }

    fn index_of(&self, key: u64) -> Option<usize> {
        self.pending.iter().position(|p| p.key == key)
    }

    /// Returns a part's vectors to the pool.
    pub(super) fn recycle(&mut self, part: Part) {
        for mut v in std::iter::once(part.rows).chain(part.filtered) {
            v.clear();
            let _ = self.vec_tx.try_send(v);
        }
    }

    /// Writes rows, counting them or the error.
    fn write(&mut self, rows: &[Measurement], sink: &mut dyn MeasurementSink) {
        match sink.write(rows) {
            Ok(()) => {
                self.counters
                    .rows_written
                    .fetch_add(rows.len() as u64, Ordering::Relaxed);
            }
            Err(e) => {
                self.counters.sink_errors.fetch_add(1, Ordering::Relaxed);
                self.first_sink_error.get_or_insert(e.to_string());
            }
        }
    }

    /// Records a frame's latency and its stages, its rows' write having run from
    /// `write_start` to `written`.
    fn record(&mut self, s: &Stamps, write_start: Instant, written: Instant) {
        let d = |a: Instant, b: Instant| b.saturating_duration_since(a);
        self.latency.record(d(s.available, written));
        self.stages.pickup.record(d(s.available, s.started));
        self.stages.process.record(d(s.started, s.processed));
        self.stages.handoff.record(d(s.processed, s.entered));
        self.stages.wait_set.record(d(s.entered, write_start));
        self.stages.write.record(d(write_start, written));
    }

    pub(super) fn add(&mut self, camera: usize, mut part: Part, sink: &mut dyn MeasurementSink) {
        if self.config.write == WriteMode::PerCamera {
            let start = Instant::now();
            self.write(part.output(), sink);
            self.record(&part.stamps, start, Instant::now());
            // Written: only the measured rows stay, for the fusion.
            if let Some(mut v) = part.filtered.take() {
                v.clear();
                let _ = self.vec_tx.try_send(v);
            }
        }
        let k = self.key_of(&part.meta);
        let tol = self.tolerance();
        // The set this frame joins: same key (frame id), or within the window (timestamps).
        let mut target = match self.config.grouping {
            Grouping::FrameId => self.index_of(k).map(|_| k),
            Grouping::Timestamp { .. } => self
                .pending
                .iter()
                .find(|p| {
                    p.key >= k.saturating_sub(tol)
                        && p.key <= k.saturating_add(tol)
                        && p.parts[camera].is_none()
                })
                .map(|p| p.key),
        };
        // A camera delivering the same id twice: close the older set first.
        if let Some(t) = target {
            if self
                .index_of(t)
                .is_some_and(|i| self.pending[i].parts[camera].is_some())
            {
                self.emit_through(t, sink);
                target = None;
            }
        }
        self.latest[camera] = Some(self.latest[camera].map_or(k, |l| l.max(k)));
        let late = target.is_none() && self.last_emitted.is_some_and(|l| k <= l);
        let key = target.unwrap_or(k);
        let i = match self.index_of(key) {
            Some(i) => i,
            None => {
                let mut parts = self.free_parts.pop().unwrap_or_default();
                parts.clear();
                parts.resize_with(self.n, || None);
                let at = self.pending.partition_point(|p| p.key < key);
                self.pending.insert(
                    at,
                    Pending {
                        key,
                        created: Instant::now(),
                        parts,
                    },
                );
                at
            }
        };
        self.pending[i].parts[camera] = Some(part);
        if late {
            // Its set was already emitted, with its fused rows: write this frame's rows on
            // their own, not fused again.
            self.counters.cameras[camera]
                .frames_late
                .fetch_add(1, Ordering::Relaxed);
            self.emit_key(key, true, sink);
        }
    }

    fn ready(&self, p: &Pending, now: Instant) -> bool {
        if now.duration_since(p.created) >= self.config.group_timeout {
            return true;
        }
        let tol = self.tolerance();
        (0..self.n).all(|c| {
            p.parts[c].is_some()
                || self.ended[c]
                || self.counters.cameras[c].absent.load(Ordering::Relaxed)
                || self.latest[c].is_some_and(|l| l > p.key.saturating_add(tol))
        })
    }

    /// Emits ready sets in key order, stopping at the first that is not ready (`all`: emit
    /// everything).
    pub(super) fn emit_ready(&mut self, now: Instant, all: bool, sink: &mut dyn MeasurementSink) {
        while let Some(p) = self.pending.front() {
            if !all && !self.ready(p, now) {
                break;
            }
            let key = p.key;
            self.emit_key(key, false, sink);
        }
    }

    /// Emits every pending set up to and including `key`.
    fn emit_through(&mut self, key: u64, sink: &mut dyn MeasurementSink) {
        while let Some(p) = self.pending.front() {
            if p.key > key {
                break;
            }
            let k = p.key;
            self.emit_key(k, false, sink);
        }
    }

    /// Writes the set of `key` (`late`: one camera's frame whose set was written already:
    /// its rows only, no fusion, not counted as a set).
    fn emit_key(&mut self, key: u64, late: bool, sink: &mut dyn MeasurementSink) {
        let Some(mut p) = self.index_of(key).and_then(|i| self.pending.remove(i)) else {
            return;
        };
        let start = Instant::now();
        let per_camera = self.config.write == WriteMode::PerCamera;
        self.last_emitted = Some(self.last_emitted.map_or(key, |l| l.max(key)));
        self.out.clear();
        let mut complete = true;
        for (c, part) in p.parts.iter().enumerate() {
            match part {
                Some(part) => {
                    if !per_camera {
                        self.out.extend_from_slice(part.output());
                    }
                }
                None if late => {}
                None => {
                    complete = false;
                    self.counters.cameras[c]
                        .missing_in_sets
                        .fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        if late {
            // Not a set.
        } else if complete {
            self.counters.sets_complete.fetch_add(1, Ordering::Relaxed);
        } else {
            self.counters
                .sets_incomplete
                .fetch_add(1, Ordering::Relaxed);
        }
        if let Some(fusion) = self.fusion.as_mut().filter(|_| !late) {
            let first = p.parts.iter().flatten().next().map(|part| part.meta);
            self.info.frame_id = first.map_or(key, |m| m.frame_id);
            self.info.timestamp_ns = first.map_or(Timestamp(0), |m| m.timestamp_ns);
            self.info.frames.clear();
            self.info
                .frames
                .extend(p.parts.iter().map(|x| x.as_ref().map(|part| part.meta)));
            self.info.complete = complete;
            // The fusion's input: the measured rows (the same as the written ones without
            // camera filters).
            let measured = if !per_camera && p.parts.iter().flatten().all(|x| x.filtered.is_none())
            {
                &self.out
            } else {
                self.raw.clear();
                for part in p.parts.iter().flatten() {
                    self.raw.extend_from_slice(&part.rows);
                }
                &self.raw
            };
            self.fused.clear();
            fusion(&self.info, measured, &mut self.fused);
            if !per_camera {
                if let Some(f) = self.camera_rows.as_mut() {
                    f(&mut self.out);
                }
            }
            self.out.extend_from_slice(&self.fused);
        }
        if !self.out.is_empty() {
            let out = std::mem::take(&mut self.out);
            self.write(&out, sink);
            self.out = out;
        }
        let now = Instant::now();
        if let Some(last) = p.parts.iter().flatten().map(|x| x.stamps.available).max() {
            self.set_last_latency
                .record(now.saturating_duration_since(last));
        }
        for part in p.parts.drain(..).flatten() {
            self.set_latency
                .record(now.saturating_duration_since(part.stamps.available));
            if !per_camera {
                self.record(&part.stamps, start, now);
            }
            self.recycle(part);
        }
        if self.free_parts.len() < 64 {
            self.free_parts.push(p.parts);
        }
    }

    pub(super) fn flush(&mut self, sink: &mut dyn MeasurementSink) {
        if let Err(e) = sink.flush() {
            self.counters.sink_errors.fetch_add(1, Ordering::Relaxed);
            self.first_sink_error.get_or_insert(e.to_string());
        }
    }

    /// The run's report, with `cameras` the final numbers of each camera.
    pub(super) fn finish(
        &mut self,
        counters: &PipelineCounters,
        cameras: Vec<CameraStats>,
        started: Instant,
        stopped: bool,
    ) -> PipelineReport {
        PipelineReport {
            cameras,
            sets_complete: counters.sets_complete.load(Ordering::Relaxed),
            sets_incomplete: counters.sets_incomplete.load(Ordering::Relaxed),
            rows_written: counters.rows_written.load(Ordering::Relaxed),
            sink_errors: counters.sink_errors.load(Ordering::Relaxed),
            first_sink_error: self.first_sink_error.take(),
            latency: self.latency.summary(),
            set_latency: self.set_latency.summary(),
            set_last_latency: self.set_last_latency.summary(),
            stages: self.stages.summary(),
            elapsed: started.elapsed(),
            stopped,
        }
    }
}
