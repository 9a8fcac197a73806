//! rodtrack's algorithms: frame views, the marker, the camera model, line sampling, the
//! paper's signal steps and rodtrack's enhanced ones, and the measurement record. No I/O.

pub mod angle;
pub mod ball;
pub mod calib;
pub mod camera;
pub mod decode;
pub mod error;
pub mod filter;
pub mod frame;
pub mod fusion;
pub mod linalg_small;
pub mod line;
pub mod marker;
pub mod measurement;
pub mod pipeline;
pub mod preview;
pub mod signal;
pub mod time;
pub mod track;

pub use camera::{Camera, CameraIntrinsics, Pose};
pub use error::CoreError;
pub use frame::{FrameView, LumaKind, PixelFormat};
pub use marker::{gray, gray_decode, Marker, MarkerSpec};
pub use measurement::{CameraId, Measurement, Status};
pub use pipeline::{CameraFilter, CameraPipeline, FrameSetFilter, SetFusion, TurnAnchor};
pub use time::Timestamp;
pub use track::{Mode, RodResult, RodTracker, Stage};
