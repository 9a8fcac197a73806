//! A session run in a background thread, its frame sets handed over through a bounded
//! channel: what `rodtrack.open` iterates.
//!
//! The session writes one frame set per sink write (every camera's rows in camera order, then
//! the fused rows). Recordings never drop: when the channel is full the session waits for the
//! reader. Live sources never wait for the reader: a frame set that finds the channel full is
//! dropped and counted ([`Stream::dropped_sets`]), so that the cameras and the temporal filter
//! keep real time whatever the reader does.

use rodtrack_core::Measurement;
use rodtrack_io::runtime::WriteMode;
use rodtrack_io::{IoError, MeasurementSink};
use rodtrack_sdk::{pipeline_config, RunReport, SdkError, Session};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// One frame set: the rows of every camera for one frame id, then the fused rows.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameSet {
    /// The frame id.
    pub frame: u64,
    /// The rows, in the order a file gets them.
    pub rows: Vec<Measurement>,
}

/// The sink of a streamed session: each write is one frame set, sent to the reader.
struct SetSender {
    tx: SyncSender<FrameSet>,
    live: bool,
    dropped: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
}

impl MeasurementSink for SetSender {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        let Some(first) = rows.first() else {
            return Ok(());
        };
        let set = FrameSet {
            frame: first.frame,
            rows: rows.to_vec(),
        };
        let gone = if self.live {
            match self.tx.try_send(set) {
                Ok(()) => false,
                Err(TrySendError::Full(_)) => {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
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
}

impl Stream {
    /// Starts `session` in a thread, its frame sets through a channel of `capacity` sets
    /// (at least 1). The session's pipeline settings become one write per frame set, the
    /// rest as [`pipeline_config`] chooses for its sources.
    pub fn start(mut session: Session, capacity: usize) -> Result<Stream, SdkError> {
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
        })
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

    #[test]
    fn a_recording_streams_every_set_in_order_through_a_small_channel_and_closes() {
        let mut stream = Stream::start(session(12), 1).unwrap();
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
        let mut stream = Stream::start(session(500), 1).unwrap();
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
