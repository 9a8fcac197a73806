//! A camera node: one camera's SDK session publishing on the network.
//!
//! [`CameraNode::sink`] publishes the camera's filtered rows (what `track --out` writes) on
//! `.../rows`; [`CameraNode::hooks`] wraps the caller's hooks and publishes the measured rows
//! (the fusion's input, [`rodtrack_sdk::Hooks::camera_rows`]) on `.../raw` and the session's
//! counters on `.../status` once a second; [`CameraNode::end`] says the run ended. With a
//! preview rate, the hooks also publish a downscaled image of the camera's latest frame on
//! `.../preview` that many times per second (module `camera_preview`).
//! [`CameraNode::ball_sink`] publishes the camera's ball rows on `.../ball`, and
//! [`CameraNode::event_sink`] the ball's events detected from this camera on `.../events`. With a ROS 2
//! domain the filtered rows also go out as `sensor_msgs/msg/JointState`, and the ball rows as
//! `geometry_msgs/msg/PointStamped` and `Vector3Stamped` ([`crate::ros2`]).

use crate::camera_preview::PreviewFeed;
use crate::layout::{camera_bit, Header, Kind};
use crate::net::{camera_key, check_chunk, net_error, NetworkOptions, RowPublisher};
use crate::ros2::{Ros2BallPublisher, Ros2Names, Ros2Node, Ros2Publisher};
use crate::ZenohError;
use rodtrack_core::ball::events::BallEvent;
use rodtrack_core::ball::BallRow;
use rodtrack_core::CameraId;
use rodtrack_core::{CameraPipeline, Measurement, Timestamp};
use rodtrack_io::{BallSink, EventSink, FrameBuffer, FrameMeta, IoError, MeasurementSink};
use rodtrack_sdk::{Hooks, Progress};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// One camera on the network; see the module documentation.
pub struct CameraNode {
    // Declared before the session so that they are undeclared first.
    rows: RowPublisher,
    raw: RowPublisher,
    ball: RowPublisher,
    events: RowPublisher,
    status: RowPublisher,
    ros2: Option<Ros2Publisher>,
    ros2_ball: Option<Ros2BallPublisher>,
    preview: Option<PreviewFeed>,
    _session: zenoh::Session,
    table: String,
    name: String,
    index: u32,
    started: Instant,
    last_frame: AtomicU64,
    last_timestamp_ns: AtomicU64,
    frames_published: AtomicU64,
    publish_errors: AtomicU64,
}

impl CameraNode {
    /// Opens the zenoh session and declares the camera's publishers; `name` and `index` are
    /// the camera's in the calibration; `preview_fps`: preview frames per second on
    /// `.../preview` (0: none); `ros2_domain`: also publish the filtered rows for ROS 2 over
    /// rmw_zenoh in that domain ([`crate::ros2`], topic
    /// `/rodtrack/<table>/cam/<camera>/joint_states`), and, with `ball_diameter_mm` (the
    /// ball's, when the node publishes its ball rows), the ball rows on `.../ball` and
    /// `.../ball/velocity` of that node.
    pub fn open(
        net: &NetworkOptions,
        name: &str,
        index: u32,
        preview_fps: f64,
        ros2_domain: Option<u32>,
        ball_diameter_mm: Option<f64>,
    ) -> Result<Arc<CameraNode>, ZenohError> {
        let table = net.table()?.to_string();
        check_chunk("camera name", name)?;
        let ros2_names = ros2_domain
            .map(|d| Ros2Names::camera(d, &table, name))
            .transpose()?;
        let session = net.open()?;
        let decl = |what: &str, format| {
            RowPublisher::declare(&session, camera_key(&table, name, what), format)
        };
        let preview = if preview_fps == 0.0 {
            None
        } else {
            Some(PreviewFeed::start(
                &session,
                camera_key(&table, name, "preview"),
                index,
                preview_fps,
            )?)
        };
        let ros2_node = match &ros2_names {
            Some(n) => Some(Ros2Node::declare(&session, n)?),
            None => None,
        };
        let ros2 = match &ros2_node {
            Some(node) => Some(Ros2Publisher::declare(&session, node)?),
            None => None,
        };
        let ros2_ball = match (&ros2_node, ball_diameter_mm) {
            (Some(node), Some(d)) => Some(Ros2BallPublisher::declare(&session, node, d)?),
            _ => None,
        };
        Ok(Arc::new(CameraNode {
            ros2,
            ros2_ball,
            rows: decl("rows", net.format)?,
            raw: decl("raw", net.format)?,
            ball: decl("ball", net.format)?,
            events: decl("events", crate::net::WireFormat::Json)?,
            status: decl("status", crate::net::WireFormat::Json)?,
            preview,
            _session: session,
            table,
            name: name.to_string(),
            index,
            started: Instant::now(),
            last_frame: AtomicU64::new(0),
            last_timestamp_ns: AtomicU64::new(0),
            frames_published: AtomicU64::new(0),
            publish_errors: AtomicU64::new(0),
        }))
    }

    /// The key expression of the filtered rows.
    pub fn rows_key(&self) -> &str {
        self.rows.key()
    }

    /// A sink that publishes the rows written to it on `.../rows`.
    pub fn sink(self: &Arc<Self>) -> CameraRowsSink {
        CameraRowsSink { node: self.clone() }
    }

    /// A ball sink that publishes the camera's ball rows, with their uncertainty, on
    /// `.../ball` (one message per write: a frame's rows).
    pub fn ball_sink(self: &Arc<Self>) -> CameraBallSink {
        CameraBallSink { node: self.clone() }
    }

    /// An event sink that publishes the ball's events detected from this camera alone on
    /// `.../events`, each as one JSON message (its line of `--events-out`), as the fusion node
    /// does on `.../fused/events`.
    pub fn event_sink(self: &Arc<Self>) -> CameraEventSink {
        CameraEventSink {
            node: self.clone(),
            text: String::new(),
        }
    }

    /// Hooks that publish the measured rows and the status, then call `inner`.
    pub fn hooks(self: &Arc<Self>, inner: Arc<dyn Hooks>) -> Arc<CameraNodeHooks> {
        Arc::new(CameraNodeHooks {
            node: self.clone(),
            inner,
        })
    }

    /// Messages that could not be published.
    pub fn publish_errors(&self) -> u64 {
        self.publish_errors.load(Ordering::Relaxed)
    }

    /// Publishes the end of the run (an `end` message on `.../raw`: the fusion stops waiting
    /// for this camera) and a last status.
    pub fn end(&self) -> Result<(), ZenohError> {
        let header = Header {
            kind: Kind::End,
            seq: 0,
            frame: self.last_frame.load(Ordering::Relaxed),
            timestamp_ns: Timestamp(self.last_timestamp_ns.load(Ordering::Relaxed)),
            complete: true,
            cameras: camera_bit(self.index),
        };
        self.raw.publish(header, &[])?;
        self.status.publish_text(&self.status_json("ended", None))
    }

    fn status_json(&self, state: &str, p: Option<&Progress>) -> String {
        let mut v = serde_json::json!({
            "version": crate::layout::VERSION,
            "table": self.table,
            "camera": self.name,
            "index": self.index,
            "state": state,
            "frame": self.last_frame.load(Ordering::Relaxed),
            "timestamp_ns": self.last_timestamp_ns.load(Ordering::Relaxed),
            "frames_published": self.frames_published.load(Ordering::Relaxed),
            "publish_errors": self.publish_errors(),
            "uptime_s": self.started.elapsed().as_secs_f64(),
            "previews_published": self.preview.as_ref().map_or(0, PreviewFeed::published),
            "preview_errors": self.preview.as_ref().map_or(0, PreviewFeed::errors),
        });
        if let (Some(p), Some(o)) = (p, v.as_object_mut()) {
            let secs = p.elapsed.as_secs_f64().max(1e-9);
            o.insert("frames".into(), p.frames.into());
            o.insert("frames_per_s".into(), (p.frames as f64 / secs).into());
            o.insert("dropped".into(), p.dropped.into());
            o.insert("bad".into(), p.bad.into());
            let us = p.tracker_time.as_secs_f64() * 1e6 / p.measured.max(1) as f64;
            o.insert("tracker_us_per_frame".into(), us.into());
        }
        v.to_string()
    }

    fn count(&self, r: Result<(), ZenohError>) -> Result<(), ZenohError> {
        if r.is_err() {
            self.publish_errors.fetch_add(1, Ordering::Relaxed);
        }
        r
    }
}

/// Publishes the rows written to it on the camera's `.../rows` (see [`CameraNode::sink`]).
pub struct CameraRowsSink {
    node: Arc<CameraNode>,
}

impl MeasurementSink for CameraRowsSink {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        let n = &self.node;
        let r = n
            .rows
            .publish_runs(Kind::CameraRows, true, camera_bit(n.index), rows);
        let rows_result = n.count(r).map_err(|e| net_error(n.rows.key(), e));
        // After the node's own rows: ROS 2 subscribers do not hold up the fusion's input.
        // Both are tried and counted; the rows' error is reported first.
        let ros2_result = match &n.ros2 {
            Some(p) => n
                .count(p.publish_frames(rows))
                .map_err(|e| net_error(p.key(), e)),
            None => Ok(()),
        };
        rows_result.and(ros2_result)
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

/// Publishes the ball rows written to it on the camera's `.../ball` (see
/// [`CameraNode::ball_sink`]).
pub struct CameraBallSink {
    node: Arc<CameraNode>,
}

impl BallSink for CameraBallSink {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        self.write_sigma(rows, &[])
    }
    fn write_sigma(&mut self, rows: &[BallRow], sigma_mm: &[f64]) -> Result<(), IoError> {
        let n = &self.node;
        let result = n
            .count(n.ball.publish_ball(rows, sigma_mm))
            .map_err(|e| net_error(n.ball.key(), e));
        // After rodtrack's own ball rows, as the joint states after the rows.
        let Some(p) = &n.ros2_ball else {
            return result;
        };
        let mut ros2_result = Ok(());
        for r in rows
            .iter()
            .filter(|r| r.camera == CameraId::Camera(n.index))
        {
            if let Err(e) = n.count(p.publish(r).map(|_| ())) {
                ros2_result = ros2_result.and(Err(net_error(p.key(), e)));
            }
        }
        result.and(ros2_result)
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

/// Publishes the events written to it on the camera's `.../events` (see
/// [`CameraNode::event_sink`]).
pub struct CameraEventSink {
    node: Arc<CameraNode>,
    /// One event's JSON, kept for its capacity.
    text: String,
}

impl EventSink for CameraEventSink {
    fn write(&mut self, events: &[BallEvent]) -> Result<(), IoError> {
        let n = &self.node;
        let r = n.events.publish_events(events, &mut self.text);
        if r.is_err() {
            n.publish_errors.fetch_add(1, Ordering::Relaxed);
        }
        r
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

/// The node's hooks (see [`CameraNode::hooks`]).
pub struct CameraNodeHooks {
    node: Arc<CameraNode>,
    inner: Arc<dyn Hooks>,
}

impl Hooks for CameraNodeHooks {
    fn measured(&self, camera: u32, meta: &FrameMeta, rows: &[Measurement], pipe: &CameraPipeline) {
        self.inner.measured(camera, meta, rows, pipe);
    }
    fn camera_rows(&self, camera: u32, meta: &FrameMeta, rows: &[Measurement]) {
        let n = &self.node;
        let header = Header {
            kind: Kind::CameraRaw,
            seq: 0,
            frame: meta.frame_id,
            timestamp_ns: meta.timestamp_ns,
            complete: true,
            cameras: camera_bit(n.index),
        };
        n.last_frame.store(meta.frame_id, Ordering::Relaxed);
        n.last_timestamp_ns
            .store(meta.timestamp_ns.as_nanos(), Ordering::Relaxed);
        if n.count(n.raw.publish(header, rows)).is_ok() {
            n.frames_published.fetch_add(1, Ordering::Relaxed);
        }
        self.inner.camera_rows(camera, meta, rows);
    }
    fn uses_frames(&self) -> bool {
        self.node.preview.is_some() || self.inner.uses_frames()
    }
    fn frame(&self, camera: u32, buf: &mut FrameBuffer) {
        // Before the inner hooks: they may swap the pixels out (the local console).
        if let Some(p) = &self.node.preview {
            p.offer(buf);
        }
        self.inner.frame(camera, buf);
    }
    fn bad_frame(&self, camera: &str, frame_id: u64, error: &str, count: u64) {
        self.inner.bad_frame(camera, frame_id, error, count);
    }
    fn warning(&self, text: &str, count: u64) {
        self.inner.warning(text, count);
    }
    fn progress(&self, p: &Progress) {
        let n = &self.node;
        let _ = n.count(n.status.publish_text(&n.status_json("running", Some(p))));
        self.inner.progress(p);
    }
}
