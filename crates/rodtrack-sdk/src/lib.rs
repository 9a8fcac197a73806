//! rodtrack as a library: calibrate cameras, open frame sources, and run tracking sessions
//! into sinks, with hooks for frames, rows and progress.
//!
//! The CLI, the web console, the demo, the evaluation and the latency benchmark all run their
//! cameras through one [`Session`]; a Rust program, a binding or a network node does the same.
//!
//! Calibrate a recording made by `rodtrack simulate` (or by cameras, with calibration inputs
//! beside it) and track it (the example `calibrate_and_track` of this crate):
//!
//! ```no_run
//! use rodtrack_core::CameraId;
//! use rodtrack_io::VecSink;
//! use rodtrack_sdk::{calibrate_files, print_warning, Session, SessionOptions};
//!
//! let dir = std::path::Path::new("rec");
//! let inputs = [dir.join("cam0.json"), dir.join("cam1.json")];
//! let paths: Vec<&std::path::Path> = inputs.iter().map(|p| p.as_path()).collect();
//! let cal = calibrate_files(&paths, &mut print_warning)?;
//! let frames = [dir.join("cam0"), dir.join("cam1")].map(|p| p.display().to_string());
//! let session = Session::open(&cal, &frames, SessionOptions::default())?;
//! let (report, sink) = session.run(VecSink::default())?;
//! for m in sink.rows.iter().filter(|m| m.camera == CameraId::Fused).take(8) {
//!     println!("frame {} rod {}: {:.3} mm {:.4} rad {}", m.frame, m.rod, m.position_mm, m.angle_rad, m.status);
//! }
//! println!("{}", report.summary());
//! # Ok::<(), rodtrack_sdk::SdkError>(())
//! ```

pub mod auto;
pub mod ball;
pub mod calibration;
pub mod control;
pub mod error;
pub mod health;
pub mod hooks;
pub mod session;
pub mod sinks;
pub mod sources;

pub use ball::{BallCounts, BallSets, EventCounts};
pub use calibration::{
    calibrate_camera_file, calibrate_files, calibration_file, print_warning, read_calibration,
    read_inputs, read_opencv_model, write_calibration, ReferenceFolder, DEFAULT_FPS,
};
pub use control::{Reanchor, SessionControl};
pub use error::SdkError;
pub use health::RodHealth;
pub use hooks::{Hooks, NoHooks, Progress};
pub use session::{
    mode_from_name, pipeline_config, RunReport, Session, SessionCamera, SessionOptions, LIVE_SPIN,
    MODE_NAMES,
};
pub use sinks::{check_out_is_not_an_input, is_broken_pipe, open_sinks, RowFormat};
pub use sources::source_factory;
