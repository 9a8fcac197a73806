//! rodtrack's simulator: a table-football table with 8 rods carrying marker v1, two overhead
//! industrial cameras, motion scripts and exact ground truth.
//!
//! # Conventions
//! World: `x` along the field (goal to goal, 1200 mm), `y` along the rods (walls at 0 and
//! 680 mm), `z` up, field at `z = 0`; rod `i` has its axis at `x = 75 + 150 i`, `z = 80`.
//! A rod's `position_mm` is its translation along the marker's `u` axis (world `y` of the
//! marker's start = `marker_start_y_mm + marker_dir * position_mm`); `angle_rad` is the
//! rotation about `u`, right-handed, 0 = figures hanging down. The print point `(u, psi)` lies
//! at `Rot_u(theta - psi + psi0) * (+z)` from the axis, so the top line reads
//! `psi = theta + psi0`. All scene numbers are fields of [`SceneConfig`] (module [`scene`]);
//! camera defaults are in [`cameras::default_cameras`].
//!
//! # API
//! - [`Simulation::new`]`(scene, cameras, scenario, mode) -> Result<Simulation>`;
//!   [`Simulation::with_seed`], [`Simulation::set_reference_poses`].
//! - [`Simulation::frame_count`], [`Simulation::frame_bytes`]`(cam)`.
//! - [`Simulation::render`]`(&mut self, frame_index, camera_index, out: &mut [u8]) ->
//!   Result<FrameMeta>` (no full-frame allocation per frame; buffers are reused).
//! - [`Simulation::render_reference`]`(camera_index, out)`: rods at their reference poses.
//! - [`Simulation::truth`]`(frame_index, camera_index) -> Result<Vec<TruthRow>>`.
//! - [`Simulation::calibration_inputs`]`(camera_index, seed) -> Result<CalibrationInputs>`
//!   and [`Simulation::calibration_inputs_with`] ([`CalibOptions`]).
//! - [`Simulation::project_rod_axis`]`(camera_index, rod, y_mm) -> Result<Option<(u, v)>>`.
//! - [`Simulation::marker_status`]`(camera_index, rod, &WorldState) -> Result<Status>`.
//! - [`write_recording`]`(&mut sim, out_dir, &RecordOptions, &mut progress)`.
//! - [`Scenario::by_name`]`(name, &scene, seed)` for the names in [`SCENARIO_NAMES`].

pub mod cameras;
pub mod error;
pub mod geom;
pub mod motion;
mod raster;
pub mod record;
pub mod render;
pub mod rng;
pub mod scenario;
pub mod scene;
pub mod sim;

pub use cameras::{default_cameras, NoiseModel, SimCamera};
pub use error::SimError;
pub use geom::{RodPose, WorldState};
pub use motion::{Move, Spin, Track, TrackBuilder};
pub use record::{write_recording, RecordOptions, RecordSummary};
pub use render::{RenderMode, RenderStats};
pub use scenario::{BallPath, HandPass, RodMotion, Scenario, SCENARIO_NAMES};
pub use scene::{Lighting, RodConfig, RodLayout, SceneConfig};
pub use sim::{CalibOptions, FrameMeta, Simulation, TruthRow};
