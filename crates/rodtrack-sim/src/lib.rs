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
//! - [`Simulation::new`]`(scene, cameras, scenario, mode) -> Result<Simulation>` (prepares each
//!   camera's tables, about 1 s, cameras in parallel); [`Simulation::with_seed`],
//!   [`Simulation::set_reference_poses`].
//! - [`Simulation::frame_count`], [`Simulation::frame_bytes`]`(cam)`, [`Simulation::timestamp_s`].
//! - [`Simulation::render`]`(&mut self, frame_index, camera_index, out: &mut [u8]) ->
//!   Result<RenderInfo>`: tightly packed (`stride = width * bytes_per_pixel`); the camera's
//!   buffers are reused (no full-frame allocation per frame).
//! - [`Simulation::render_reference`]`(camera_index, out)`: rods at their reference poses, no
//!   hands, no ball, no motion; [`Simulation::render_state`]`(camera_index, &WorldState,
//!   frame_id, out)` for any pose.
//! - [`Simulation::truth`]`(frame_index, camera_index) -> Result<Vec<TruthRow>>`: one row per
//!   rod, values at the middle of the exposure, timestamp = trigger time.
//! - [`Simulation::calibration_inputs`]`(camera_index, seed) -> Result<CalibrationInputs>` and
//!   [`Simulation::calibration_inputs_with`] ([`CalibOptions`]: omit the OpenCV model, click
//!   noise, points per rod).
//! - [`Simulation::project_rod_axis`]`(camera_index, rod, y_mm) -> Result<Option<(u, v)>>`.
//! - [`Simulation::marker_status`]`(camera_index, rod, &WorldState) -> Result<Status>`.
//! - [`Simulation::last_render_stats`]`(camera_index)`: where the last frame's time went.
//! - [`write_recording`]`(&mut sim, out_dir, &RecordOptions, &mut progress)`.
//! - [`apply_variation`]`(name, &mut scene, &mut cameras)` for the setup variations in
//!   [`VARIATION_NAMES`] (camera yawed 180 degrees, markers flipped, k1 = -0.35, dim light,
//!   20 mm rods).
//! - [`Scenario::by_name`]`(name, &scene, seed)` for the names in [`SCENARIO_NAMES`];
//!   [`Scenario::with_duration`], [`Scenario::with_frames`]; scenarios are plain data (tracks of
//!   trapezoidal moves and spins, hand passes, ball path, light levels) and can be built by hand.
//!
//! # Rendering
//! Per camera, once: a ray grid (exact undistortion at every 8th pixel, interpolated), the
//! table supersampled, every pixel where a rod can appear (rods only slide and turn, so the
//! hit point on the cylinder is fixed per pixel) and a few noisy copies of the still image.
//! Per frame, fast mode: each marker's pixels are shaded with the print box-filtered
//! analytically over the pixel footprint widened by the motion during the exposure; figures,
//! hands and the ball are rasterised (camera-facing box faces, far to near) with exact
//! occlusion tests against the rods and walls, the ball smeared along its path (each pixel
//! the part of the exposure its ray meets the moving sphere); light, glare, shot and read noise and 8-bit
//! quantisation finish the frame (rows of a noisy still copy where nothing changed). Quality
//! mode traces 4 x 4 sub-samples per marker pixel, each at its own time in the exposure, and
//! 2 x 2 for moving objects. Speed: `cargo bench -p rodtrack-sim --bench render -- fast
//! gameplay` (see the crate's bench for the numbers).

pub mod ball;
pub mod build;
pub mod cameras;
pub mod error;
pub mod geom;
mod goals;
mod inputs;
pub mod motion;
mod raster;
pub mod record;
pub mod render;
pub mod rng;
pub mod scenario;
pub mod scene;
pub mod sim;
pub mod source;
pub mod variations;

pub use build::{build_simulation, calibrate_sim_camera, SimCalibration};
pub use cameras::{default_cameras, NoiseModel, SimCamera};
pub use error::SimError;
pub use geom::{RodPose, WorldState};
pub use motion::{Move, Spin, Track, TrackBuilder};
pub use record::{write_recording, RecordOptions, RecordSummary};
pub use render::{RenderMode, RenderStats};
pub use scenario::{BallPath, HandPass, RodMotion, Scenario, SCENARIO_NAMES};
pub use scene::{Lighting, RodConfig, RodLayout, SceneConfig};
pub use sim::{frame_time, CalibOptions, RenderInfo, Simulation, TruthRow};
pub use source::{register_sim_source, Playback, SimSource};
pub use variations::{apply_variation, VARIATION_NAMES};
