//! The ball (SPEC section 9): its detection in the raw mosaic and its tracking, in the table
//! frame, with no I/O.
//!
//! - [`colour`]: one RGB sample per Bayer quad, chromaticity, the calibrated colour model.
//! - [`detect`]: colour candidates on a grid of quads (every `coarse_step` quads over the
//!   field when lost, a window around the prediction when tracking), the compact blob of the
//!   ball's expected size, edge points on rays from its centre (only where the field's colour
//!   lies beyond), and the sphere's centre at `z = radius` fitted to the edge points' rays
//!   (a ball smeared over the exposure: the centre of its image's symmetry).
//! - [`track`]: the constant-velocity filter, statuses `ok`, `predicted`, `lost`.
//! - [`events`]: goals (with the score), shots, ball out, ball stopped, from one ball row per
//!   frame set.
//! - [`tuning`]: the constants.

pub mod colour;
pub mod detect;
pub mod events;
pub mod fuse;
mod memo;
pub mod track;
pub mod tuning;

pub use detect::{BallDetector, Detection, Reach, ScanArea};
pub use fuse::{BallFuser, CameraBall};
pub use track::BallTracker;

use crate::{CameraId, Timestamp};
use serde::{Deserialize, Serialize};

/// What a ball row says about the ball.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BallStatus {
    /// Measured in this frame.
    Ok,
    /// Not seen in this frame; the filter's prediction from the last detections (a short
    /// occlusion).
    Predicted,
    /// Not seen for longer than the prediction is trusted (or never): `x_mm`, `y_mm` and the
    /// velocity are 0 and mean nothing.
    Lost,
    /// `fused` rows only: cameras that see the ball disagree beyond their uncertainties and
    /// none is better supported by the fused track; the position is the best-measured
    /// camera's, not to be trusted.
    Conflict,
}

impl BallStatus {
    /// The name in files: `ok`, `predicted`, `lost`, `conflict`.
    pub fn name(self) -> &'static str {
        match self {
            BallStatus::Ok => "ok",
            BallStatus::Predicted => "predicted",
            BallStatus::Lost => "lost",
            BallStatus::Conflict => "conflict",
        }
    }

    /// The status of a name in files ([`BallStatus::name`]).
    pub fn from_name(s: &str) -> Option<BallStatus> {
        [
            BallStatus::Ok,
            BallStatus::Predicted,
            BallStatus::Lost,
            BallStatus::Conflict,
        ]
        .into_iter()
        .find(|b| b.name() == s)
    }
}

impl std::fmt::Display for BallStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The ball record (SPEC section 9): the ball's centre in the table frame.
///
/// ```
/// use rodtrack_core::ball::{BallRow, BallStatus};
/// use rodtrack_core::{CameraId, Timestamp};
/// let row = BallRow {
///     frame: 10,
///     timestamp_ns: Timestamp(50_000_000),
///     camera: CameraId::Camera(0),
///     x_mm: -120.5,
///     y_mm: 33.0,
///     vx_mm_s: 800.0,
///     vy_mm_s: -150.0,
///     quality: 0.9,
///     status: BallStatus::Ok,
/// };
/// assert_eq!(BallRow::CSV_HEADER, "frame,timestamp_s,camera,x_mm,y_mm,vx_mm_s,vy_mm_s,quality,status");
/// assert_eq!(row.csv_line(), "10,0.050000,0,-120.500,33.000,800.0,-150.0,0.900,ok");
/// assert!((row.speed_mm_s() - 813.9).abs() < 0.1);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BallRow {
    /// Frame id.
    pub frame: u64,
    /// Capture time.
    pub timestamp_ns: Timestamp,
    /// The camera, or `fused` (several cameras combined: [`BallFuser`]).
    pub camera: CameraId,
    /// Ball centre, table frame, mm.
    pub x_mm: f64,
    /// Ball centre, table frame, mm.
    pub y_mm: f64,
    /// Velocity, mm/s.
    pub vx_mm_s: f64,
    /// Velocity, mm/s.
    pub vy_mm_s: f64,
    /// Fraction of the ball's outline measured (0 when not measured).
    pub quality: f64,
    /// `ok`, `predicted`, `lost` (or `conflict`, fused rows only).
    pub status: BallStatus,
}

impl BallRow {
    /// The CSV columns.
    pub const CSV_HEADER: &'static str =
        "frame,timestamp_s,camera,x_mm,y_mm,vx_mm_s,vy_mm_s,quality,status";

    /// A `lost` row of `camera` for a frame: no position, no velocity, quality 0.
    pub fn lost(frame: u64, timestamp_ns: Timestamp, camera: CameraId) -> BallRow {
        BallRow {
            frame,
            timestamp_ns,
            camera,
            x_mm: 0.0,
            y_mm: 0.0,
            vx_mm_s: 0.0,
            vy_mm_s: 0.0,
            quality: 0.0,
            status: BallStatus::Lost,
        }
    }

    /// Capture time, s (for printing).
    pub fn timestamp_s(&self) -> f64 {
        self.timestamp_ns.as_secs_f64()
    }

    /// Speed, mm/s.
    pub fn speed_mm_s(&self) -> f64 {
        self.vx_mm_s.hypot(self.vy_mm_s)
    }

    /// One CSV line (no newline).
    pub fn csv_line(&self) -> String {
        let mut s = String::with_capacity(80);
        self.push_csv(&mut s);
        s
    }

    /// Appends [`BallRow::csv_line`] to `out` (no allocation once `out` has room).
    pub fn push_csv(&self, out: &mut String) {
        use std::fmt::Write;
        let _ = write!(
            out,
            "{},{:.6},{},{:.3},{:.3},{:.1},{:.1},{:.3},{}",
            self.frame,
            self.timestamp_s(),
            self.camera,
            self.x_mm,
            self.y_mm,
            self.vx_mm_s,
            self.vy_mm_s,
            self.quality,
            self.status
        );
    }

    /// Appends the row as one JSON object to `out` (no allocation once `out` has room), the
    /// CSV's columns and precision: `camera` a number, or the string `"fused"`; `status` a
    /// string.
    pub fn push_json(&self, out: &mut String) {
        use std::fmt::Write;
        let _ = write!(
            out,
            "{{\"frame\":{},\"timestamp_s\":{:.6},",
            self.frame,
            self.timestamp_s()
        );
        let _ = match self.camera {
            CameraId::Camera(c) => write!(out, "\"camera\":{c},"),
            CameraId::Fused => write!(out, "\"camera\":\"fused\","),
        };
        let _ = write!(
            out,
            "\"x_mm\":{:.3},\"y_mm\":{:.3},\"vx_mm_s\":{:.1},\"vy_mm_s\":{:.1},\"quality\":{:.3},\"status\":\"{}\"}}",
            self.x_mm, self.y_mm, self.vx_mm_s, self.vy_mm_s, self.quality, self.status
        );
    }

    /// Non-finite numbers replaced: the row becomes `lost` with zeros.
    pub fn sanitized(mut self) -> BallRow {
        let all = [
            self.x_mm,
            self.y_mm,
            self.vx_mm_s,
            self.vy_mm_s,
            self.quality,
        ];
        if !all.iter().all(|v| v.is_finite()) {
            self.x_mm = 0.0;
            self.y_mm = 0.0;
            self.vx_mm_s = 0.0;
            self.vy_mm_s = 0.0;
            self.quality = 0.0;
            self.status = BallStatus::Lost;
        }
        self
    }
}
