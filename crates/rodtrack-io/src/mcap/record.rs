//! [`McapRecorder`]: rodtrack's rows, joint states and frames in an MCAP file, as JSON
//! messages with JSON schemas (what Foxglove and Rerun read without plugins).
//!
//! Channels (`<table>`: the table's name; `<camera>`: the camera's name in the calibration):
//!
//! | topic | schema | what |
//! |---|---|---|
//! | `/rodtrack/<table>/cam/<camera>/rows` | `rodtrack.Rows` | the camera's rows of one frame |
//! | `/rodtrack/<table>/fused/rows` | `rodtrack.Rows` | the fused rows of one frame set |
//! | `/rodtrack/<table>/cam/<camera>/joints`, `/rodtrack/<table>/fused/joints` | `rodtrack.JointState` | the same rows as joints: `rod<k>_slide` (m, m/s) and `rod<k>_turn` (rad, rad/s) |
//! | `/rodtrack/<table>/cam/<camera>/image` | `foxglove.RawImage` | downscaled grey frames, when asked for |
//! | `/rodtrack/<table>/cam/<camera>/ball`, `/rodtrack/<table>/fused/ball` | `rodtrack.Ball` | the ball's rows, one per frame ([`super::ball`], through [`McapRecorder::ball_sink`]) |
//! | `/rodtrack/<table>/fused/events` | `rodtrack.Event` | the ball's events, one per message, as decided ([`super::events`], through [`McapRecorder::event_sink`]) |
//!
//! Every message's log time and publish time are the frame's capture timestamp, ns. Each
//! channel's metadata names its `table` and `camera`.
//!
//! With [`Profile::Ros2`] the file is a ROS 2 bag instead (MCAP profile `ros2`, what rosbag2
//! and rosbags read): only `sensor_msgs/msg/JointState` messages in CDR (schema encoding
//! `ros2msg`), on `/rodtrack/<table>/cam/<camera>/joint_states` and
//! `/rodtrack/<table>/fused/joint_states` (names made ROS names by
//! [`super::ros2::ros_name_token`]), and the ball as `geometry_msgs/msg/PointStamped` and
//! `Vector3Stamped` on `.../ball` and `.../ball/velocity`, each channel with its
//! `offered_qos_profiles`. The profile admits no other encoding, so the rows, frames and
//! events are not in that file.

use super::ball::{BALL_SCHEMA, BALL_SCHEMA_NAME};
use super::events::{EVENT_SCHEMA, EVENT_SCHEMA_NAME};
use super::ros2::{
    ros_name_token, JointState, JOINT_STATE_MSGDEF, JOINT_STATE_QOS, JOINT_STATE_SCHEMA_NAME,
    POINT_STAMPED_MSGDEF, POINT_STAMPED_SCHEMA_NAME, VECTOR3_STAMPED_MSGDEF,
    VECTOR3_STAMPED_SCHEMA_NAME,
};
use super::write::{ChunkLimits, Compression, McapWriter, WriteSummary};
use crate::IoError;
use crate::MeasurementSink;
use rodtrack_core::{CameraId, FrameView, Measurement, Status};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// The rows' schema name.
pub const ROWS_SCHEMA_NAME: &str = "rodtrack.Rows";
/// The joint states' schema name.
pub const JOINTS_SCHEMA_NAME: &str = "rodtrack.JointState";
/// The frames' schema name (Foxglove's raw image).
pub const IMAGE_SCHEMA_NAME: &str = "foxglove.RawImage";

/// The JSON schema of a rows message (`rodtrack.Rows`).
pub const ROWS_SCHEMA: &str = r#"{
  "title": "rodtrack.Rows",
  "description": "The rows of one camera frame, or the fused rows of one frame set (docs/network.md). Lengths in mm, angles in rad, times in ns.",
  "type": "object",
  "properties": {
    "frame": {"type": "integer", "minimum": 0, "description": "The frame id (a fused set: its frame id)"},
    "timestamp_ns": {"type": "integer", "minimum": 0, "description": "Capture timestamp, ns (also the message's log time)"},
    "camera": {"type": "string", "description": "The camera's name in the calibration, or \"fused\""},
    "camera_index": {"type": "integer", "minimum": 0, "description": "The camera's index in the calibration (absent on fused rows)"},
    "rows": {
      "type": "array",
      "items": {
        "type": "object",
        "properties": {
          "rod": {"type": "integer", "minimum": 0, "description": "Rod id"},
          "position_mm": {"type": "number", "description": "Translation along the rod from its calibrated zero, mm"},
          "angle_rad": {"type": "number", "description": "Rotation about the rod in [0, 2 pi), rad"},
          "angle_unwrapped_rad": {"type": "number", "description": "Rotation counting whole turns, rad"},
          "velocity_mm_s": {"type": "number", "description": "Translation velocity, mm/s"},
          "angular_velocity_rad_s": {"type": "number", "description": "Angular velocity, rad/s"},
          "quality": {"type": "number", "minimum": 0, "maximum": 1, "description": "Confidence"},
          "status": {"type": "string", "enum": ["ok", "not_found", "occluded", "out_of_view", "predicted", "lost", "bad_frame", "conflict"]},
          "turns_known": {"type": "boolean", "description": "Whether angle_unwrapped_rad counts every whole turn"}
        },
        "required": ["rod", "position_mm", "angle_rad", "angle_unwrapped_rad", "velocity_mm_s", "angular_velocity_rad_s", "quality", "status", "turns_known"]
      }
    }
  },
  "required": ["frame", "timestamp_ns", "camera", "rows"]
}"#;

/// The JSON schema of a joint state message (`rodtrack.JointState`, shaped as ROS 2
/// `sensor_msgs/msg/JointState`).
pub const JOINTS_SCHEMA: &str = r#"{
  "title": "rodtrack.JointState",
  "description": "The rods as joints, shaped as ROS 2 sensor_msgs/msg/JointState: two joints per rod, rod<k>_slide (m, m/s) and rod<k>_turn (rad, rad/s, whole turns counted). Only rods whose row has a value (status ok, predicted or conflict).",
  "type": "object",
  "properties": {
    "header": {
      "type": "object",
      "properties": {
        "stamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nanosec": {"type": "integer"}}},
        "frame_id": {"type": "string"}
      }
    },
    "name": {"type": "array", "items": {"type": "string"}},
    "position": {"type": "array", "items": {"type": "number"}},
    "velocity": {"type": "array", "items": {"type": "number"}},
    "effort": {"type": "array", "items": {"type": "number"}}
  },
  "required": ["header", "name", "position", "velocity", "effort"]
}"#;

/// The JSON schema of a frame (`foxglove.RawImage`, its fields as Foxglove defines them).
pub const IMAGE_SCHEMA: &str = r#"{
  "title": "foxglove.RawImage",
  "description": "A raw image",
  "type": "object",
  "properties": {
    "timestamp": {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
    "frame_id": {"type": "string"},
    "width": {"type": "integer", "minimum": 0},
    "height": {"type": "integer", "minimum": 0},
    "encoding": {"type": "string"},
    "step": {"type": "integer", "minimum": 0},
    "data": {"type": "string", "contentEncoding": "base64"}
  }
}"#;

/// What kind of file a recording is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Profile {
    /// rodtrack's (no MCAP profile): rows and joints as JSON, frames as `foxglove.RawImage`.
    #[default]
    Rodtrack,
    /// A ROS 2 bag (MCAP profile `ros2`): joint states in CDR only.
    Ros2,
}

/// What a recording holds and how it is cut into chunks.
#[derive(Debug, Clone, Default)]
pub struct RecordOptions {
    /// What kind of file.
    pub profile: Profile,
    /// How chunks are compressed.
    pub compression: Compression,
    /// The table's name in the topics.
    pub table: String,
    /// The cameras' names by index (a camera not listed is named by its index).
    pub cameras: Vec<(u32, String)>,
    /// When chunks are written out.
    pub chunk: ChunkLimits,
    /// Frames recorded per second per camera (0: none).
    pub frames_per_s: f64,
}

/// Records rows (through [`McapRecorder::sink`]) and frames (through
/// [`McapRecorder::record_frame`]) into one MCAP file; [`McapRecorder::finish`] ends it.
/// Clones share the file. Dropping the last clone unfinished finishes the file, ignoring
/// errors.
#[derive(Clone)]
pub struct McapRecorder {
    inner: Arc<Mutex<Inner>>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Topic {
    Rows(CameraId),
    Joints(CameraId),
    JointStates(CameraId),
    Image(u32),
    /// The ball's rows ([`super::ball`]).
    Ball(CameraId),
    /// The ball's place in a ROS 2 bag.
    BallPoint(CameraId),
    /// The ball's velocity in a ROS 2 bag.
    BallVelocity(CameraId),
    /// The ball's events ([`super::events`]).
    Events,
}

struct Channel {
    id: u16,
    sequence: u32,
}

pub(super) struct Inner {
    writer: McapWriter<File>,
    path: PathBuf,
    pub(super) options: RecordOptions,
    schemas: BTreeMap<&'static str, u16>,
    /// The channels added, few: searched in order.
    channels: Vec<(Topic, Channel)>,
    /// The last frame recorded per camera, ns.
    last_frame_ns: BTreeMap<u32, u64>,
    pub(super) json: Vec<u8>,
    pub(super) cdr: Vec<u8>,
    /// The ball's diameter, mm, in its channels' metadata (`ball_diameter_mm`).
    pub(super) ball_diameter_mm: Option<f64>,
    groups: Vec<(CameraId, u64, u64)>,
}

impl McapRecorder {
    /// Creates (truncates) the file `path`.
    pub fn create(path: &Path, options: RecordOptions) -> Result<Self, IoError> {
        let f = File::create(path).map_err(|e| IoError::file(path, "cannot create", e))?;
        let library = concat!("rodtrack ", env!("CARGO_PKG_VERSION"));
        let profile = match options.profile {
            Profile::Rodtrack => "",
            Profile::Ros2 => "ros2",
        };
        let writer = McapWriter::new(
            f,
            path,
            profile,
            library,
            options.chunk,
            options.compression,
        )?;
        Ok(McapRecorder {
            inner: Arc::new(Mutex::new(Inner {
                writer,
                path: path.to_path_buf(),
                options,
                schemas: BTreeMap::new(),
                channels: Vec::new(),
                last_frame_ns: BTreeMap::new(),
                json: Vec::with_capacity(4096),
                cdr: Vec::with_capacity(1024),
                ball_diameter_mm: None,
                groups: Vec::new(),
            })),
        })
    }

    pub(super) fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A sink whose rows are recorded.
    pub fn sink(&self) -> McapSink {
        McapSink {
            recorder: self.clone(),
        }
    }

    /// Whether frames are recorded at all ([`RecordOptions::frames_per_s`] above 0, not a
    /// ROS 2 bag).
    pub fn wants_frames(&self) -> bool {
        let o = &self.lock().options;
        o.frames_per_s > 0.0 && o.frames_per_s.is_finite() && o.profile == Profile::Rodtrack
    }

    /// Whether a frame of `camera` captured at `timestamp_ns` is to be recorded (at most
    /// [`RecordOptions::frames_per_s`] per camera).
    pub fn wants_frame(&self, camera: u32, timestamp_ns: u64) -> bool {
        let inner = self.lock();
        let fps = inner.options.frames_per_s;
        if fps <= 0.0 || !fps.is_finite() {
            return false;
        }
        let period_ns = (1e9 / fps) as u64;
        match inner.last_frame_ns.get(&camera) {
            Some(&last) => timestamp_ns >= last.saturating_add(period_ns) || timestamp_ns < last,
            None => true,
        }
    }

    /// Records a grey frame of `camera` (`mono8`, `width` x `height`, rows of `width` bytes)
    /// captured at `timestamp_ns`.
    pub fn record_frame(
        &self,
        camera: u32,
        timestamp_ns: u64,
        width: usize,
        height: usize,
        grey: &[u8],
    ) -> Result<(), IoError> {
        let mut inner = self.lock();
        if inner.options.profile == Profile::Ros2 {
            return Err(inner.bad("a ROS 2 bag holds no frames".into()));
        }
        if grey.len() != width * height {
            let reason = format!(
                "a {width}x{height} frame of {} bytes cannot be recorded",
                grey.len()
            );
            return Err(inner.bad(reason));
        }
        inner.last_frame_ns.insert(camera, timestamp_ns);
        let name = inner.camera_name(CameraId::Camera(camera));
        let mut json = std::mem::take(&mut inner.json);
        json.clear();
        let _ = write!(
            json,
            "{{\"timestamp\":{{\"sec\":{},\"nsec\":{}}},\"frame_id\":{},\"width\":{width},\"height\":{height},\"encoding\":\"mono8\",\"step\":{width},\"data\":\"",
            timestamp_ns / 1_000_000_000,
            timestamp_ns % 1_000_000_000,
            json_string(&name),
        );
        push_base64(&mut json, grey);
        json.extend_from_slice(b"\"}");
        let r = inner.message(Topic::Image(camera), timestamp_ns, &json);
        inner.json = json;
        r
    }

    /// Records `view` downscaled by a whole factor to at most `max_side_px` on its longer
    /// side, as grey (Bayer 2x2 blocks and RGB averaged to luminance).
    pub fn record_view(
        &self,
        camera: u32,
        timestamp_ns: u64,
        view: &FrameView<'_>,
        max_side_px: usize,
    ) -> Result<(), IoError> {
        let (w, h) = (view.width(), view.height());
        let factor = w.max(h).div_ceil(max_side_px.max(1)).max(1);
        let (ow, oh) = (w / factor, h / factor);
        let mut grey = Vec::with_capacity(ow * oh);
        for y in 0..oh {
            for x in 0..ow {
                let v = view.luma_node((x * factor) as isize, (y * factor) as isize);
                grey.push(v.round().clamp(0.0, 255.0) as u8);
            }
        }
        self.record_frame(camera, timestamp_ns, ow, oh, &grey)
    }

    /// Writes the open chunk, the summary and the footer. Later rows are refused.
    pub fn finish(&self) -> Result<WriteSummary, IoError> {
        self.lock().writer.finish()
    }

    /// The file's path.
    pub fn path(&self) -> PathBuf {
        self.lock().path.clone()
    }
}

/// Escapes a string for JSON.
pub(super) fn json_string(s: &str) -> String {
    serde_json::Value::from(s).to_string()
}

const BASE64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Appends `b` in base64 (RFC 4648, with padding).
fn push_base64(out: &mut Vec<u8>, b: &[u8]) {
    for c in b.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(c.get(1).copied().unwrap_or(0)) << 8)
            | u32::from(c.get(2).copied().unwrap_or(0));
        for k in 0..4 {
            if k <= c.len() {
                out.push(BASE64[(n >> (18 - 6 * k) & 63) as usize]);
            } else {
                out.push(b'=');
            }
        }
    }
}

impl Inner {
    fn bad(&self, reason: String) -> IoError {
        IoError::Recording {
            path: self.path.clone(),
            reason,
        }
    }

    pub(super) fn camera_name(&self, camera: CameraId) -> String {
        match camera {
            CameraId::Fused => "fused".into(),
            CameraId::Camera(k) => self
                .options
                .cameras
                .iter()
                .find(|(i, _)| *i == k)
                .map_or_else(|| k.to_string(), |(_, n)| n.clone()),
        }
    }

    pub(super) fn topic_name(&self, topic: Topic) -> String {
        let t = if self.options.table.is_empty() {
            "default"
        } else {
            &self.options.table
        };
        let prefix = |c: CameraId| match c {
            CameraId::Fused => format!("/rodtrack/{t}/fused"),
            c => format!("/rodtrack/{t}/cam/{}", self.camera_name(c)),
        };
        let ros_prefix = |c: CameraId| match c {
            CameraId::Fused => format!("/rodtrack/{}/fused", ros_name_token(t)),
            c => format!(
                "/rodtrack/{}/cam/{}",
                ros_name_token(t),
                ros_name_token(&self.camera_name(c))
            ),
        };
        match topic {
            Topic::Rows(c) => format!("{}/rows", prefix(c)),
            Topic::Joints(c) => format!("{}/joints", prefix(c)),
            Topic::JointStates(c) => format!("{}/joint_states", ros_prefix(c)),
            Topic::Image(c) => format!("{}/image", prefix(CameraId::Camera(c))),
            Topic::Ball(c) => format!("{}/ball", prefix(c)),
            Topic::BallPoint(c) => format!("{}/ball", ros_prefix(c)),
            Topic::BallVelocity(c) => format!("{}/ball/velocity", ros_prefix(c)),
            Topic::Events => format!("{}/events", prefix(CameraId::Fused)),
        }
    }

    /// The channel of `topic`, added (with its schema) when first used.
    fn channel(&mut self, topic: Topic) -> Result<&mut Channel, IoError> {
        if !self.channels.iter().any(|(t, _)| *t == topic) {
            let (schema_name, schema, encoding) = match topic {
                Topic::Rows(_) => (ROWS_SCHEMA_NAME, ROWS_SCHEMA, "jsonschema"),
                Topic::Joints(_) => (JOINTS_SCHEMA_NAME, JOINTS_SCHEMA, "jsonschema"),
                Topic::JointStates(_) => (JOINT_STATE_SCHEMA_NAME, JOINT_STATE_MSGDEF, "ros2msg"),
                Topic::Image(_) => (IMAGE_SCHEMA_NAME, IMAGE_SCHEMA, "jsonschema"),
                Topic::Ball(_) => (BALL_SCHEMA_NAME, BALL_SCHEMA, "jsonschema"),
                Topic::Events => (EVENT_SCHEMA_NAME, EVENT_SCHEMA, "jsonschema"),
                Topic::BallPoint(_) => (POINT_STAMPED_SCHEMA_NAME, POINT_STAMPED_MSGDEF, "ros2msg"),
                Topic::BallVelocity(_) => (
                    VECTOR3_STAMPED_SCHEMA_NAME,
                    VECTOR3_STAMPED_MSGDEF,
                    "ros2msg",
                ),
            };
            let schema_id = match self.schemas.get(schema_name) {
                Some(&id) => id,
                None => {
                    let id = self
                        .writer
                        .add_schema(schema_name, encoding, schema.as_bytes())?;
                    self.schemas.insert(schema_name, id);
                    id
                }
            };
            let name = self.topic_name(topic);
            let table = if self.options.table.is_empty() {
                "default".to_string()
            } else {
                self.options.table.clone()
            };
            let camera = match topic {
                Topic::Rows(c)
                | Topic::Joints(c)
                | Topic::JointStates(c)
                | Topic::Ball(c)
                | Topic::BallPoint(c)
                | Topic::BallVelocity(c) => self.camera_name(c),
                Topic::Image(c) => self.camera_name(CameraId::Camera(c)),
                Topic::Events => self.camera_name(CameraId::Fused),
            };
            let mut metadata = vec![("table", table.as_str()), ("camera", camera.as_str())];
            let diameter = self.ball_diameter_mm.map(|d| d.to_string());
            if let (Topic::Ball(_) | Topic::BallPoint(_) | Topic::BallVelocity(_), Some(d)) =
                (topic, &diameter)
            {
                metadata.push(("ball_diameter_mm", d.as_str()));
            }
            let message_encoding = match topic {
                Topic::JointStates(_) | Topic::BallPoint(_) | Topic::BallVelocity(_) => {
                    metadata.insert(0, ("offered_qos_profiles", JOINT_STATE_QOS));
                    "cdr"
                }
                _ => "json",
            };
            let id = self
                .writer
                .add_channel(schema_id, &name, message_encoding, &metadata)?;
            self.channels.push((topic, Channel { id, sequence: 0 }));
        }
        self.channels
            .iter_mut()
            .find(|(t, _)| *t == topic)
            .map(|(_, c)| c)
            .ok_or_else(|| IoError::Config("a channel just added is missing".into()))
    }

    pub(super) fn message(
        &mut self,
        topic: Topic,
        time_ns: u64,
        data: &[u8],
    ) -> Result<(), IoError> {
        let ch = self.channel(topic)?;
        let (id, seq) = (ch.id, ch.sequence);
        ch.sequence = ch.sequence.wrapping_add(1);
        self.writer.write_message(id, seq, time_ns, time_ns, data)
    }

    /// Records the rows of one camera (or the fused rows) of one frame.
    fn rows(&mut self, camera: CameraId, rows: &[&Measurement]) -> Result<(), IoError> {
        let Some(first) = rows.first() else {
            return Ok(());
        };
        let (frame, time_ns) = (first.frame, first.timestamp_ns.as_nanos());
        if self.options.profile == Profile::Ros2 {
            return self.joint_states(camera, rows, time_ns);
        }
        let name = self.camera_name(camera);
        let mut json = std::mem::take(&mut self.json);
        json.clear();
        let _ = write!(
            json,
            "{{\"frame\":{frame},\"timestamp_ns\":{time_ns},\"camera\":{}",
            json_string(&name)
        );
        if let CameraId::Camera(k) = camera {
            let _ = write!(json, ",\"camera_index\":{k}");
        }
        json.extend_from_slice(b",\"rows\":[");
        for (i, r) in rows.iter().enumerate() {
            let r = r.sanitized();
            if i > 0 {
                json.push(b',');
            }
            let row = serde_json::json!({
                "rod": r.rod,
                "position_mm": r.position_mm,
                "angle_rad": r.angle_rad,
                "angle_unwrapped_rad": r.angle_unwrapped_rad,
                "velocity_mm_s": r.velocity_mm_s,
                "angular_velocity_rad_s": r.angular_velocity_rad_s,
                "quality": r.quality,
                "status": r.status.name(),
                "turns_known": r.turns_known,
            });
            let _ = serde_json::to_writer(&mut json, &row);
        }
        json.extend_from_slice(b"]}");
        let r = self.message(Topic::Rows(camera), time_ns, &json);
        self.json = json;
        r?;
        self.joints(camera, rows, time_ns)
    }

    /// The rows as a ROS 2 joint state in CDR.
    fn joint_states(
        &mut self,
        camera: CameraId,
        rows: &[&Measurement],
        time_ns: u64,
    ) -> Result<(), IoError> {
        let topic = self.topic_name(Topic::Rows(camera));
        let frame_id = topic.trim_start_matches('/').trim_end_matches("/rows");
        let mut cdr = std::mem::take(&mut self.cdr);
        JointState::rows_to_cdr(rows.iter().copied(), time_ns, frame_id, &mut cdr);
        let r = self.message(Topic::JointStates(camera), time_ns, &cdr);
        self.cdr = cdr;
        r
    }

    /// The rows as a joint state.
    fn joints(
        &mut self,
        camera: CameraId,
        rows: &[&Measurement],
        time_ns: u64,
    ) -> Result<(), IoError> {
        let mut name = Vec::with_capacity(rows.len() * 2);
        let mut position = Vec::with_capacity(rows.len() * 2);
        let mut velocity = Vec::with_capacity(rows.len() * 2);
        for r in rows.iter().map(|r| r.sanitized()) {
            if !matches!(r.status, Status::Ok | Status::Predicted | Status::Conflict) {
                continue;
            }
            name.push(format!("rod{}_slide", r.rod));
            position.push(r.position_mm * 1e-3);
            velocity.push(r.velocity_mm_s * 1e-3);
            name.push(format!("rod{}_turn", r.rod));
            position.push(r.angle_unwrapped_rad);
            velocity.push(r.angular_velocity_rad_s);
        }
        let frame_id = self.topic_name(Topic::Rows(camera));
        let msg = serde_json::json!({
            "header": {
                "stamp": {"sec": time_ns / 1_000_000_000, "nanosec": time_ns % 1_000_000_000},
                "frame_id": frame_id.trim_start_matches('/').trim_end_matches("/rows"),
            },
            "name": name,
            "position": position,
            "velocity": velocity,
            "effort": [],
        });
        let data = msg.to_string();
        self.message(Topic::Joints(camera), time_ns, data.as_bytes())
    }
}

/// Records the rows written to it; see [`McapRecorder::sink`]. A write is cut into one
/// message per camera (or fused) and frame.
pub struct McapSink {
    recorder: McapRecorder,
}

impl McapSink {
    /// The recorder.
    pub fn recorder(&self) -> &McapRecorder {
        &self.recorder
    }
}

impl MeasurementSink for McapSink {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        let mut inner = self.recorder.lock();
        let mut groups = std::mem::take(&mut inner.groups);
        groups.clear();
        for r in rows {
            let key = (r.camera, r.frame, r.timestamp_ns.as_nanos());
            if !groups.contains(&key) {
                groups.push(key);
            }
        }
        let mut first = Ok(());
        let mut members: Vec<&Measurement> = Vec::with_capacity(rows.len());
        for &(camera, frame, time_ns) in &groups {
            members.clear();
            members.extend(rows.iter().filter(|r| {
                r.camera == camera && r.frame == frame && r.timestamp_ns.as_nanos() == time_ns
            }));
            if let Err(e) = inner.rows(camera, &members) {
                if first.is_ok() {
                    first = Err(e);
                }
            }
        }
        inner.groups = groups;
        first
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.recorder.lock().writer.flush()
    }
}

/// A rows message read back ([`parse_rows_message`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RowsMessage {
    /// The camera's name, or `fused`.
    pub camera_name: String,
    /// The rows (camera, frame and timestamp from the message).
    pub rows: Vec<Measurement>,
}

#[derive(serde::Deserialize)]
struct JsonRows {
    frame: u64,
    timestamp_ns: u64,
    camera: String,
    camera_index: Option<u32>,
    rows: Vec<JsonRow>,
}

#[derive(serde::Deserialize)]
struct JsonRow {
    rod: u32,
    position_mm: f64,
    angle_rad: f64,
    angle_unwrapped_rad: f64,
    velocity_mm_s: f64,
    angular_velocity_rad_s: f64,
    quality: f64,
    status: String,
    turns_known: bool,
}

/// Parses a `rodtrack.Rows` message (what [`McapSink`] records); the reason when it is not
/// one.
pub fn parse_rows_message(data: &[u8]) -> Result<RowsMessage, String> {
    let m: JsonRows =
        serde_json::from_slice(data).map_err(|e| format!("not a rows message: {e}"))?;
    let camera = match (m.camera.as_str(), m.camera_index) {
        ("fused", None) => CameraId::Fused,
        (_, Some(k)) => CameraId::Camera(k),
        (name, None) => return Err(format!("camera {name:?} without its camera_index")),
    };
    let rows = m
        .rows
        .into_iter()
        .map(|r| {
            let status = Status::from_name(&r.status)
                .ok_or_else(|| format!("rod {}: unknown status {:?}", r.rod, r.status))?;
            let row = Measurement {
                frame: m.frame,
                timestamp_ns: rodtrack_core::Timestamp(m.timestamp_ns),
                camera,
                rod: r.rod,
                position_mm: r.position_mm,
                angle_rad: r.angle_rad,
                angle_unwrapped_rad: r.angle_unwrapped_rad,
                velocity_mm_s: r.velocity_mm_s,
                angular_velocity_rad_s: r.angular_velocity_rad_s,
                quality: r.quality,
                status,
                turns_known: r.turns_known,
            };
            Ok(row)
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok(RowsMessage {
        camera_name: m.camera,
        rows,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn base64_is_rfc4648() {
        for (raw, enc) in [
            (&b""[..], ""),
            (b"f", "Zg=="),
            (b"fo", "Zm8="),
            (b"foo", "Zm9v"),
            (b"foob", "Zm9vYg=="),
            (b"fooba", "Zm9vYmE="),
            (b"foobar", "Zm9vYmFy"),
        ] {
            let mut out = Vec::new();
            push_base64(&mut out, raw);
            assert_eq!(String::from_utf8(out).unwrap(), enc);
        }
    }

    #[test]
    fn schemas_are_json() {
        for s in [
            ROWS_SCHEMA,
            JOINTS_SCHEMA,
            IMAGE_SCHEMA,
            BALL_SCHEMA,
            EVENT_SCHEMA,
        ] {
            let v: serde_json::Value = serde_json::from_str(s).unwrap();
            assert_eq!(v["type"], "object");
        }
    }
}
