//! A session run in a background thread, its frame sets handed over through a bounded
//! channel: what `rodtrack.open` iterates.
//!
//! The session writes one frame set per sink write (every camera's rows in camera order, then
//! the fused rows). Recordings never drop: when the channel is full the session waits for the
//! reader. Live sources never wait for the reader: a frame set that finds the channel full is
//! dropped and counted ([`Stream::dropped_sets`]), so that the cameras and the temporal filter
//! keep real time whatever the reader does.
//!
//! With the ball ([`BallShare`]), each frame set also carries the ball's rows and events: the
//! session writes a frame's ball rows (each camera's, then the fused one) as soon as every
//! camera has reported the frame, before the frame set's rows, so a set carries its own
//! frame's ball rows; rows of older frames that came late (a camera behind) ride with the next
//! set written, and the events with the first set written after they were decided.

use rodtrack_core::ball::events::BallEvent;
use rodtrack_core::ball::BallRow;
use rodtrack_core::Measurement;
use rodtrack_io::runtime::WriteMode;
use rodtrack_io::{BallSink, EventSink, IoError, MeasurementSink};
use rodtrack_sdk::{pipeline_config, RunReport, SdkError, Session};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// The most ball rows held for frame sets not written yet (5 s of two cameras and the fused
/// row at 200 fps); older ones are dropped and counted ([`Stream::dropped_ball_rows`]).
const MAX_HELD_BALL_ROWS: usize = 3000;

/// One frame set: the rows of every camera for one frame id, then the fused rows; with the
/// ball, its rows and the events decided since the last set.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameSet {
    /// The frame id.
    pub frame: u64,
    /// The rows, in the order a file gets them.
    pub rows: Vec<Measurement>,
    /// The ball's rows of this frame (each camera's, then the fused one), after those of
    /// older frames that came late; empty without the ball.
    pub ball: Vec<BallRow>,
    /// The events decided since the last set was written.
    pub events: Vec<BallEvent>,
}

/// The ball's rows and events waiting for their frame set.
#[derive(Debug, Default)]
struct Held {
    ball: VecDeque<BallRow>,
    events: Vec<BallEvent>,
    dropped: u64,
}

/// The session's ball sink and event sink for a streamed session: what they get is held
/// until the frame set it belongs to is written ([`Stream::start`] with it).
#[derive(Debug, Clone, Default)]
pub struct BallShare(Arc<Mutex<Held>>);

impl BallShare {
    fn lock(&self) -> std::sync::MutexGuard<'_, Held> {
        // The state changes between calls only: a panic elsewhere left it whole.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The ball rows of frames up to `frame` and the events held, moved into `set`.
    fn take_into(&self, set: &mut FrameSet) {
        let mut h = self.lock();
        while h.ball.front().is_some_and(|b| b.frame <= set.frame) {
            if let Some(b) = h.ball.pop_front() {
                set.ball.push(b);
            }
        }
        set.events.append(&mut h.events);
    }

    /// A set that was not delivered gives its events back, ahead of those decided since: the
    /// next set carries them (its ball rows go with it: those frames are dropped).
    fn give_back(&self, mut events: Vec<BallEvent>) {
        if events.is_empty() {
            return;
        }
        let mut h = self.lock();
        events.append(&mut h.events);
        h.events = events;
    }

    /// The events no set has carried.
    fn take_events(&self) -> Vec<BallEvent> {
        std::mem::take(&mut self.lock().events)
    }
}

impl BallSink for BallShare {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        let mut h = self.lock();
        for r in rows {
            if h.ball.len() >= MAX_HELD_BALL_ROWS {
                h.ball.pop_front();
                h.dropped += 1;
            }
            h.ball.push_back(*r);
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

impl EventSink for BallShare {
    fn write(&mut self, events: &[BallEvent]) -> Result<(), IoError> {
        self.lock().events.extend_from_slice(events);
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

/// The sink of a streamed session: each write is one frame set, sent to the reader.
struct SetSender {
    tx: SyncSender<FrameSet>,
    live: bool,
    dropped: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    ball: Option<BallShare>,
}

impl MeasurementSink for SetSender {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        let Some(first) = rows.first() else {
            return Ok(());
        };
        let mut set = FrameSet {
            frame: first.frame,
            rows: rows.to_vec(),
            ball: Vec::new(),
            events: Vec::new(),
        };
        if let Some(b) = &self.ball {
            b.take_into(&mut set);
        }
        let gone = if self.live {
            match self.tx.try_send(set) {
                Ok(()) => false,
                Err(TrySendError::Full(set)) => {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                    // A frame set may be dropped, an event (a goal) not.
                    if let Some(b) = &self.ball {
                        b.give_back(set.events);
                    }
                    false
                }
                Err(TrySendError::Disconnected(_)) => true,
            }
        } else {
            self.tx.send(set).is_err()
        };
        if gone {
            // Nobody reads any more: the session stops.
            self.stop.store(true, Ordering::SeqCst);
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

/// What [`Stream::next_timeout`] found.
#[derive(Debug)]
pub enum Next {
    /// A frame set.
    Set(FrameSet),
    /// Nothing yet: the timeout passed.
    Pending,
    /// The session has ended (its sources ended, it was stopped, or it failed).
    Ended(Result<Box<RunReport>, SdkError>),
}

/// A session running in its own thread.
pub struct Stream {
    rx: Option<Receiver<FrameSet>>,
    stop: Arc<AtomicBool>,
    dropped: Arc<AtomicU64>,
    handle: Option<JoinHandle<Result<RunReport, SdkError>>>,
    live: bool,
    ball: Option<BallShare>,
}

impl Stream {
    /// Starts `session` in a thread, its frame sets through a channel of `capacity` sets
    /// (at least 1). The session's pipeline settings become one write per frame set, the
    /// rest as [`pipeline_config`] chooses for its sources. `ball`: the share the session's
    /// ball (and events) sink writes to, whose rows the sets carry.
    pub fn start(
        mut session: Session,
        capacity: usize,
        ball: Option<BallShare>,
    ) -> Result<Stream, SdkError> {
        let live = session.is_live();
        let options = session.options_mut();
        let mut config = options.config.unwrap_or_else(|| pipeline_config(live));
        config.write = WriteMode::Set;
        options.config = Some(config);
        // The options' own choice would override the settings': whole sets here too.
        options.write = Some(WriteMode::Set);
        let stop = session.stop_flag();
        let dropped = Arc::new(AtomicU64::new(0));
        let (tx, rx) = std::sync::mpsc::sync_channel(capacity.max(1));
        let sink = SetSender {
            tx,
            live,
            dropped: dropped.clone(),
            stop: stop.clone(),
            ball: ball.clone(),
        };
        let handle = std::thread::Builder::new()
            .name("rodtrack-session".into())
            .spawn(move || session.run(sink).map(|(report, _sink)| report))
            .map_err(|e| SdkError::Runtime(format!("cannot start the session thread: {e}")))?;
        Ok(Stream {
            rx: Some(rx),
            stop,
            dropped,
            handle: Some(handle),
            live,
            ball,
        })
    }

    /// The events decided after the last frame set was written (the end of the run decides
    /// what was pending), once the session has ended; empty before, and after the first call.
    pub fn take_final_events(&self) -> Vec<BallEvent> {
        match (&self.ball, self.handle.is_none()) {
            (Some(b), true) => b.take_events(),
            _ => Vec::new(),
        }
    }

    /// Ball rows dropped because no frame set took them in time (more than 3000 held: 5 s of
    /// two cameras and the fused row at 200 fps).
    pub fn dropped_ball_rows(&self) -> u64 {
        self.ball.as_ref().map_or(0, |b| b.lock().dropped)
    }

    /// True when a source is live.
    pub fn is_live(&self) -> bool {
        self.live
    }

    /// Frame sets dropped because the reader was behind (live sources only).
    pub fn dropped_sets(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// The next frame set, waiting at most `timeout`. After [`Next::Ended`], `Ended` again
    /// with an error saying so.
    pub fn next_timeout(&mut self, timeout: Duration) -> Next {
        let Some(rx) = self.rx.as_ref() else {
            return Next::Ended(Err(SdkError::Invalid("the session has ended".into())));
        };
        match rx.recv_timeout(timeout) {
            Ok(set) => Next::Set(set),
            Err(RecvTimeoutError::Timeout) => Next::Pending,
            Err(RecvTimeoutError::Disconnected) => {
                self.rx = None;
                Next::Ended(self.join().map(Box::new))
            }
        }
    }

    /// Stops the session (pending frame sets are discarded) and waits for its thread; its
    /// report, or its error. A second call returns an error saying it has ended.
    pub fn close(&mut self) -> Result<RunReport, SdkError> {
        self.stop.store(true, Ordering::SeqCst);
        // Dropping the receiver unblocks a recording's sink waiting on a full channel.
        self.rx = None;
        self.join()
    }

    fn join(&mut self) -> Result<RunReport, SdkError> {
        let Some(handle) = self.handle.take() else {
            return Err(SdkError::Invalid("the session has ended".into()));
        };
        handle
            .join()
            .unwrap_or_else(|_| Err(SdkError::Runtime("the session thread panicked".into())))
    }
}

impl Drop for Stream {
    fn drop(&mut self) {
        if self.handle.is_some() {
            let _ = self.close();
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use rodtrack_core::CameraId;
    use rodtrack_sdk::SessionOptions;
    use std::time::Instant;

    /// Both simulated cameras calibrated once (it takes seconds) for every session.
    fn calibration() -> &'static rodtrack_core::calib::CalibrationFile {
        static CAL: std::sync::OnceLock<rodtrack_core::calib::CalibrationFile> =
            std::sync::OnceLock::new();
        CAL.get_or_init(|| {
            let mut sim =
                rodtrack_sim::build_simulation("exp3", Some(2), 1, false, "default").unwrap();
            let cams = (0..2)
                .map(|c| {
                    rodtrack_sim::calibrate_sim_camera(&mut sim, c, 1)
                        .unwrap()
                        .calibration
                })
                .collect();
            rodtrack_sdk::calibration_file(cams).unwrap()
        })
    }

    fn session(frames: usize) -> Session {
        let cal = calibration();
        let inputs: Vec<String> = (0..2)
            .map(|c| format!("sim://exp3?camera={c}&frames={frames}&seed=1"))
            .collect();
        Session::open(cal, &inputs, SessionOptions::default()).unwrap()
    }

    /// The `goals` table (seed 3: a shot, then a goal within 200 frames), calibrated.
    fn goals_calibration() -> rodtrack_core::calib::CalibrationFile {
        let mut sim =
            rodtrack_sim::build_simulation("goals", Some(200), 3, false, "default").unwrap();
        let cams = (0..2)
            .map(|c| sim.calibrated_camera_with_ball(c, 3).unwrap())
            .collect();
        rodtrack_sdk::calibration_file(cams).unwrap()
    }

    #[test]
    fn each_set_carries_its_frames_ball_rows_and_the_events_as_the_sessions_sinks_get_them() {
        let cal = goals_calibration();
        let inputs: Vec<String> = (0..2)
            .map(|c| format!("sim://goals?camera={c}&frames=200&seed=3"))
            .collect();
        let open = |ball: Box<dyn BallSink>, events: Box<dyn EventSink>| {
            Session::open(&cal, &inputs, SessionOptions::default())
                .unwrap()
                .with_ball(&cal, ball)
                .unwrap()
                .with_events(&cal, Default::default(), events)
                .unwrap()
        };
        // The reference: the same session into the SDK's own sinks.
        let (want_ball, want_events) = (
            rodtrack_io::BallVecSink::default(),
            rodtrack_io::EventVecSink::default(),
        );
        open(Box::new(want_ball.clone()), Box::new(want_events.clone()))
            .run(rodtrack_io::VecSink::default())
            .unwrap();
        let share = BallShare::default();
        let session = open(Box::new(share.clone()), Box::new(share.clone()));
        let mut stream = Stream::start(session, 4, Some(share)).unwrap();
        let (mut ball, mut events, mut sets) = (Vec::new(), Vec::new(), 0);
        loop {
            match stream.next_timeout(Duration::from_secs(60)) {
                Next::Set(set) => {
                    sets += 1;
                    // Its own frame's rows (both cameras, then the fused one) come last.
                    let own: Vec<_> = set.ball.iter().filter(|b| b.frame == set.frame).collect();
                    assert_eq!(own.len(), 3, "frame {}: {:?}", set.frame, set.ball);
                    assert_eq!(own[2].camera, CameraId::Fused);
                    assert!(set.ball.iter().all(|b| b.frame <= set.frame));
                    ball.extend(set.ball);
                    events.extend(set.events);
                }
                Next::Pending => panic!("no frame set within 60 s"),
                Next::Ended(r) => {
                    r.unwrap();
                    break;
                }
            };
        }
        events.extend(stream.take_final_events());
        assert_eq!(sets, 200);
        assert_eq!(ball, want_ball.rows(), "every ball row once, in order");
        assert_eq!(events, want_events.events());
        assert!(events
            .iter()
            .any(|e| matches!(e.kind, rodtrack_core::ball::events::EventKind::Goal { .. })));
        assert_eq!(stream.dropped_ball_rows(), 0);
    }

    #[test]
    fn a_live_reader_that_is_behind_loses_frame_sets_but_no_event() {
        let cal = goals_calibration();
        // Real time (200 fps): a reader slower than the cameras makes the session drop sets.
        let inputs: Vec<String> = (0..2)
            .map(|c| format!("sim://goals?camera={c}&frames=200&seed=3&realtime=1&prerender=200"))
            .collect();
        let share = BallShare::default();
        let session = Session::open(&cal, &inputs, SessionOptions::default())
            .unwrap()
            .with_ball(&cal, Box::new(share.clone()))
            .unwrap()
            .with_events(&cal, Default::default(), Box::new(share.clone()))
            .unwrap();
        let mut stream = Stream::start(session, 1, Some(share)).unwrap();
        assert!(stream.is_live());
        let mut events = Vec::new();
        loop {
            match stream.next_timeout(Duration::from_secs(60)) {
                Next::Set(set) => {
                    events.extend(set.events);
                    std::thread::sleep(Duration::from_millis(20));
                }
                Next::Pending => panic!("no frame set within 60 s"),
                Next::Ended(r) => {
                    r.unwrap();
                    break;
                }
            }
        }
        events.extend(stream.take_final_events());
        assert!(
            stream.dropped_sets() > 50,
            "{} dropped",
            stream.dropped_sets()
        );
        let kinds: Vec<&str> = events.iter().map(|e| e.kind.name()).collect();
        assert_eq!(kinds, ["shot", "goal"], "{events:?}");
    }

    #[test]
    fn a_recording_streams_every_set_in_order_through_a_small_channel_and_closes() {
        let mut stream = Stream::start(session(12), 1, None).unwrap();
        assert!(!stream.is_live());
        let mut frames = Vec::new();
        let report = loop {
            match stream.next_timeout(Duration::from_secs(30)) {
                Next::Set(set) => {
                    // One set per write: both cameras' rows, then the fused rows.
                    assert!(set.rows.iter().all(|m| m.frame == set.frame));
                    assert_eq!(set.rows.last().unwrap().camera, CameraId::Fused);
                    frames.push(set.frame);
                    // A slow reader: a recording waits for it instead of dropping.
                    std::thread::sleep(Duration::from_millis(5));
                }
                Next::Pending => panic!("no frame set within 30 s"),
                Next::Ended(r) => break r.unwrap(),
            }
        };
        assert_eq!(frames, (0..12).collect::<Vec<u64>>());
        assert_eq!(stream.dropped_sets(), 0);
        assert_eq!(report.pipeline.cameras[0].frames_read, 12);
        assert!(matches!(
            stream.next_timeout(Duration::ZERO),
            Next::Ended(Err(_))
        ));
        assert!(stream.close().is_err(), "closing an ended stream says so");

        // Closed while the session waits on a full channel: it stops at once.
        let mut stream = Stream::start(session(500), 1, None).unwrap();
        assert!(matches!(
            stream.next_timeout(Duration::from_secs(30)),
            Next::Set(_)
        ));
        let t = Instant::now();
        let report = stream.close().unwrap();
        assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
        assert!(report.pipeline.cameras[0].frames_read < 500);
    }
}
