//! The ball in a session: each camera's [`BallTracker`] runs on the frames its tracker reads,
//! and the rows go, in frame order, to a [`BallSink`] ([`crate::Session::with_ball`]).

mod events;

use crate::SdkError;
pub use events::EventCounts;
use events::{camera_index, EventStage};
use rodtrack_core::ball::events::EventConfig;
use rodtrack_core::ball::{BallFuser, BallRow, BallStatus, BallTracker, CameraBall};
use rodtrack_core::calib::CalibrationFile;
use rodtrack_core::Measurement;
use rodtrack_io::{BallSink, EventSink};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// The most ball rows held back for a camera that has not reported their frame yet (a second
/// of two cameras at 200 fps). Live, a row that comes later than that is written when it
/// comes, out of frame order, never dropped; from recordings, the cameras ahead wait instead
/// ([`BallFeed::push`]), so the rows and events do not depend on the threads' timing.
const MAX_PENDING_ROWS: usize = 400;

/// Counts of the ball rows a session wrote.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BallCounts {
    /// Rows `ok`.
    pub ok: u64,
    /// Rows `predicted`.
    pub predicted: u64,
    /// Rows `lost`.
    pub lost: u64,
    /// Rows `conflict` (fused rows whose cameras disagree).
    pub conflict: u64,
}

/// The cameras' ball rows of frame sets put together away from their trackers (a network's
/// fusion node): each frame's rows are written once every camera has reported it, or once
/// another camera is a set lag of frames past it, followed, with several cameras, by the
/// frame's `fused` row ([`BallFuser`], as in a session). A row of a frame already written goes
/// out on its own, not fused again.
pub struct BallSets(BallWriter);

impl BallSets {
    /// The rows of the cameras `cameras` (their indices) into `sink`, a camera silent while
    /// another one is `max_lag_frames` frames ahead not waited for.
    pub fn new(cameras: &[u32], max_lag_frames: u64, sink: Box<dyn BallSink>) -> BallSets {
        let mut w = BallWriter::new(sink, cameras);
        w.max_lag_frames = Some(max_lag_frames);
        BallSets(w)
    }

    /// Takes camera `camera`'s row with its position's standard deviation, mm (infinite, 0 or
    /// NaN when lost or not known: such a row is not weighed into the fused position).
    pub fn push(&mut self, camera: u32, row: BallRow, sigma_mm: f64) {
        let sigma_mm = if sigma_mm > 0.0 {
            sigma_mm
        } else {
            f64::INFINITY
        };
        self.0.push(camera, row, sigma_mm);
    }

    /// Detects the events of the frame sets' rows too (the `fused` row with several cameras,
    /// else the camera's), as [`crate::Session::with_events`] does: the table of `cal`, the
    /// rules `cfg`, into `sink`. The shot's rod comes from the rods' rows given to
    /// [`BallSets::push_rods`].
    pub fn with_events(
        mut self,
        cal: &CalibrationFile,
        cfg: EventConfig,
        sink: Box<dyn EventSink>,
    ) -> Result<BallSets, SdkError> {
        self.0.events = Some(EventStage::new(cal, cfg, sink)?);
        Ok(self)
    }

    /// Takes a camera's measured rod rows of a frame (before its filter, as its tracker wrote
    /// them), best before the camera's ball row of the frame: their angles tell the events
    /// which rod kicked. Nothing without events.
    pub fn push_rods(&mut self, rows: &[Measurement]) {
        self.0.push_rods(rows);
    }

    /// Writes what is pending and flushes: the counts, or the first error.
    pub fn finish(&mut self) -> Result<BallCounts, SdkError> {
        self.0.finish()
    }

    /// After [`BallSets::finish`]: the events' last decisions written and flushed, and their
    /// counts (`None` without events), or the first error.
    pub fn finish_events(&mut self) -> Result<Option<EventCounts>, SdkError> {
        self.0.events.as_mut().map(|e| e.finish()).transpose()
    }
}

/// The session's ball: the trackers (taken by the cameras' threads) and the ordered writer.
pub(crate) struct BallStage {
    trackers: Vec<(u32, BallTracker)>,
    shared: Arc<BallShared>,
}

/// The writer the cameras' threads share, and the signal a thread ahead waits on.
pub(crate) struct BallShared {
    writer: Mutex<BallWriter>,
    moved: Condvar,
}

/// A camera's ball: its tracker and its feed of the shared writer.
pub(crate) struct BallCamera {
    pub(crate) tracker: BallTracker,
    pub(crate) feed: BallFeed,
}

/// A camera's rows into the shared writer. Dropped (the camera's thread ended), it tells the
/// writer not to wait for the camera.
pub(crate) struct BallFeed {
    camera: u32,
    shared: Arc<BallShared>,
}

/// Rows of all cameras put in frame order before they reach the sink: a frame's rows are
/// written once every camera has reported that frame (or at the end), followed, with
/// several cameras, by the frame's `fused` row ([`BallFuser`]).
pub(crate) struct BallWriter {
    sink: Box<dyn BallSink>,
    pending: Vec<CameraBall>,
    /// The fuser, with several cameras.
    fuser: Option<BallFuser>,
    /// The rows of one write (cameras' and fused), kept for its capacity.
    out: Vec<BallRow>,
    /// Their positions' standard deviations (NaN for a fused row), beside `out`.
    out_sigma: Vec<f64>,
    /// The newest frame written: a camera's row of it or an older one comes late, and is
    /// written on its own, not fused again (the frame's fused row is out already).
    written_up_to: Option<u64>,
    /// Frames held back for a camera that has not reported them at most this many frames
    /// behind the newest frame reported (a network's lost camera); `None`: only
    /// [`MAX_PENDING_ROWS`] bounds it.
    max_lag_frames: Option<u64>,
    /// One frame's camera rows, kept for its capacity.
    group: Vec<CameraBall>,
    /// Per camera: its index, the newest frame it reported, whether it ended.
    last: Vec<(u32, Option<u64>, bool)>,
    /// Recordings: a camera ahead of another by [`MAX_PENDING_ROWS`] rows waits at most
    /// this long for it before its rows are written without the other's.
    hold: Option<Duration>,
    error: Option<String>,
    counts: BallCounts,
    /// The events of each frame set's row (the fused row, or the one camera's).
    events: Option<EventStage>,
}

impl BallStage {
    pub(crate) fn new(
        cal: &CalibrationFile,
        sink: Box<dyn BallSink>,
    ) -> Result<BallStage, SdkError> {
        let mut trackers = Vec::new();
        for c in &cal.cameras {
            let t = BallTracker::new(c).map_err(|e| SdkError::core("the ball", e))?;
            if let Some(t) = t {
                trackers.push((c.index, t));
            }
        }
        if trackers.is_empty() {
            return Err(SdkError::Invalid(
                "no camera of the calibration has `[cameras.ball]`: give the calibration inputs \
                 a `ball` click (and `table` points) and calibrate again"
                    .into(),
            ));
        }
        let cameras: Vec<u32> = trackers.iter().map(|(i, _)| *i).collect();
        let writer = BallWriter::new(sink, &cameras);
        Ok(BallStage {
            trackers,
            shared: Arc::new(BallShared {
                writer: Mutex::new(writer),
                moved: Condvar::new(),
            }),
        })
    }

    /// Camera `index`'s tracker with the shared writer.
    pub(crate) fn take(&mut self, index: u32) -> Option<BallCamera> {
        let at = self.trackers.iter().position(|(i, _)| *i == index)?;
        Some(BallCamera {
            tracker: self.trackers.swap_remove(at).1,
            feed: BallFeed {
                camera: index,
                shared: self.shared.clone(),
            },
        })
    }

    /// Before the run: the cameras a thread ahead waits for at most `hold` (recordings;
    /// `None` live: the oldest rows are written without a camera [`MAX_PENDING_ROWS`] behind).
    /// The calibration's cameras the session does not run are not waited for.
    pub(crate) fn start(&mut self, hold: Option<Duration>) {
        if let Ok(mut w) = self.shared.writer.lock() {
            w.hold = hold;
        }
        for (camera, _) in self.trackers.drain(..) {
            self.shared.ended(camera);
        }
    }

    /// Detects the events of the frame sets' ball rows (the `fused` row with several cameras,
    /// else the camera's) with the table of `cal` and the rules `cfg`, into `sink`.
    pub(crate) fn set_events(
        &mut self,
        cal: &CalibrationFile,
        cfg: EventConfig,
        sink: Box<dyn EventSink>,
    ) -> Result<(), SdkError> {
        let stage = EventStage::new(cal, cfg, sink)?;
        self.shared.lock()?.events = Some(stage);
        Ok(())
    }

    /// The event counts, when events were asked for (after [`BallStage::finish`]).
    pub(crate) fn finish_events(&self) -> Result<Option<EventCounts>, SdkError> {
        let mut w = self.shared.lock()?;
        w.events.as_mut().map(|e| e.finish()).transpose()
    }

    /// Writes what is pending and flushes: the counts, or the first error.
    pub(crate) fn finish(&self) -> Result<BallCounts, SdkError> {
        let mut w = self.shared.lock()?;
        w.finish()
    }
}

impl BallShared {
    fn lock(&self) -> Result<MutexGuard<'_, BallWriter>, SdkError> {
        self.writer
            .lock()
            .map_err(|_| SdkError::Runtime("the ball writer's lock is poisoned".into()))
    }

    /// Camera `camera` has ended: its frames are no longer waited for.
    fn ended(&self, camera: u32) {
        self.writer
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .camera_ended(camera);
        self.moved.notify_all();
    }
}

impl BallFeed {
    /// The camera's ball row of a frame (with its position's standard deviation), after the
    /// rods' rows of the same frame when they were measured (`rods`: the events' shot rod).
    /// From recordings, a camera [`MAX_PENDING_ROWS`] rows ahead of another waits for it here
    /// (at most the writer's hold time).
    pub(crate) fn push(&self, row: BallRow, sigma_mm: f64, rods: Option<&[Measurement]>) {
        // A thread that panicked holding the lock left the writer whole (its state changes
        // between calls only): the rows go on being written.
        let mut w = self.shared.writer.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(rows) = rods {
            w.push_rods(rows);
        }
        w.push(self.camera, row, sigma_mm);
        self.shared.moved.notify_all();
        let Some(hold) = w.hold else {
            return;
        };
        let since = Instant::now();
        while w.ahead(self.camera) {
            let left = hold.saturating_sub(since.elapsed());
            if left.is_zero() {
                // A camera behind is stuck: from now on no camera waits (the live rule: the
                // oldest frames are written without it, its rows late on their own).
                w.hold = None;
                w.evict();
                return;
            }
            w = match self.shared.moved.wait_timeout(w, left) {
                Ok((w, _)) => w,
                Err(e) => e.into_inner().0,
            };
        }
    }
}

impl Drop for BallFeed {
    fn drop(&mut self) {
        self.shared.ended(self.camera);
    }
}

impl BallWriter {
    /// The writer of the cameras `cameras` (their indices, none reported yet).
    fn new(sink: Box<dyn BallSink>, cameras: &[u32]) -> BallWriter {
        let last = cameras.iter().map(|&c| (c, None, false)).collect();
        let cameras = cameras.len();
        BallWriter {
            sink,
            pending: Vec::with_capacity(MAX_PENDING_ROWS + 1),
            fuser: (cameras > 1).then(BallFuser::default),
            out: Vec::with_capacity(MAX_PENDING_ROWS + 1 + MAX_PENDING_ROWS.div_ceil(2)),
            out_sigma: Vec::with_capacity(MAX_PENDING_ROWS + 1 + MAX_PENDING_ROWS.div_ceil(2)),
            written_up_to: None,
            max_lag_frames: None,
            group: Vec::with_capacity(cameras),
            last,
            hold: None,
            error: None,
            counts: BallCounts::default(),
            events: None,
        }
    }

    /// Takes camera `camera`'s row, with its position's standard deviation
    /// ([`BallTracker::row_sigma_mm`]), and writes every frame all cameras have reported.
    pub(crate) fn push(&mut self, camera: u32, row: BallRow, sigma_mm: f64) {
        if self.written_up_to.is_some_and(|w| row.frame <= w) {
            self.write_late(row, sigma_mm);
            return;
        }
        let at = self
            .pending
            .iter()
            .position(|r| (r.row.frame, cam_key(&r.row)) > (row.frame, cam_key(&row)))
            .unwrap_or(self.pending.len());
        self.pending.insert(at, CameraBall { row, sigma_mm });
        for (c, l, _) in &mut self.last {
            if *c == camera {
                *l = Some(row.frame);
            }
        }
        self.emit_done();
        // Live, a camera that stopped reporting (gone, or stuck) holds the others' rows back
        // no longer than [`MAX_PENDING_ROWS`]: the oldest frame is written without it. From
        // recordings, the camera ahead waits instead ([`BallFeed::push`]).
        if self.hold.is_none() {
            self.evict();
        }
        if let Some(lag) = self.max_lag_frames {
            let newest = self.last.iter().filter_map(|(_, l, _)| *l).max();
            if let Some(n) = newest.filter(|&n| n > lag) {
                self.emit(n - lag - 1);
            }
        }
    }

    /// Writes every frame each camera that has not ended has reported (all, when every
    /// camera ended).
    fn emit_done(&mut self) {
        let running = self.last.iter().filter(|(_, _, ended)| !ended);
        match running.map(|(_, l, _)| *l).min() {
            None => self.emit(u64::MAX),
            Some(Some(f)) => self.emit(f),
            Some(None) => {}
        }
    }

    /// Writes the oldest frames, without the cameras that have not reported them, until at
    /// most [`MAX_PENDING_ROWS`] rows are held.
    fn evict(&mut self) {
        while self.pending.len() > MAX_PENDING_ROWS {
            let oldest = self.pending[0].row.frame;
            self.emit(oldest);
        }
    }

    /// Camera `camera` has ended: what the others reported is written.
    fn camera_ended(&mut self, camera: u32) {
        for (c, _, ended) in &mut self.last {
            if *c == camera {
                *ended = true;
            }
        }
        self.emit_done();
    }

    /// Whether `camera` should wait: [`MAX_PENDING_ROWS`] rows held and a camera still
    /// running has not reached this camera's newest frame.
    fn ahead(&self, camera: u32) -> bool {
        if self.pending.len() < MAX_PENDING_ROWS {
            return false;
        }
        let mine = self
            .last
            .iter()
            .find(|(c, _, _)| *c == camera)
            .and_then(|(_, l, _)| *l);
        self.last
            .iter()
            .any(|&(c, l, ended)| c != camera && !ended && l < mine)
    }

    /// Writes what is pending and flushes: the counts, or the first error.
    fn finish(&mut self) -> Result<BallCounts, SdkError> {
        self.emit(u64::MAX);
        if self.error.is_none() {
            if let Err(e) = self.sink.flush() {
                self.error = Some(e.to_string());
            }
        }
        match &self.error {
            Some(e) => Err(SdkError::Runtime(format!("writing the ball rows: {e}"))),
            None => Ok(self.counts),
        }
    }

    /// A camera's row of a frame already written: on its own, counted, not fused.
    fn write_late(&mut self, row: BallRow, sigma_mm: f64) {
        self.count(row.status);
        if self.error.is_none() {
            if let Err(e) = self.sink.write_sigma(&[row], &[sigma_mm]) {
                self.error = Some(e.to_string());
            }
        }
    }

    fn count(&mut self, status: BallStatus) {
        match status {
            BallStatus::Ok => self.counts.ok += 1,
            BallStatus::Predicted => self.counts.predicted += 1,
            BallStatus::Lost => self.counts.lost += 1,
            BallStatus::Conflict => self.counts.conflict += 1,
        }
    }

    /// Takes a camera's rod rows of a frame: their angles give the events the rods' swings
    /// (the shot's rod). Nothing without events.
    pub(crate) fn push_rods(&mut self, rows: &[Measurement]) {
        if let Some(e) = self.events.as_mut() {
            e.push_rods(rows);
        }
    }

    fn emit(&mut self, up_to_frame: u64) {
        let n = self
            .pending
            .iter()
            .take_while(|r| r.row.frame <= up_to_frame)
            .count();
        if n == 0 {
            return;
        }
        self.out.clear();
        self.out_sigma.clear();
        let mut i = 0;
        while i < n {
            let frame = self.pending[i].row.frame;
            self.group.clear();
            while i < n && self.pending[i].row.frame == frame {
                self.out.push(self.pending[i].row);
                self.out_sigma.push(self.pending[i].sigma_mm);
                self.group.push(self.pending[i]);
                i += 1;
            }
            if let Some(f) = self.fuser.as_mut() {
                self.out.push(f.fuse(&self.group));
                self.out_sigma.push(f64::NAN);
            }
            // The frame set's row: the fused one, or the one camera's.
            if let (Some(e), Some(r)) = (self.events.as_mut(), self.out.last()) {
                e.push(r);
            }
        }
        for i in 0..self.out.len() {
            self.count(self.out[i].status);
        }
        self.written_up_to = self.written_up_to.max(Some(self.pending[n - 1].row.frame));
        if self.error.is_none() {
            if let Err(e) = self.sink.write_sigma(&self.out, &self.out_sigma) {
                self.error = Some(e.to_string());
            }
        }
        self.pending.drain(..n);
        if let Some(e) = self.events.as_mut() {
            e.write();
        }
    }
}

fn cam_key(r: &BallRow) -> u32 {
    camera_index(r.camera)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rodtrack_core::{CameraId, Timestamp};
    use rodtrack_io::BallVecSink;

    fn row(camera: u32, frame: u64) -> BallRow {
        BallRow::lost(
            frame,
            Timestamp(frame * 5_000_000),
            CameraId::Camera(camera),
        )
    }

    fn writer(sink: &BallVecSink) -> BallWriter {
        BallWriter::new(Box::new(sink.clone()), &[0, 1])
    }

    /// Both cameras reporting: each frame is written once both have it, in frame and camera
    /// order.
    #[test]
    fn frames_are_written_in_order_once_every_camera_has_them() {
        let sink = BallVecSink::default();
        let mut w = writer(&sink);
        w.push(1, row(1, 0), f64::INFINITY);
        w.push(1, row(1, 1), f64::INFINITY);
        assert!(sink.rows().is_empty());
        w.push(0, row(0, 0), f64::INFINITY);
        let order: Vec<(u64, CameraId)> = sink.rows().iter().map(|r| (r.frame, r.camera)).collect();
        assert_eq!(
            order,
            [
                (0, CameraId::Camera(0)),
                (0, CameraId::Camera(1)),
                (0, CameraId::Fused)
            ]
        );
    }

    /// A camera that never reports holds the other's rows back by at most
    /// [`MAX_PENDING_ROWS`], and the late rows are written when they come.
    #[test]
    fn a_silent_camera_holds_the_rows_back_a_bounded_time() {
        let sink = BallVecSink::default();
        let mut w = writer(&sink);
        let n = 3 * MAX_PENDING_ROWS as u64;
        for f in 0..n {
            w.push(0, row(0, f), f64::INFINITY);
            assert!(w.pending.len() <= MAX_PENDING_ROWS);
        }
        // Each frame written: camera 0's row and the fused one.
        assert_eq!(sink.rows().len() as u64, 2 * (n - MAX_PENDING_ROWS as u64));
        // Camera 1's row of a frame written without it: on its own, not fused again.
        w.push(1, row(1, 3), f64::INFINITY);
        w.emit(u64::MAX);
        assert_eq!(sink.rows().len() as u64, 2 * n + 1);
        assert_eq!(w.counts.lost, 2 * n + 1);
        let fused_3 = sink
            .rows()
            .iter()
            .filter(|r| r.frame == 3 && r.camera == CameraId::Fused)
            .count();
        assert_eq!(fused_3, 1, "one fused row per frame");
    }

    /// On a network (a bounded lag), a camera that stops is waited for that many frames.
    #[test]
    fn a_network_writer_waits_for_a_silent_camera_at_most_its_lag() {
        let sink = BallVecSink::default();
        let mut w = BallSets::new(&[0, 1], 3, Box::new(sink.clone()));
        // Camera 1's first row before camera 0's: held, not written alone.
        w.push(1, row(1, 0), f64::INFINITY);
        assert!(sink.rows().is_empty());
        w.push(0, row(0, 0), f64::INFINITY);
        for f in 1..10 {
            w.push(0, row(0, f), f64::INFINITY);
            w.push(1, row(1, f), f64::INFINITY);
        }
        assert_eq!(
            sink.rows().len(),
            30,
            "both cameras and the fused row per frame"
        );
        for f in 10..20 {
            w.push(0, row(0, f), f64::INFINITY);
        }
        // Frames 10..=15 written without camera 1 (each: camera 0's row and the fused one);
        // 16..=19 held, 3 frames or fewer behind.
        assert_eq!(sink.rows().len(), 30 + 2 * 6);
        let counts = w.finish().unwrap();
        assert_eq!(sink.rows().len(), 30 + 2 * 10);
        assert_eq!(counts.lost, 50);
    }

    /// The shared writer of a session with cameras 0 and 1, holding for recordings.
    fn shared(sink: &BallVecSink, hold: Duration) -> (BallFeed, BallFeed, Arc<BallShared>) {
        let mut w = writer(sink);
        w.hold = Some(hold);
        let shared = Arc::new(BallShared {
            writer: Mutex::new(w),
            moved: Condvar::new(),
        });
        let cam = |camera| BallFeed {
            camera,
            shared: shared.clone(),
        };
        (cam(0), cam(1), shared)
    }

    /// From recordings, a camera far ahead of the other waits for it (no frame is written
    /// without the other's row, none late), however the threads are scheduled; and a camera
    /// whose thread ended is no longer waited for.
    #[test]
    fn a_camera_ahead_waits_for_the_other_and_an_ended_one_is_not_waited_for() {
        let sink = BallVecSink::default();
        let (fast, slow, shared) = shared(&sink, Duration::from_secs(60));
        let n = 3 * MAX_PENDING_ROWS as u64;
        let ahead = std::thread::spawn(move || {
            for f in 0..n {
                fast.push(row(0, f), f64::INFINITY, None);
            }
            // Camera 0 ends here (dropped), after its last row.
        });
        // Camera 1 starts late and goes slowly: camera 0 must wait for it.
        std::thread::sleep(Duration::from_millis(50));
        for f in 0..n / 2 {
            slow.push(row(1, f), f64::INFINITY, None);
            if f % 100 == 0 {
                std::thread::sleep(Duration::from_millis(5));
            }
            assert!(shared.writer.lock().unwrap().pending.len() <= MAX_PENDING_ROWS + 1);
        }
        // Camera 1 ends half way: camera 0's last frames are written without it.
        drop(slow);
        ahead.join().unwrap();
        let counts = shared.lock().unwrap().finish().unwrap();
        let rows = sink.rows();
        // Per frame of the first half: both cameras and the fused row; then camera 0 and the
        // fused row. In frame order: nothing came late.
        assert_eq!(rows.len() as u64, 3 * (n / 2) + 2 * (n - n / 2));
        assert!(rows.windows(2).all(|p| p[0].frame <= p[1].frame));
        assert_eq!(counts.lost, rows.len() as u64);
    }

    /// Without a hold time (live), the camera ahead does not wait: the rows of a camera far
    /// behind are written late, on their own.
    #[test]
    fn live_a_camera_ahead_does_not_wait() {
        let sink = BallVecSink::default();
        let (fast, slow, shared) = shared(&sink, Duration::ZERO);
        shared.writer.lock().unwrap().hold = None;
        let n = 3 * MAX_PENDING_ROWS as u64;
        for f in 0..n {
            fast.push(row(0, f), f64::INFINITY, None);
        }
        slow.push(row(1, 0), f64::INFINITY, None);
        drop((fast, slow));
        let rows = sink.rows();
        assert_eq!(
            rows.len() as u64,
            2 * n + 1,
            "camera 1's frame 0 on its own"
        );
        let at = |frame, camera| {
            rows.iter()
                .position(|r| (r.frame, r.camera) == (frame, camera))
        };
        let late = at(0, CameraId::Camera(1)).unwrap();
        assert!(
            late > at(1, CameraId::Fused).unwrap(),
            "written after newer frames"
        );
    }

    /// A camera that never reports is waited for once, the hold time, and then no more: the
    /// camera ahead goes on with the live rule (rows without it, none lost). Waiting the hold
    /// time at each of its 800 rows past the limit would take 40 s.
    #[test]
    fn a_stuck_camera_is_waited_for_once() {
        let sink = BallVecSink::default();
        let (fast, silent, shared) = shared(&sink, Duration::from_millis(50));
        let n = 3 * MAX_PENDING_ROWS as u64;
        let started = Instant::now();
        for f in 0..n {
            fast.push(row(0, f), f64::INFINITY, None);
        }
        assert!(
            started.elapsed() < Duration::from_secs(10),
            "{:?}",
            started.elapsed()
        );
        assert!(shared.writer.lock().unwrap().hold.is_none());
        drop((fast, silent));
        // Each frame: camera 0's row and the fused one.
        assert_eq!(sink.rows().len() as u64, 2 * n);
    }
}
