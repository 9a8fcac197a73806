//! The calibration service: per camera, the frozen frame and the calibration inputs being
//! edited in the browser; calibration with [`rodtrack_core::calib::calibrate_rod`], exactly as
//! `rodtrack calibrate` does it; the calibration file written as TOML.

use crate::image::{to_pnm, OwnedFrame};
use crate::ConsoleError;
use rodtrack_core::calib::{
    calibrate_rods, CalibrationFile, CalibrationInputs, CameraCalibration, ImageSize, KnownPose,
    ReferenceFrames, ReferencePose, Residuals, RodInputs, CALIBRATION_VERSION,
};
use rodtrack_core::{CameraIntrinsics, LumaKind, MarkerSpec};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What the console calibrates: the cameras' inputs (and reference frames, when there are
/// some) and where the calibration file goes.
#[derive(Debug, Clone, Default)]
pub struct CalibrationContext {
    /// Where "save" writes the calibration file (TOML); `None` disables saving.
    pub out_path: Option<PathBuf>,
    /// The cameras known from the start.
    pub cameras: Vec<CameraSetup>,
}

/// One camera's starting point for calibration.
#[derive(Debug, Clone)]
pub struct CameraSetup {
    /// Camera index (as in the rows and the calibration file).
    pub index: u32,
    /// The calibration inputs (rods, path points, reference poses) to start from.
    pub inputs: CalibrationInputs,
    /// The reference frame, frozen from the start (e.g. read from the inputs' folder).
    pub reference: Option<OwnedFrame>,
}

/// How calibrating one rod went.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RodOutcome {
    /// Rod id.
    pub rod: u32,
    /// The residuals, when calibration succeeded.
    pub residuals: Option<Residuals>,
    /// The error, when it failed.
    pub error: Option<String>,
}

/// One camera in the calibration service.
#[derive(Debug, Clone)]
pub(crate) struct CalibCamera {
    pub index: u32,
    pub inputs: CalibrationInputs,
    pub frozen: Option<OwnedFrame>,
    /// Frames captured with a rod at a known pose: frame `i + 1` of the reference folder
    /// (the frozen frame is frame 0), named by the rods' `known_poses`.
    pub pose_frames: Vec<OwnedFrame>,
    pub outcomes: Vec<RodOutcome>,
    pub calibration: Option<CameraCalibration>,
}

/// Which end stop of its travel a rod is pushed against for a known pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Stop {
    /// The start of the travel (`travel_mm[0]`).
    Left,
    /// The end of the travel (`travel_mm[1]`).
    Right,
}

/// A known-pose capture waiting for the camera's next frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub(crate) struct PoseCapture {
    pub camera: u32,
    pub rod: u32,
    pub stop: Stop,
}

/// Every camera in the calibration service.
#[derive(Debug, Default)]
pub(crate) struct CalibState {
    pub out_path: Option<PathBuf>,
    pub cameras: Vec<CalibCamera>,
    pub saved: Option<String>,
    /// The known-pose capture the next frozen frame is for (else it is the reference frame).
    pub pending_pose: Option<PoseCapture>,
}

/// Default inputs for a camera that has none (the operator adds rods in the browser).
pub fn default_inputs(index: u32, frame: &OwnedFrame) -> CalibrationInputs {
    CalibrationInputs {
        camera_name: format!("cam{index}"),
        image_size: ImageSize {
            width: frame.width(),
            height: frame.height(),
        },
        pixel_format: frame.format().name().to_string(),
        opencv_model_optional: None,
        reference_frames: ReferenceFrames {
            dir: format!("cam{index}"),
            reference_frame: 0,
        },
        fps: None,
        rods: Vec::new(),
        table: None,
        ball: None,
    }
}

/// A new rod's inputs: marker v1, no points, reference pose (0, 0).
pub fn new_rod(rod: u32, travel_mm: [f64; 2]) -> RodInputs {
    RodInputs {
        rod,
        path_points_px: Vec::new(),
        travel_mm,
        reference: ReferencePose {
            frame: 0,
            position_mm: 0.0,
            angle_rad: 0.0,
        },
        known_poses: Vec::new(),
        travel_frames: None,
        marker: MarkerSpec::default(),
    }
}

impl CalibState {
    pub fn new(ctx: CalibrationContext) -> CalibState {
        let mut cameras: Vec<CalibCamera> = ctx
            .cameras
            .into_iter()
            .map(|c| {
                let mut inputs = c.inputs;
                // The console holds one reference frame and the poses it captures itself:
                // known poses naming other frames of a folder have no frame here.
                for r in &mut inputs.rods {
                    r.known_poses.clear();
                    r.travel_frames = None;
                }
                CalibCamera {
                    index: c.index,
                    inputs,
                    frozen: c.reference,
                    pose_frames: Vec::new(),
                    outcomes: Vec::new(),
                    calibration: None,
                }
            })
            .collect();
        cameras.sort_by_key(|c| c.index);
        CalibState {
            out_path: ctx.out_path,
            cameras,
            saved: None,
            pending_pose: None,
        }
    }

    pub fn camera_mut(&mut self, index: u32) -> Option<&mut CalibCamera> {
        self.cameras.iter_mut().find(|c| c.index == index)
    }

    pub fn camera(&self, index: u32) -> Option<&CalibCamera> {
        self.cameras.iter().find(|c| c.index == index)
    }

    /// Stores a frozen frame, creating the camera with default inputs when it is new; when a
    /// known-pose capture of this camera is pending ([`CalibState::pending_pose`]), the frame
    /// is that pose's instead (see [`CalibCamera::add_known_pose`]).
    pub fn freeze(&mut self, index: u32, frame: OwnedFrame) {
        if let Some(p) = self.pending_pose.filter(|p| p.camera == index) {
            self.pending_pose = None;
            if let Some(c) = self.camera_mut(index) {
                c.add_known_pose(p.rod, p.stop, frame);
                return;
            }
        }
        match self.camera_mut(index) {
            Some(c) => {
                c.frozen = Some(frame);
                c.calibration = None;
            }
            None => {
                let inputs = default_inputs(index, &frame);
                self.cameras.push(CalibCamera {
                    index,
                    inputs,
                    frozen: Some(frame),
                    pose_frames: Vec::new(),
                    outcomes: Vec::new(),
                    calibration: None,
                });
                self.cameras.sort_by_key(|c| c.index);
            }
        }
    }

    pub fn rod_mut(&mut self, camera: u32, rod: u32) -> Result<&mut RodInputs, ConsoleError> {
        let cam = self
            .camera_mut(camera)
            .ok_or_else(|| ConsoleError::Camera {
                camera,
                reason: "not in the calibration (freeze a frame first)".into(),
            })?;
        cam.calibration = None;
        cam.inputs
            .rods
            .iter_mut()
            .find(|r| r.rod == rod)
            .ok_or(ConsoleError::NoSuchRod { camera, rod })
    }
}

impl CalibCamera {
    /// Takes `frame` as rod `rod`'s known pose at `stop` (its travel's end there): the frame
    /// becomes the next frame of the reference folder and the rod's `known_poses` names it,
    /// replacing an earlier capture at the same stop.
    pub(crate) fn add_known_pose(&mut self, rod: u32, stop: Stop, frame: OwnedFrame) {
        let Some(r) = self.inputs.rods.iter_mut().find(|r| r.rod == rod) else {
            return;
        };
        let position_mm = match stop {
            Stop::Left => r.travel_mm[0],
            Stop::Right => r.travel_mm[1],
        };
        self.pose_frames.push(frame);
        let pose = KnownPose {
            frame: self.pose_frames.len(),
            position_mm,
            angle_rad: None,
        };
        r.known_poses.retain(|k| k.position_mm != position_mm);
        r.known_poses.push(pose);
        r.known_poses
            .sort_by(|a, b| a.position_mm.total_cmp(&b.position_mm));
        self.calibration = None;
    }
}

/// Calibrates every rod of one camera on its frozen frame and its captured known poses, as
/// `rodtrack calibrate` does (every rod together: [`calibrate_rods`]). Returns the per-rod
/// outcomes and, when every rod succeeded, the camera's calibration.
pub(crate) fn calibrate_camera(
    cam: &CalibCamera,
) -> Result<(Vec<RodOutcome>, Option<CameraCalibration>), ConsoleError> {
    let camera = cam.index;
    let frame = cam.frozen.as_ref().ok_or_else(|| ConsoleError::Camera {
        camera,
        reason: "no frozen frame to calibrate on".into(),
    })?;
    let view = frame.view()?;
    let intrinsics = match &cam.inputs.opencv_model_optional {
        Some(m) => Some(CameraIntrinsics::from_opencv(
            m.camera_matrix,
            &m.dist_coeffs,
        )?),
        None => None,
    };
    // The reference folder as `save` writes it: the frozen frame is frame 0 (every rod's
    // reference), the known poses' frames follow.
    let mut frames = vec![(0, view)];
    for (i, f) in cam.pose_frames.iter().enumerate() {
        frames.push((i + 1, f.view()?));
    }
    let mut inputs = cam.inputs.rods.clone();
    for r in &mut inputs {
        r.reference.frame = 0;
    }
    let results = calibrate_rods(&inputs, &frames, intrinsics.as_ref());
    let mut outcomes = Vec::new();
    let mut rods = Vec::new();
    for (r, result) in cam.inputs.rods.iter().zip(results) {
        match result {
            Ok(c) => {
                outcomes.push(RodOutcome {
                    rod: r.rod,
                    residuals: Some(c.residuals.clone()),
                    error: None,
                });
                rods.push(c);
            }
            Err(e) => outcomes.push(RodOutcome {
                rod: r.rod,
                residuals: None,
                error: Some(e.to_string()),
            }),
        }
    }
    let complete = !rods.is_empty() && rods.len() == cam.inputs.rods.len();
    let calibration = complete.then(|| CameraCalibration {
        name: cam.inputs.camera_name.clone(),
        index: camera,
        image_width: view.width(),
        image_height: view.height(),
        pixel_format: view.format().name().to_string(),
        fps: cam.inputs.fps.unwrap_or(200.0),
        opencv_model: cam.inputs.opencv_model_optional.clone(),
        table: None,
        ball: None,
        rods,
    });
    Ok((outcomes, calibration))
}

/// The header `rodtrack calibrate` writes above the TOML.
const TOML_HEADER: &str =
    "# rodtrack calibration file. Made by the rodtrack console; validated on load.\n\
# knots: the rod's line every step_mm along its axis (enhanced mode);\n\
# paper: the paper's parameters (O_m = offset_px, S_m = spacing_px, T_hat = period_px).\n\n";

/// The calibration file of every camera (all must be calibrated), as TOML text.
pub(crate) fn calibration_toml(cameras: &[CalibCamera]) -> Result<String, ConsoleError> {
    if cameras.is_empty() {
        return Err(ConsoleError::BadRequest {
            field: "cameras",
            reason: "no camera to save".into(),
        });
    }
    let mut list = Vec::new();
    for c in cameras {
        let cal = c.calibration.clone().ok_or_else(|| ConsoleError::Camera {
            camera: c.index,
            reason: "not calibrated (every rod must calibrate before saving)".into(),
        })?;
        list.push(cal);
    }
    let file = CalibrationFile {
        version: CALIBRATION_VERSION,
        cameras: list,
    };
    file.validate()?;
    let text = toml::to_string_pretty(&file).map_err(|e| ConsoleError::Serialize {
        what: "the calibration",
        reason: e.to_string(),
    })?;
    Ok(format!("{TOML_HEADER}{text}"))
}

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ConsoleError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, bytes).map_err(|source| ConsoleError::Write {
        path: tmp.clone(),
        source,
    })?;
    std::fs::rename(&tmp, path).map_err(|source| ConsoleError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// What "save" wrote.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Saved {
    /// The calibration file.
    pub calibration: PathBuf,
    /// The calibration inputs written beside it (one JSON per camera, with its reference
    /// frame), so that `rodtrack calibrate --inputs ...` reproduces the file.
    pub inputs: Vec<PathBuf>,
}

/// Writes the calibration file and, in `<out>.inputs/`, each camera's inputs JSON and frozen
/// reference frame (PNM).
pub(crate) fn save(out: &Path, cameras: &[CalibCamera]) -> Result<Saved, ConsoleError> {
    let text = calibration_toml(cameras)?;
    let dir = out.with_extension("inputs");
    let mut inputs_paths = Vec::new();
    for c in cameras {
        let Some(frame) = &c.frozen else { continue };
        let name = format!("cam{}", c.index);
        let frames_dir = dir.join(&name);
        std::fs::create_dir_all(&frames_dir).map_err(|source| ConsoleError::Write {
            path: frames_dir.clone(),
            source,
        })?;
        let ext = if frame.format().luma_kind() == LumaKind::Rgb {
            "ppm"
        } else {
            "pgm"
        };
        write_atomic(&frames_dir.join(format!("000000.{ext}")), &to_pnm(frame))?;
        // The known poses' frames, in the order their `known_poses` name them.
        for (i, f) in c.pose_frames.iter().enumerate() {
            write_atomic(&frames_dir.join(format!("{:06}.{ext}", i + 1)), &to_pnm(f))?;
        }
        let mut inputs = c.inputs.clone();
        inputs.reference_frames = ReferenceFrames {
            dir: name.clone(),
            reference_frame: 0,
        };
        for r in &mut inputs.rods {
            r.reference.frame = 0;
        }
        // The ball's click names a frame of its own, which is not among the frames saved here
        // (the table's points lie in the reference frame, which is): left out, the saved
        // inputs calibrate as they are.
        inputs.ball = None;
        let json = serde_json::to_string_pretty(&inputs).map_err(|e| ConsoleError::Serialize {
            what: "the calibration inputs",
            reason: e.to_string(),
        })?;
        let p = dir.join(format!("{name}.json"));
        write_atomic(&p, json.as_bytes())?;
        inputs_paths.push(p);
    }
    write_atomic(out, text.as_bytes())?;
    Ok(Saved {
        calibration: out.to_path_buf(),
        inputs: inputs_paths,
    })
}
