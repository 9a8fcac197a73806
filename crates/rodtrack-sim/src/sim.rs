//! The simulation: scene + cameras + scenario -> frames, ground truth and calibration inputs.

use crate::cameras::SimCamera;
use crate::geom::{Obj, Shader, WorldGeom, WorldState, V3};
use crate::inputs::known_pose_list;
use crate::render::{noise_table, CameraRenderer, RenderMode};
use crate::rng::hash_words;
use crate::scenario::Scenario;
use crate::scene::{Lighting, SceneConfig};
use crate::SimError;
use rodtrack_core::angle::wrap_2pi;
use rodtrack_core::calib::CalibrationInputs;
use rodtrack_core::{CameraId, Measurement, PixelFormat, Status, Timestamp};
use serde::{Deserialize, Serialize};

/// What [`Simulation::render`] produced.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RenderInfo {
    /// Frame id (shared by all cameras of a frame: hardware-synchronised).
    pub frame_id: u64,
    /// Trigger time (shared by all cameras of a frame): [`frame_time`].
    pub timestamp_ns: Timestamp,
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// Row stride, bytes.
    pub stride: usize,
    /// Pixel format.
    pub format: PixelFormat,
}

/// The trigger time of frame `frame` at `fps`: `frame / fps` seconds, to the nearest
/// nanosecond (the world itself is rendered at the exact `f64` time).
pub fn frame_time(frame: u64, fps: f64) -> Timestamp {
    Timestamp::from_secs_f64(frame as f64 / fps)
}

/// One ground-truth row: the SPEC section 6 record plus whether the whole marker is visible.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TruthRow {
    /// The record: `quality` 1, `status` ok when visible, else occluded / out_of_view.
    pub m: Measurement,
    /// True when the whole marker is in the frame and nothing hides it.
    pub visible: bool,
}

/// Options for [`Simulation::calibration_inputs_with`].
#[derive(Debug, Clone, PartialEq)]
pub struct CalibOptions {
    /// Write the true intrinsics as `opencv_model_optional`.
    pub include_opencv_model: bool,
    /// Standard deviation of the "clicked" path points, px.
    pub click_noise_px: f64,
    /// Path points per rod (3 to 5).
    pub points_per_rod: usize,
    /// List the known-pose frames ([`Simulation::known_pose_frames`]) in the inputs.
    pub known_poses: bool,
    /// With [`CalibOptions::known_poses`], give each its angle; `false`: its position alone
    /// (an operator who pushes each rod to its stops without knowing its angle there).
    pub known_pose_angles: bool,
    /// Write the field's corners and the centre line's ends seen by the camera as `table`
    /// points (SPEC section 9).
    pub table_points: bool,
    /// Standard deviation of the clicked table points, px.
    pub table_click_noise_px: f64,
    /// Write a ball calibration frame to the reference folder (after the known poses) and
    /// the ball's click as `ball`.
    pub ball_click: bool,
}

impl CalibOptions {
    /// The reference folder's frame with the ball ([`CalibOptions::ball_click`]): after the
    /// reference frame and the known poses of `rods` rods.
    pub fn ball_frame(&self, rods: usize) -> usize {
        if self.known_poses {
            1 + 3 * rods
        } else {
            1
        }
    }
}

impl Default for CalibOptions {
    fn default() -> Self {
        CalibOptions {
            include_opencv_model: true,
            click_noise_px: 1.0,
            points_per_rod: 4,
            known_poses: false,
            known_pose_angles: true,
            table_points: true,
            table_click_noise_px: 0.5,
            ball_click: true,
        }
    }
}

/// Everything but the per-camera renderers (so both can be borrowed at once).
#[derive(Debug, Clone)]
pub(crate) struct Ctx {
    pub scene: SceneConfig,
    pub scenario: Scenario,
    pub cameras: Vec<SimCamera>,
    pub mode: RenderMode,
    pub seed: u64,
    pub shader: Shader,
    pub noise: Vec<f32>,
    /// Reference pose per rod: (position_mm, angle_rad).
    pub reference: Vec<(f64, f64)>,
}

/// A running simulation.
#[derive(Debug, Clone)]
pub struct Simulation {
    pub(crate) ctx: Ctx,
    pub(crate) renderers: Vec<CameraRenderer>,
}

/// Marker sample positions along `u` for the visibility test, as fractions of its length.
const VIS_U: [f64; 9] = [0.003, 0.04, 0.2, 0.4, 0.6, 0.69, 0.75, 0.9, 0.997];
/// Angles (rad) around the direction towards the camera for the visibility test.
const VIS_ANGLE: [f64; 3] = [-0.8, 0.0, 0.8];

impl Simulation {
    /// Builds the simulation: precomputes every camera's ray table, background and rod strips
    /// (about a second per camera; cameras are prepared in parallel).
    pub fn new(
        scene: SceneConfig,
        cameras: Vec<SimCamera>,
        scenario: Scenario,
        mode: RenderMode,
    ) -> Result<Simulation, SimError> {
        let marker = scene.marker.validate()?;
        if scenario.rods.len() != scene.rods.len() {
            return Err(SimError::Config(format!(
                "scenario `{}` moves {} rods, the scene has {}",
                scenario.name,
                scenario.rods.len(),
                scene.rods.len()
            )));
        }
        if !(scenario.fps.is_finite() && scenario.fps > 0.0) {
            return Err(SimError::Config(format!(
                "fps must be positive, got {}",
                scenario.fps
            )));
        }
        for r in &scene.rods {
            if !(r.diameter_mm > 0.0 && r.travel_mm >= 0.0) {
                return Err(SimError::Config(format!(
                    "rod at x = {} mm: diameter and travel must be positive",
                    r.x_mm
                )));
            }
        }
        let _ = marker;
        if scene.rods.len() > 64 {
            return Err(SimError::Config(format!(
                "at most 64 rods are supported, the scene has {}",
                scene.rods.len()
            )));
        }
        for c in &cameras {
            let ok = matches!(
                c.pixel_format,
                PixelFormat::Mono8
                    | PixelFormat::Rgb8
                    | PixelFormat::BayerRggb8
                    | PixelFormat::BayerBggr8
                    | PixelFormat::BayerGrbg8
                    | PixelFormat::BayerGbrg8
            );
            if !ok {
                return Err(SimError::UnsupportedFormat {
                    camera: c.name.clone(),
                    format: c.pixel_format.name().to_string(),
                });
            }
            if c.camera.width < 2 || c.camera.height < 2 {
                return Err(SimError::Config(format!(
                    "camera `{}`: image too small",
                    c.name
                )));
            }
        }
        // The cameras are hardware-synchronised: the scenario's frame rate triggers them all.
        let mut cameras = cameras;
        for c in &mut cameras {
            c.fps = scenario.fps;
            if !(c.exposure_us > 0.0 && c.exposure_us <= 1e6 / scenario.fps) {
                return Err(SimError::Config(format!(
                    "camera `{}`: exposure {} us must be positive and at most one frame period ({} us)",
                    c.name,
                    c.exposure_us,
                    1e6 / scenario.fps
                )));
            }
        }
        let lighting: Lighting = scenario.lighting.unwrap_or(scene.lighting);
        let mut lit_scene = scene.clone();
        lit_scene.lighting = lighting;
        let shader = Shader::new(&lit_scene);
        let noise = noise_table(1 << 20, 0x0015_E7AB);
        let renderers: Vec<CameraRenderer> = std::thread::scope(|s| {
            let handles: Vec<_> = cameras
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let (sc, sh, nz) = (&lit_scene, &shader, &noise);
                    let lighting = lighting.for_camera(i);
                    s.spawn(move || CameraRenderer::new(c, sc, &lighting, sh, mode, nz))
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("camera preparation thread panicked"))
                .collect()
        });
        let reference = vec![(0.0, 0.0); scene.rods.len()];
        Ok(Simulation {
            ctx: Ctx {
                scene,
                scenario,
                cameras,
                mode,
                seed: 1,
                shader,
                noise,
                reference,
            },
            renderers,
        })
    }

    /// Renders the markers with `n x n` point rays per pixel (each the print where its ray
    /// meets the rod, none the mean over an area) instead of the pixel's whole area: as a ray
    /// tracer with a few rays per pixel renders, and as a sensor whose pixels see less than
    /// their whole area (a fill factor below 1) samples. The print's edges then move in the
    /// image in steps of `1 / n` px, and their positions alias with the pixel grid; the
    /// tracker's angle must average that over many edges. `n` is at least 1.
    pub fn with_point_rays(mut self, n: usize) -> Self {
        for r in &mut self.renderers {
            r.point_rays = Some(n.max(1));
        }
        self
    }

    /// Sets the seed of the sensor noise (same seed, same bytes).
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.ctx.seed = seed;
        self
    }

    /// Sets the reference pose `(position_mm, angle_rad)` of every rod (default all zero).
    pub fn set_reference_poses(&mut self, poses: &[(f64, f64)]) -> Result<(), SimError> {
        if poses.len() != self.ctx.scene.rods.len() {
            return Err(SimError::Config(format!(
                "{} reference poses for {} rods",
                poses.len(),
                self.ctx.scene.rods.len()
            )));
        }
        self.ctx.reference = poses.to_vec();
        Ok(())
    }

    /// The scene.
    pub fn scene(&self) -> &SceneConfig {
        &self.ctx.scene
    }
    /// The cameras.
    pub fn cameras(&self) -> &[SimCamera] {
        &self.ctx.cameras
    }
    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.ctx.scenario
    }
    /// The render mode.
    pub fn mode(&self) -> RenderMode {
        self.ctx.mode
    }
    /// Number of frames of the scenario.
    pub fn frame_count(&self) -> usize {
        self.ctx.scenario.frame_count()
    }
    /// Bytes of one frame of camera `cam` (tightly packed).
    pub fn frame_bytes(&self, cam: usize) -> Result<usize, SimError> {
        Ok(self.ctx.camera(cam)?.frame_bytes())
    }
    /// Trigger time of frame `i`, s (the physical time the world is rendered at).
    pub fn timestamp_s(&self, frame_index: usize) -> f64 {
        frame_index as f64 / self.ctx.scenario.fps
    }
    /// Trigger time of frame `i` as frames and truth carry it: [`frame_time`].
    pub fn timestamp(&self, frame_index: usize) -> Timestamp {
        frame_time(frame_index as u64, self.ctx.scenario.fps)
    }
    /// The world state at time `t_s`.
    pub fn state_at(&self, t_s: f64) -> WorldState {
        WorldState::at(&self.ctx.scene, &self.ctx.scenario, t_s)
    }

    /// Renders frame `frame_index` of camera `camera_index` into `out` (tightly packed,
    /// `width * bytes_per_pixel` bytes per row). Reuses the camera's buffers.
    pub fn render(
        &mut self,
        frame_index: usize,
        camera_index: usize,
        out: &mut [u8],
    ) -> Result<RenderInfo, SimError> {
        let r = self
            .renderers
            .get_mut(camera_index)
            .ok_or(SimError::NoSuchCamera {
                index: camera_index,
                count: self.ctx.cameras.len(),
            })?;
        self.ctx.render_frame(r, frame_index, camera_index, out)
    }

    /// Timing of the last frame rendered for camera `camera_index`.
    pub fn last_render_stats(&self, camera_index: usize) -> Option<crate::render::RenderStats> {
        self.renderers.get(camera_index).map(|r| r.stats)
    }

    /// Renders the reference frame of camera `camera_index`: every rod at its reference pose,
    /// no hands, no ball, no motion (with sensor noise).
    pub fn render_reference(
        &mut self,
        camera_index: usize,
        out: &mut [u8],
    ) -> Result<RenderInfo, SimError> {
        let r = self
            .renderers
            .get_mut(camera_index)
            .ok_or(SimError::NoSuchCamera {
                index: camera_index,
                count: self.ctx.cameras.len(),
            })?;
        self.ctx.render_reference(r, camera_index, out)
    }

    /// The frames of the reference folder with one rod at a known pose, as the validation
    /// tables have them: frames `1 + 3 k`, `2 + 3 k`, `3 + 3 k` hold rod `k` at the start, the
    /// middle (0) and the end of its travel, every other rod at its reference pose. Returns
    /// `(frame, rod, position_mm)`.
    pub fn known_pose_frames(&self) -> Vec<(usize, usize, f64)> {
        self.ctx
            .scene
            .rods
            .iter()
            .enumerate()
            .flat_map(|(i, r)| {
                known_pose_list(i, r.half_travel_mm())
                    .into_iter()
                    .map(move |(f, p)| (f, i, p))
            })
            .collect()
    }

    /// Renders camera `camera_index` with every rod at its reference pose but `rod`, which
    /// stands at `position_mm` (a known-pose frame of the reference folder).
    pub fn render_known_pose(
        &mut self,
        camera_index: usize,
        rod: usize,
        position_mm: f64,
        out: &mut [u8],
    ) -> Result<RenderInfo, SimError> {
        let mut poses = self.ctx.reference.clone();
        let p = poses.get_mut(rod).ok_or_else(|| {
            SimError::Config(format!(
                "no rod {rod} (the scene has {})",
                self.ctx.reference.len()
            ))
        })?;
        p.0 = position_mm;
        let st = WorldState::posed(&poses);
        self.render_state(camera_index, &st, u64::MAX - 1 - rod as u64, out)
            .map(|m| RenderInfo {
                frame_id: 0,
                timestamp_ns: Timestamp(0),
                ..m
            })
    }

    /// Renders camera `camera_index` with the world in an arbitrary state (no motion blur),
    /// for tests and overlays; `frame_id` only seeds the noise and labels the frame.
    pub fn render_state(
        &mut self,
        camera_index: usize,
        state: &WorldState,
        frame_id: u64,
        out: &mut [u8],
    ) -> Result<RenderInfo, SimError> {
        if state.rods.len() != self.ctx.scene.rods.len() {
            return Err(SimError::Config(format!(
                "state has {} rods, the scene {}",
                state.rods.len(),
                self.ctx.scene.rods.len()
            )));
        }
        let r = self
            .renderers
            .get_mut(camera_index)
            .ok_or(SimError::NoSuchCamera {
                index: camera_index,
                count: self.ctx.cameras.len(),
            })?;
        self.ctx.render_state(r, camera_index, state, frame_id, out)
    }

    /// Ground truth of every rod for frame `frame_index` seen by camera `camera_index`; values
    /// at the middle of the exposure, timestamp = the frame's trigger time.
    pub fn truth(
        &self,
        frame_index: usize,
        camera_index: usize,
    ) -> Result<Vec<TruthRow>, SimError> {
        self.ctx.truth(frame_index, camera_index)
    }

    /// Projects world `y_mm` on rod `rod`'s axis into camera `camera_index` (pixel, with
    /// distortion); `None` if behind the camera.
    pub fn project_rod_axis(
        &self,
        camera_index: usize,
        rod: usize,
        y_mm: f64,
    ) -> Result<Option<(f64, f64)>, SimError> {
        let cam = self.ctx.camera(camera_index)?;
        let r = self.ctx.rod(rod)?;
        Ok(cam.camera.project([r.x_mm, y_mm, r.z_mm]))
    }

    /// Status of rod `rod`'s marker in camera `camera_index` for a given world state:
    /// `Ok` (wholly visible), `OutOfView` or `Occluded`.
    pub fn marker_status(
        &self,
        camera_index: usize,
        rod: usize,
        state: &WorldState,
    ) -> Result<Status, SimError> {
        self.ctx.camera(camera_index)?;
        self.ctx.rod(rod)?;
        let g = WorldGeom::build(&self.ctx.scene, state, 0.0);
        Ok(self.ctx.marker_status(camera_index, rod, state, &g))
    }

    /// Calibrates camera `camera_index` from its simulated clicks (`seed`) and reference frame,
    /// rod by rod as `rodtrack calibrate` does (with the camera model in the inputs), at the
    /// scenario's frame rate. For benchmarks and tests that need a ready calibration.
    pub fn calibrated_camera(
        &mut self,
        camera_index: usize,
        seed: u64,
    ) -> Result<rodtrack_core::calib::CameraCalibration, SimError> {
        let inputs = self.calibration_inputs(camera_index, seed)?;
        let mut buf = vec![0u8; self.frame_bytes(camera_index)?];
        let meta = self.render_reference(camera_index, &mut buf)?;
        let view =
            rodtrack_core::FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format)?;
        let intrinsics = match &inputs.opencv_model_optional {
            Some(m) => Some(rodtrack_core::CameraIntrinsics::from_opencv(
                m.camera_matrix,
                &m.dist_coeffs,
            )?),
            None => None,
        };
        let rods = inputs
            .rods
            .iter()
            .map(|r| rodtrack_core::calib::calibrate_rod(r, &view, intrinsics.as_ref()))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(rodtrack_core::calib::CameraCalibration {
            name: inputs.camera_name.clone(),
            index: camera_index as u32,
            image_width: meta.width,
            image_height: meta.height,
            pixel_format: meta.format.name().into(),
            fps: 1.0 / self.timestamp_s(1).max(1e-6),
            opencv_model: inputs.opencv_model_optional.clone(),
            table: None,
            ball: None,
            rods,
        })
    }

    /// Calibration inputs (SPEC section 5) for camera `camera_index` with default options;
    /// `seed` drives the click errors.
    pub fn calibration_inputs(
        &self,
        camera_index: usize,
        seed: u64,
    ) -> Result<CalibrationInputs, SimError> {
        self.calibration_inputs_with(camera_index, seed, &CalibOptions::default())
    }

    /// Calibration inputs with explicit options.
    pub fn calibration_inputs_with(
        &self,
        camera_index: usize,
        seed: u64,
        opts: &CalibOptions,
    ) -> Result<CalibrationInputs, SimError> {
        self.ctx.calibration_inputs(camera_index, seed, opts)
    }
}

impl Ctx {
    pub fn camera(&self, i: usize) -> Result<&SimCamera, SimError> {
        self.cameras.get(i).ok_or(SimError::NoSuchCamera {
            index: i,
            count: self.cameras.len(),
        })
    }

    pub fn rod(&self, i: usize) -> Result<&crate::scene::RodConfig, SimError> {
        self.scene.rods.get(i).ok_or(SimError::NoSuchRod {
            index: i,
            count: self.scene.rods.len(),
        })
    }

    fn exposure_s(&self, cam: usize) -> f64 {
        self.cameras[cam].exposure_us * 1e-6
    }

    /// The geometry at the time samples of frame `frame_index` for camera `cam`, into
    /// reused buffers.
    fn fill_geoms(
        &self,
        frame_index: usize,
        cam: usize,
        st: &mut WorldState,
        geoms: &mut Vec<WorldGeom>,
    ) {
        let t0 = frame_index as f64 / self.scenario.fps;
        let exp = self.exposure_s(cam);
        let (n, blur) = match self.mode {
            RenderMode::Fast => (1, exp),
            RenderMode::Quality => (crate::render::QSUB * crate::render::QSUB, 0.0),
        };
        geoms.resize_with(n, WorldGeom::default);
        for (k, g) in geoms.iter_mut().enumerate() {
            let t = if n == 1 {
                t0 + 0.5 * exp
            } else {
                t0 + exp * (k as f64 + 0.5) / n as f64
            };
            st.set_at(&self.scene, &self.scenario, t);
            g.build_into(&self.scene, st, blur);
        }
        // Fast mode's one geometry blurs the ball analytically along its path over the
        // exposure (the chord from its start to its end).
        if n == 1 && exp > 0.0 {
            if let Some(b) = &self.scenario.ball {
                if let (Some(a), Some(z)) = (b.at(t0), b.at(t0 + exp)) {
                    geoms[0].ball_move = [(z.0 - a.0) as f32, (z.1 - a.1) as f32, 0.0];
                }
            }
        }
    }

    pub fn render_frame(
        &self,
        r: &mut CameraRenderer,
        frame_index: usize,
        cam: usize,
        out: &mut [u8],
    ) -> Result<RenderInfo, SimError> {
        let c = self.camera(cam)?;
        let need = c.frame_bytes();
        if out.len() < need {
            return Err(SimError::BufferSize {
                expected: need,
                got: out.len(),
            });
        }
        let t0 = frame_index as f64 / self.scenario.fps;
        let tm = t0 + 0.5 * self.exposure_s(cam);
        let mut geoms = std::mem::take(&mut r.scratch_geoms);
        let mut st = std::mem::take(&mut r.scratch_state);
        self.fill_geoms(frame_index, cam, &mut st, &mut geoms);
        let b = self.scenario.brightness.value(tm) as f32;
        let g = self.scenario.glare.value(tm).max(0.0) as f32;
        let seed = hash_words(&[self.seed, frame_index as u64, cam as u64]);
        r.render(
            &geoms,
            &self.shader,
            self.mode,
            b,
            g,
            &self.noise,
            seed,
            &mut out[..need],
        );
        r.scratch_geoms = geoms;
        r.scratch_state = st;
        Ok(self.meta(
            cam,
            frame_index as u64,
            frame_time(frame_index as u64, self.scenario.fps),
        ))
    }

    pub fn render_reference(
        &self,
        r: &mut CameraRenderer,
        cam: usize,
        out: &mut [u8],
    ) -> Result<RenderInfo, SimError> {
        let st = WorldState::posed(&self.reference);
        self.render_state(r, cam, &st, u64::MAX, out)
            .map(|m| RenderInfo {
                frame_id: 0,
                timestamp_ns: Timestamp(0),
                ..m
            })
    }

    pub fn render_state(
        &self,
        r: &mut CameraRenderer,
        cam: usize,
        st: &WorldState,
        frame_id: u64,
        out: &mut [u8],
    ) -> Result<RenderInfo, SimError> {
        let c = self.camera(cam)?;
        let need = c.frame_bytes();
        if out.len() < need {
            return Err(SimError::BufferSize {
                expected: need,
                got: out.len(),
            });
        }
        let g = WorldGeom::build(&self.scene, st, 0.0);
        let n = match self.mode {
            RenderMode::Fast => 1,
            RenderMode::Quality => crate::render::QSUB * crate::render::QSUB,
        };
        let geoms = vec![g; n];
        let b = self.scenario.brightness.value(0.0) as f32;
        let gl = self.scenario.glare.value(0.0).max(0.0) as f32;
        let seed = hash_words(&[self.seed, frame_id, cam as u64, 0x0005_7A7E]);
        r.render(
            &geoms,
            &self.shader,
            self.mode,
            b,
            gl,
            &self.noise,
            seed,
            &mut out[..need],
        );
        Ok(self.meta(cam, frame_id, frame_time(frame_id, self.scenario.fps)))
    }

    fn meta(&self, cam: usize, frame_id: u64, t: Timestamp) -> RenderInfo {
        let c = &self.cameras[cam];
        RenderInfo {
            frame_id,
            timestamp_ns: t,
            width: c.camera.width,
            height: c.camera.height,
            stride: c.camera.width * c.pixel_format.bytes_per_pixel(),
            format: c.pixel_format,
        }
    }

    pub fn truth(&self, frame_index: usize, cam: usize) -> Result<Vec<TruthRow>, SimError> {
        self.camera(cam)?;
        let t0 = frame_index as f64 / self.scenario.fps;
        let tm = t0 + 0.5 * self.exposure_s(cam);
        let st = WorldState::at(&self.scene, &self.scenario, tm);
        let g = WorldGeom::build(&self.scene, &st, 0.0);
        Ok((0..self.scene.rods.len())
            .map(|i| {
                let p = st.rods[i];
                let status = self.marker_status(cam, i, &st, &g);
                TruthRow {
                    m: Measurement {
                        frame: frame_index as u64,
                        timestamp_ns: frame_time(frame_index as u64, self.scenario.fps),
                        camera: CameraId::Camera(cam as u32),
                        rod: i as u32,
                        position_mm: p.position_mm,
                        angle_rad: wrap_2pi(p.angle_rad),
                        angle_unwrapped_rad: p.angle_rad,
                        velocity_mm_s: p.velocity_mm_s,
                        angular_velocity_rad_s: p.angular_velocity_rad_s,
                        quality: 1.0,
                        status,
                        turns_known: true,
                    }
                    .sanitized(),
                    visible: status == Status::Ok,
                }
            })
            .collect())
    }

    /// Ray-casts points on the camera-facing half of the marker.
    pub fn marker_status(&self, cam: usize, rod: usize, st: &WorldState, g: &WorldGeom) -> Status {
        let c = &self.cameras[cam];
        let rc = &self.scene.rods[rod];
        let len = self.scene.marker_len_mm();
        let o = c.camera.pose.centre_world();
        let (w, h) = (c.camera.width as f64, c.camera.height as f64);
        let pos = st.rods[rod].position_mm;
        let mut cands: Vec<Obj> = Vec::new();
        for (i, r) in g.rods.iter().enumerate() {
            if i != rod {
                cands.push(Obj::Rod(i as u16));
            }
            for k in 0..r.figs.len() {
                cands.push(Obj::Figure(i as u16, k as u16));
            }
        }
        for k in 0..g.hand_boxes.len() {
            cands.push(Obj::Hand(k as u16));
        }
        if g.ball.is_some() {
            cands.push(Obj::Ball);
        }
        let of: V3 = o.map(|v| v as f32);
        let mut occluded = false;
        for fu in VIS_U {
            let y = rc.marker_y(fu * len, pos);
            let gc = (o[0] - rc.x_mm).atan2(o[2] - rc.z_mm);
            for da in VIS_ANGLE {
                let a = gc + da;
                let p = [
                    rc.x_mm + rc.radius_mm() * a.sin(),
                    y,
                    rc.z_mm + rc.radius_mm() * a.cos(),
                ];
                match c.camera.project(p) {
                    Some((u, v)) if u >= 1.0 && v >= 1.0 && u <= w - 2.0 && v <= h - 2.0 => {}
                    _ => return Status::OutOfView,
                }
                if !occluded {
                    let dv = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
                    let dist = (dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]).sqrt();
                    let d: V3 = dv.map(|v| (v / dist) as f32);
                    let hit = self
                        .shader
                        .trace(g, &cands, of, d, 0.0, (dist - 0.5) as f32, None);
                    if hit.is_some() {
                        occluded = true;
                    }
                }
            }
        }
        if occluded {
            Status::Occluded
        } else {
            Status::Ok
        }
    }
}
