//! The fusion node's ball: the camera nodes' ball rows (`.../cam/<camera>/ball`) put together
//! per frame and fused exactly as in a session ([`BallSets`]), into the caller's ball sink and
//! onto `rodtrack/<table>/fused/ball` (one message per frame: the cameras' rows, then the
//! fused one), and the fused rows for ROS 2 when the node has a ROS 2 domain
//! ([`Ros2BallPublisher`]). A camera that sends no ball rows (its node tracks no ball, or it is lost) is
//! waited for at most the loss time in frames.

use crate::ball_layout::decode_ball;
use crate::net::{fused_key, net_error, RowPublisher};
use crate::ros2::Ros2BallPublisher;
use crate::ZenohError;
use rodtrack_core::ball::events::{BallEvent, EventConfig};
use rodtrack_core::ball::BallRow;
use rodtrack_core::calib::CalibrationFile;
use rodtrack_core::{CameraId, Measurement};
use rodtrack_io::{BallSink, EventSink, IoError};
use rodtrack_sdk::{BallCounts, BallSets, EventCounts};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, RecvTimeoutError, SyncSender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use zenoh::Wait;

/// Logs a line (the fusion's `log` callback).
pub(super) type Log = Arc<dyn Fn(&str) + Send + Sync>;

/// What the ball's thread takes, in the order the camera nodes' messages came.
pub(super) enum Feed {
    /// A camera's ball rows, with their positions' standard deviations (mm).
    Ball(u32, Vec<(BallRow, f64)>),
    /// A camera's measured rod rows of a frame (its `raw` message): the events' shot rod.
    Rods(Vec<Measurement>),
}

/// The ball's subscriber and the thread that fuses its rows.
pub(super) struct BallFusion {
    subscriber: zenoh::pubsub::Subscriber<()>,
    done: Arc<AtomicBool>,
    thread: JoinHandle<Result<(BallCounts, Option<EventCounts>), String>>,
    refused: Arc<AtomicU64>,
    /// The rods' rows for the events (`None` without events).
    rods: Option<SyncSender<Feed>>,
}

/// The ball's events at the fusion node: the rules, and where they go besides
/// `rodtrack/<table>/fused/events`.
pub struct FusionEvents {
    /// The rules (the table's geometry comes from the calibration).
    pub config: EventConfig,
    /// The caller's sink (a file), if any.
    pub sink: Option<Box<dyn EventSink>>,
}

/// What the ball's part of a fusion run did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BallReport {
    /// Rows written, by status.
    pub counts: BallCounts,
    /// Ball messages refused (malformed, of a camera the calibration does not have, a row of
    /// another camera).
    pub refused: u64,
    /// The events written, when they were detected.
    pub events: Option<EventCounts>,
}

/// The events published on `.../fused/events` (one JSON object per event, as a line of
/// `track --events-out`), then the caller's.
struct EventOut {
    publisher: Option<RowPublisher>,
    inner: Option<Box<dyn EventSink>>,
    /// One event's JSON, kept for its capacity.
    text: String,
}

impl EventSink for EventOut {
    fn write(&mut self, events: &[BallEvent]) -> Result<(), IoError> {
        let mut first = match &self.publisher {
            Some(p) => p.publish_events(events, &mut self.text),
            None => Ok(()),
        };
        if let Some(s) = self.inner.as_mut() {
            let r = s.write(events);
            if first.is_ok() {
                first = r;
            }
        }
        first
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.inner.as_mut().map_or(Ok(()), |s| s.flush())
    }
}

/// The fused ball rows published on `.../fused/ball`, a message per frame, and the fused row
/// for ROS 2, then the caller's.
struct Out {
    publisher: Option<RowPublisher>,
    ros2: Option<Ros2BallPublisher>,
    inner: Option<Box<dyn BallSink>>,
}

impl BallSink for Out {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        self.write_sigma(rows, &[])
    }
    fn write_sigma(&mut self, rows: &[BallRow], sigma_mm: &[f64]) -> Result<(), IoError> {
        let mut first = Ok(());
        if let Some(p) = &self.publisher {
            let mut at = 0;
            for run in rows.chunk_by(|a, b| a.frame == b.frame) {
                let s = sigma_mm.get(at..at + run.len()).unwrap_or(&[]);
                at += run.len();
                if let Err(e) = p.publish_ball(run, s) {
                    if first.is_ok() {
                        first = Err(net_error(p.key(), e));
                    }
                }
            }
        }
        if let Some(p) = &self.ros2 {
            for r in rows.iter().filter(|r| r.camera == CameraId::Fused) {
                if let Err(e) = p.publish(r) {
                    if first.is_ok() {
                        first = Err(net_error(p.key(), e));
                    }
                }
            }
        }
        if let Some(s) = self.inner.as_mut() {
            let r = s.write_sigma(rows, sigma_mm);
            if first.is_ok() {
                first = r;
            }
        }
        first
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.inner.as_mut().map_or(Ok(()), |s| s.flush())
    }
}

impl BallFusion {
    /// Subscribes to the ball rows of `cameras` (name, index) of `table`; fuses them with a
    /// lag of `lag_frames`, into `sink` and, with `publish`, onto `.../fused/ball`; with
    /// `ros2`, the fused rows for ROS 2 too. With `events`, the frame sets' rows give the
    /// ball's events (the table of `cal`), published on `.../fused/events` with `publish`;
    /// their shot's rod needs the rods' rows ([`BallFusion::rods`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn start(
        session: &zenoh::Session,
        table: &str,
        cal: &CalibrationFile,
        lag_frames: u64,
        publish: Option<crate::net::WireFormat>,
        ros2: Option<Ros2BallPublisher>,
        sink: Option<Box<dyn BallSink>>,
        events: Option<FusionEvents>,
        log: Log,
    ) -> Result<BallFusion, ZenohError> {
        let cameras: Vec<(String, u32)> = cal
            .cameras
            .iter()
            .filter(|c| c.ball.is_some())
            .map(|c| (c.name.clone(), c.index))
            .collect();
        let publisher = match publish {
            Some(format) => Some(RowPublisher::declare(
                session,
                fused_key(table, "ball"),
                format,
            )?),
            None => None,
        };
        let indices: Vec<u32> = cameras.iter().map(|c| c.1).collect();
        let mut sets = BallSets::new(
            &indices,
            lag_frames,
            Box::new(Out {
                publisher,
                ros2,
                inner: sink,
            }),
        );
        let with_events = events.is_some();
        if let Some(events) = events {
            let publisher = match publish {
                Some(_) => Some(RowPublisher::declare(
                    session,
                    fused_key(table, "events"),
                    crate::net::WireFormat::Json,
                )?),
                None => None,
            };
            let out = EventOut {
                publisher,
                inner: events.sink,
                text: String::with_capacity(256),
            };
            sets = sets
                .with_events(cal, events.config, Box::new(out))
                .map_err(|e| ZenohError::Invalid(e.to_string()))?;
        }
        let (tx, rx) = sync_channel::<Feed>(1024);
        let rods = with_events.then(|| tx.clone());
        let refused = Arc::new(AtomicU64::new(0));
        let prefix = format!("rodtrack/{table}/cam/");
        let (sub_log, sub_refused) = (log.clone(), refused.clone());
        let subscriber = session
            .declare_subscriber(format!("{prefix}*/ball"))
            .callback(move |sample| {
                let key = sample.key_expr().as_str();
                let name = key
                    .strip_prefix(&prefix)
                    .and_then(|k| k.strip_suffix("/ball"))
                    .unwrap_or(key);
                let refuse = |why: String| {
                    if sub_refused.fetch_add(1, Ordering::Relaxed) < 10 {
                        sub_log(&format!("fusion: ball message on {key} refused: {why}"));
                    }
                };
                let Some(&(_, index)) = cameras.iter().find(|c| c.0 == name) else {
                    return refuse(format!(
                        "camera {name:?} is not one of the calibration's with a ball"
                    ));
                };
                let m = match decode_ball(&sample.payload().to_bytes()) {
                    Ok(m) => m,
                    Err(e) => return refuse(e.to_string()),
                };
                if let Some(r) = m
                    .rows
                    .iter()
                    .find(|r| r.0.camera != CameraId::Camera(index))
                {
                    return refuse(format!(
                        "a row of camera {} where the calibration has camera {index} ({name})",
                        r.0.camera
                    ));
                }
                if tx.try_send(Feed::Ball(index, m.rows)).is_err() {
                    refuse("the ball fusion is behind: queue full, message dropped".into());
                }
            })
            .wait()
            .map_err(|e| ZenohError::zenoh("declaring the ball subscriber", e))?;
        let done = Arc::new(AtomicBool::new(false));
        let stop = done.clone();
        let thread = std::thread::Builder::new()
            .name("rodtrack-fusion-ball".into())
            .spawn(move || {
                let take = |sets: &mut BallSets, feed: Feed| match feed {
                    Feed::Ball(camera, rows) => {
                        for (row, sigma) in rows {
                            sets.push(camera, row, sigma);
                        }
                    }
                    Feed::Rods(rows) => sets.push_rods(&rows),
                };
                loop {
                    match rx.recv_timeout(Duration::from_millis(20)) {
                        Ok(feed) => take(&mut sets, feed),
                        Err(RecvTimeoutError::Timeout) if !stop.load(Ordering::SeqCst) => {}
                        Err(_) => break,
                    }
                }
                // What came before the stop, then the rest written.
                while let Ok(feed) = rx.try_recv() {
                    take(&mut sets, feed);
                }
                let counts = sets.finish().map_err(|e| e.to_string())?;
                let events = sets.finish_events().map_err(|e| e.to_string())?;
                Ok((counts, events))
            })
            .map_err(|e| ZenohError::Invalid(format!("cannot start the ball thread: {e}")))?;
        Ok(BallFusion {
            subscriber,
            done,
            thread,
            refused,
            rods,
        })
    }

    /// Where the fusion node's `raw` subscriber hands each camera's measured rod rows, when
    /// the events are detected (their shot's rod), in the order the messages came.
    pub(super) fn rods(&self) -> Option<SyncSender<Feed>> {
        self.rods.clone()
    }

    /// Stops, writes what is pending, and reports (or the sink's first error).
    pub(super) fn finish(self) -> Result<BallReport, ZenohError> {
        let refused = self.refused.clone();
        drop(self.subscriber);
        drop(self.rods);
        self.done.store(true, Ordering::SeqCst);
        let (counts, events) = self
            .thread
            .join()
            .map_err(|_| ZenohError::Invalid("the ball thread panicked".into()))?
            .map_err(ZenohError::Invalid)?;
        Ok(BallReport {
            counts,
            refused: refused.load(Ordering::Relaxed),
            events,
        })
    }
}
