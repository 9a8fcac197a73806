//! The ball in recordings: [`McapRecorder::ball_sink`] records each ball row (a camera's, or
//! the fused one) as one message.
//!
//! - rodtrack's files: `rodtrack.Ball` JSON messages ([`BALL_SCHEMA`]) on
//!   `/rodtrack/<table>/cam/<camera>/ball` and `/rodtrack/<table>/fused/ball`, every row with
//!   its status and the position's standard deviation the fusion weighs a camera's row by;
//!   [`parse_ball_message`] reads one back.
//! - ROS 2 bags: the rows with a place (`ok`, `predicted`) as `geometry_msgs/msg/PointStamped`
//!   on `.../ball` (m, the table frame `rodtrack/<table>`, `z` the ball's radius) and
//!   `geometry_msgs/msg/Vector3Stamped` on `.../ball/velocity` (m/s), as the camera network
//!   publishes them for ROS 2.
//!
//! Every message's log time is the frame's capture timestamp, ns. The ball's channels' metadata
//! hold the ball's diameter (`ball_diameter_mm`) beside the table and the camera.

use super::record::{json_string, McapRecorder, Profile, Topic};
use super::ros2::{ball_place_and_velocity, ros_name_token, StampedXyz};
use crate::{BallSink, IoError};
use rodtrack_core::ball::{BallRow, BallStatus};
use rodtrack_core::{CameraId, Timestamp};
use std::io::Write as _;

/// The ball messages' schema name.
pub const BALL_SCHEMA_NAME: &str = "rodtrack.Ball";

/// The JSON schema of a ball message (`rodtrack.Ball`).
pub const BALL_SCHEMA: &str = r#"{
  "title": "rodtrack.Ball",
  "description": "One ball row: the ball's centre in the table frame (origin at the field's centre, x towards goal B, y along the rods, mm), of one camera or fused (docs/ball.md).",
  "type": "object",
  "properties": {
    "frame": {"type": "integer", "minimum": 0, "description": "The frame id"},
    "timestamp_ns": {"type": "integer", "minimum": 0, "description": "Capture timestamp, ns (also the message's log time)"},
    "camera": {"type": "string", "description": "The camera's name in the calibration, or \"fused\""},
    "camera_index": {"type": "integer", "minimum": 0, "description": "The camera's index in the calibration (absent on fused rows)"},
    "x_mm": {"type": "number", "description": "Ball centre, table frame, mm"},
    "y_mm": {"type": "number", "description": "Ball centre, table frame, mm"},
    "vx_mm_s": {"type": "number", "description": "Velocity, mm/s"},
    "vy_mm_s": {"type": "number", "description": "Velocity, mm/s"},
    "quality": {"type": "number", "minimum": 0, "maximum": 1, "description": "Fraction of the ball's outline measured"},
    "status": {"type": "string", "enum": ["ok", "predicted", "lost", "conflict"]},
    "sigma_mm": {"type": ["number", "null"], "description": "The position's standard deviation per axis, mm (null: unbounded, a lost row, or not known, a fused row)"}
  },
  "required": ["frame", "timestamp_ns", "camera", "x_mm", "y_mm", "vx_mm_s", "vy_mm_s", "quality", "status"]
}"#;

impl McapRecorder {
    /// A ball sink whose rows are recorded; `diameter_mm` is the ball's (its centre's height
    /// in a ROS 2 bag).
    pub fn ball_sink(&self, diameter_mm: f64) -> McapBallSink {
        let mut inner = self.lock();
        inner.ball_diameter_mm = Some(diameter_mm);
        let table = match inner.options.table.as_str() {
            "" => "default",
            t => t,
        };
        let frame_id = format!("rodtrack/{}", ros_name_token(table));
        drop(inner);
        McapBallSink {
            recorder: self.clone(),
            centre_z_m: diameter_mm * 0.5e-3,
            frame_id,
        }
    }
}

/// Records the ball rows written to it (see [`McapRecorder::ball_sink`]).
pub struct McapBallSink {
    recorder: McapRecorder,
    centre_z_m: f64,
    /// The table frame's id in a ROS 2 bag (`rodtrack/<table>`).
    frame_id: String,
}

impl BallSink for McapBallSink {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        self.write_sigma(rows, &[])
    }
    fn write_sigma(&mut self, rows: &[BallRow], sigma_mm: &[f64]) -> Result<(), IoError> {
        let mut inner = self.recorder.lock();
        for (i, row) in rows.iter().enumerate() {
            let sigma = sigma_mm.get(i).copied().unwrap_or(f64::NAN);
            let row = row.sanitized();
            let time_ns = row.timestamp_ns.as_nanos();
            if inner.options.profile == Profile::Ros2 {
                let Some((p, v)) = ball_place_and_velocity(&row, self.centre_z_m) else {
                    continue;
                };
                let mut cdr = std::mem::take(&mut inner.cdr);
                StampedXyz::write_cdr(time_ns, &self.frame_id, p, &mut cdr);
                let r = inner.message(Topic::BallPoint(row.camera), time_ns, &cdr);
                StampedXyz::write_cdr(time_ns, &self.frame_id, v, &mut cdr);
                let r = r.and(inner.message(Topic::BallVelocity(row.camera), time_ns, &cdr));
                inner.cdr = cdr;
                r?;
                continue;
            }
            let name = inner.camera_name(row.camera);
            let mut json = std::mem::take(&mut inner.json);
            json.clear();
            let _ = write!(
                json,
                "{{\"frame\":{},\"timestamp_ns\":{time_ns},\"camera\":{}",
                row.frame,
                json_string(&name)
            );
            if let CameraId::Camera(k) = row.camera {
                let _ = write!(json, ",\"camera_index\":{k}");
            }
            let number = |v: f64| serde_json::Value::from(v).to_string();
            let _ = write!(
                json,
                ",\"x_mm\":{},\"y_mm\":{},\"vx_mm_s\":{},\"vy_mm_s\":{},\"quality\":{},\"status\":\"{}\",\"sigma_mm\":{}}}",
                number(row.x_mm),
                number(row.y_mm),
                number(row.vx_mm_s),
                number(row.vy_mm_s),
                number(row.quality),
                row.status.name(),
                // serde_json writes a non-finite number as null.
                number(sigma),
            );
            let r = inner.message(Topic::Ball(row.camera), time_ns, &json);
            inner.json = json;
            r?;
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

/// A ball message read back ([`parse_ball_message`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BallMessage {
    /// The camera's name in the recording (`fused` for fused rows).
    pub camera_name: String,
    /// The row (its camera from `camera_index`, fused without one).
    pub row: BallRow,
    /// The position's standard deviation per axis, mm: infinite for a `lost` row and NaN for
    /// any other whose message has none (null).
    pub sigma_mm: f64,
}

#[derive(serde::Deserialize)]
struct JsonBall {
    frame: u64,
    timestamp_ns: u64,
    camera: String,
    camera_index: Option<u32>,
    x_mm: f64,
    y_mm: f64,
    vx_mm_s: f64,
    vy_mm_s: f64,
    quality: f64,
    status: String,
    sigma_mm: Option<f64>,
}

/// Parses a `rodtrack.Ball` message.
pub fn parse_ball_message(data: &[u8]) -> Result<BallMessage, String> {
    let m: JsonBall =
        serde_json::from_slice(data).map_err(|e| format!("not a ball message: {e}"))?;
    let camera = match (m.camera.as_str(), m.camera_index) {
        ("fused", None) => CameraId::Fused,
        (_, Some(k)) => CameraId::Camera(k),
        (name, None) => return Err(format!("camera {name:?} without its camera_index")),
    };
    let status = BallStatus::from_name(&m.status)
        .ok_or_else(|| format!("frame {}: unknown ball status {:?}", m.frame, m.status))?;
    let sigma_mm = match (m.sigma_mm, status) {
        (Some(s), _) => s,
        (None, BallStatus::Lost) => f64::INFINITY,
        (None, _) => f64::NAN,
    };
    Ok(BallMessage {
        camera_name: m.camera,
        row: BallRow {
            frame: m.frame,
            timestamp_ns: Timestamp(m.timestamp_ns),
            camera,
            x_mm: m.x_mm,
            y_mm: m.y_mm,
            vx_mm_s: m.vx_mm_s,
            vy_mm_s: m.vy_mm_s,
            quality: m.quality,
            status,
        },
        sigma_mm,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_ball_message_reads_back_and_a_bad_one_is_named() {
        let m = parse_ball_message(
            br#"{"frame":3,"timestamp_ns":15000000,"camera":"cam1","camera_index":1,"x_mm":-12.25,"y_mm":3.5,"vx_mm_s":100.0,"vy_mm_s":0.0,"quality":0.9,"status":"ok","sigma_mm":0.4}"#,
        )
        .unwrap();
        assert_eq!(m.camera_name, "cam1");
        assert_eq!(m.row.camera, CameraId::Camera(1));
        assert_eq!(
            (m.row.x_mm, m.row.status, m.sigma_mm),
            (-12.25, BallStatus::Ok, 0.4)
        );
        // null: unbounded for a lost row, not known otherwise.
        let lost = br#"{"frame":3,"timestamp_ns":0,"camera":"fused","x_mm":0,"y_mm":0,"vx_mm_s":0,"vy_mm_s":0,"quality":0,"status":"lost","sigma_mm":null}"#;
        let m = parse_ball_message(lost).unwrap();
        assert_eq!((m.row.camera, m.sigma_mm), (CameraId::Fused, f64::INFINITY));
        let fused = String::from_utf8_lossy(lost).replace("lost", "predicted");
        assert!(parse_ball_message(fused.as_bytes())
            .unwrap()
            .sigma_mm
            .is_nan());
        for (bad, says) in [
            (
                String::from_utf8_lossy(lost).replace("lost", "gone"),
                "unknown ball status \"gone\"",
            ),
            (
                String::from_utf8_lossy(lost).replace("fused", "cam0"),
                "without its camera_index",
            ),
            ("{}".to_string(), "not a ball message"),
        ] {
            let e = parse_ball_message(bad.as_bytes()).unwrap_err();
            assert!(e.contains(says), "{e}");
        }
    }
}
