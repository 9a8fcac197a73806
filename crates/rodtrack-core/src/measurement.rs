//! The measurement record (SPEC section 6), shared by tracking output and simulator truth.

use crate::time::Timestamp;
use serde::{Deserialize, Serialize};

/// How far a measurement can be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Marker found and decoded consistently.
    #[default]
    Ok,
    /// The rod's line is in view but no marker was found on it.
    NotFound,
    /// A marker was found but part of it is hidden or inconsistent.
    Occluded,
    /// The marker's expected place lies outside the frame.
    OutOfView,
    /// No usable measurement: the value is the state filter's prediction.
    Predicted,
    /// The rod has not been seen for too long to predict.
    Lost,
    /// The frame itself was unusable (corrupt, wrong size).
    BadFrame,
    /// Cameras disagree beyond their uncertainties. On a fused row: no camera is clearly right
    /// (none agrees with the filter's track, or there is no track yet); the values are the
    /// filter's prediction, as for `predicted`. On a camera's row: this camera's measurement
    /// lost against the others and was left out of the fusion; the values are its own.
    Conflict,
}

impl Status {
    /// The name written in files.
    pub fn name(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::NotFound => "not_found",
            Status::Occluded => "occluded",
            Status::OutOfView => "out_of_view",
            Status::Predicted => "predicted",
            Status::Lost => "lost",
            Status::BadFrame => "bad_frame",
            Status::Conflict => "conflict",
        }
    }
    /// Parses a name written by [`Status::name`].
    pub fn from_name(s: &str) -> Option<Status> {
        [
            Status::Ok,
            Status::NotFound,
            Status::Occluded,
            Status::OutOfView,
            Status::Predicted,
            Status::Lost,
            Status::BadFrame,
            Status::Conflict,
        ]
        .into_iter()
        .find(|v| v.name() == s)
    }
}

impl std::fmt::Display for Status {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Which camera a row comes from: one camera's index, or the fusion of all.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum CameraId {
    /// One camera, by index.
    Camera(u32),
    /// The fused estimate.
    Fused,
}

impl std::fmt::Display for CameraId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CameraId::Camera(i) => write!(f, "{i}"),
            CameraId::Fused => f.write_str("fused"),
        }
    }
}

/// One row: one rod, one frame, one camera (or fused).
///
/// Values that are unknown (for example the angle of a rod that is not found) are `0.0` with a
/// status that says so; a record never holds NaN.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// The camera's frame id.
    pub frame: u64,
    /// Capture time, from the frame's source (written as seconds, `timestamp_s`, in files:
    /// see [`Measurement::timestamp_s`]).
    #[serde(rename = "timestamp_s", with = "crate::time::as_secs")]
    pub timestamp_ns: Timestamp,
    /// Source camera or fused.
    pub camera: CameraId,
    /// Rod id.
    pub rod: u32,
    /// Translation along the rod's `u` axis from its calibrated zero, mm.
    pub position_mm: f64,
    /// Rotation about `u`, right-handed, in `[0, 2 pi)`.
    pub angle_rad: f64,
    /// Rotation counting whole turns.
    pub angle_unwrapped_rad: f64,
    /// Translation velocity, mm/s (0 when not estimated).
    pub velocity_mm_s: f64,
    /// Angular velocity, rad/s (0 when not estimated).
    pub angular_velocity_rad_s: f64,
    /// Confidence in `[0, 1]`.
    pub quality: f64,
    /// Whether to trust the values.
    pub status: Status,
    /// Whether `angle_unwrapped_rad` counts every whole turn since the count's anchor (the
    /// rod's first confirmed frame, or its last re-anchoring). `false` after any stretch in
    /// which the count could have slipped (frames rejected or missing for too long, a speed
    /// the frame rate does not disambiguate), until the count is re-anchored: the unwrapped
    /// angle is then the filter's best guess, right modulo `2 pi` (`angle_rad` is exact) but
    /// possibly off by whole turns. `false` on rows without a value. Files written before this
    /// field existed read as `true`.
    #[serde(default = "known_by_default")]
    pub turns_known: bool,
}

fn known_by_default() -> bool {
    true
}

impl Measurement {
    /// A record with no value, for a rod that was not measured.
    pub fn empty(
        frame: u64,
        timestamp_ns: Timestamp,
        camera: CameraId,
        rod: u32,
        status: Status,
    ) -> Self {
        Measurement {
            frame,
            timestamp_ns,
            camera,
            rod,
            position_mm: 0.0,
            angle_rad: 0.0,
            angle_unwrapped_rad: 0.0,
            velocity_mm_s: 0.0,
            angular_velocity_rad_s: 0.0,
            quality: 0.0,
            status,
            turns_known: false,
        }
    }

    /// The capture time in seconds ([`Timestamp::as_secs_f64`]), as files print it.
    pub fn timestamp_s(&self) -> f64 {
        self.timestamp_ns.as_secs_f64()
    }

    /// Replaces any non-finite number by 0 and marks the row, so that no NaN is ever written.
    pub fn sanitized(mut self) -> Self {
        let mut bad = false;
        for v in [
            &mut self.position_mm,
            &mut self.angle_rad,
            &mut self.angle_unwrapped_rad,
            &mut self.velocity_mm_s,
            &mut self.angular_velocity_rad_s,
            &mut self.quality,
        ] {
            if !v.is_finite() {
                *v = 0.0;
                bad = true;
            }
        }
        if bad && self.status == Status::Ok {
            self.status = Status::NotFound;
            self.quality = 0.0;
            self.turns_known = false;
        }
        self.quality = self.quality.clamp(0.0, 1.0);
        self
    }
}

/// The CSV header of SPEC section 6.
pub const CSV_COLUMNS: [&str; 11] = [
    "frame",
    "timestamp_s",
    "camera",
    "rod",
    "position_mm",
    "angle_rad",
    "angle_unwrapped_rad",
    "velocity_mm_s",
    "angular_velocity_rad_s",
    "quality",
    "status",
];

/// The column written after [`CSV_COLUMNS`] by rodtrack's measurement files: `true` or
/// `false` ([`Measurement::turns_known`]). Readers accept files without it (read as `true`).
pub const TURNS_KNOWN_COLUMN: &str = "turns_known";

/// The columns rodtrack's measurement files carry: [`CSV_COLUMNS`], then
/// [`TURNS_KNOWN_COLUMN`] (last, so that the older columns keep their places).
pub const OUTPUT_COLUMNS: [&str; 12] = output_columns();

/// [`CSV_COLUMNS`] followed by [`TURNS_KNOWN_COLUMN`], built at compile time so that the two
/// lists cannot drift apart.
const fn output_columns() -> [&'static str; 12] {
    let mut out = [TURNS_KNOWN_COLUMN; 12];
    let mut i = 0;
    while i < CSV_COLUMNS.len() {
        out[i] = CSV_COLUMNS[i];
        i += 1;
    }
    out
}
