//! `rodtrack calibrate`.

use crate::calibration_io::{read_inputs, write_calibration};
use anyhow::{anyhow, bail, Context, Result};
use rodtrack_core::calib::{
    calibrate_rod, CalibrationFile, CalibrationInputs, CameraCalibration, CALIBRATION_VERSION,
};
use rodtrack_core::{CameraIntrinsics, FrameView, PixelFormat};
use rodtrack_io::source::{decode_image_file, list_image_files};
use rodtrack_io::FrameBuffer;
use std::path::{Path, PathBuf};

/// Arguments of `rodtrack calibrate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Calibration-inputs JSON, one per camera (repeat for several cameras).
    #[arg(long = "inputs", required = true)]
    pub inputs: Vec<PathBuf>,
    /// Output calibration file (TOML).
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let mut cameras = Vec::new();
    for (index, path) in args.inputs.iter().enumerate() {
        let inputs = read_inputs(path)?;
        let cam = calibrate_camera(&inputs, path, index as u32)?;
        print_report(&cam);
        cameras.push(cam);
    }
    let file = CalibrationFile {
        version: CALIBRATION_VERSION,
        cameras,
    };
    file.validate().context("the calibration made is invalid")?;
    write_calibration(&args.out, &file)?;
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Calibrates one camera from its inputs file (reference frames relative to it).
pub fn calibrate_camera(
    inputs: &CalibrationInputs,
    path: &Path,
    index: u32,
) -> Result<CameraCalibration> {
    let name = path.display().to_string();
    let format = PixelFormat::from_name(&inputs.pixel_format).ok_or_else(|| {
        anyhow!(
            "{name}: field `pixel_format`: unknown format {:?}",
            inputs.pixel_format
        )
    })?;
    let intrinsics = match &inputs.opencv_model_optional {
        Some(m) => Some(
            CameraIntrinsics::from_opencv(m.camera_matrix, &m.dist_coeffs)
                .with_context(|| format!("{name}: field `opencv_model_optional`"))?,
        ),
        None => None,
    };
    let dir = path
        .parent()
        .unwrap_or(Path::new("."))
        .join(&inputs.reference_frames.dir);
    let files =
        list_image_files(&dir).with_context(|| format!("{name}: field `reference_frames.dir`"))?;
    let mut rods = Vec::new();
    let mut frames: Vec<(usize, FrameBuffer)> = Vec::new();
    for rod in &inputs.rods {
        let idx = rod.reference.frame;
        if !frames.iter().any(|(i, _)| *i == idx) {
            let file = files.get(idx).ok_or_else(|| {
                anyhow!(
                    "{name}: rod {}: field `reference.frame`: frame {idx} does not exist ({} images in {})",
                    rod.rod,
                    files.len(),
                    dir.display()
                )
            })?;
            let mut buf = FrameBuffer::new();
            decode_image_file(file, Some(format), &mut buf)
                .with_context(|| format!("reference frame {}", file.display()))?;
            frames.push((idx, buf));
        }
        let Some((_, buf)) = frames.iter().find(|(i, _)| *i == idx) else {
            bail!("internal: reference frame {idx} not loaded");
        };
        let view: FrameView = buf.view()?;
        if view.width() != inputs.image_size.width || view.height() != inputs.image_size.height {
            bail!(
                "{name}: reference frame is {}x{} but `image_size` says {}x{}",
                view.width(),
                view.height(),
                inputs.image_size.width,
                inputs.image_size.height
            );
        }
        let cal = calibrate_rod(rod, &view, intrinsics.as_ref())
            .with_context(|| format!("{name}: calibrating rod {}", rod.rod))?;
        rods.push(cal);
    }
    Ok(CameraCalibration {
        name: inputs.camera_name.clone(),
        index,
        image_width: inputs.image_size.width,
        image_height: inputs.image_size.height,
        pixel_format: format.name().to_string(),
        fps: inputs.fps.unwrap_or(200.0),
        opencv_model: inputs.opencv_model_optional.clone(),
        rods,
    })
}

/// Calibrates every rod of one camera from its inputs and a reference frame already in memory
/// (all rods at their reference pose in that frame).
pub fn calibrate_from_view(
    inputs: &CalibrationInputs,
    view: &FrameView,
    index: u32,
    default_fps: f64,
) -> Result<CameraCalibration> {
    let intrinsics = match &inputs.opencv_model_optional {
        Some(m) => Some(
            CameraIntrinsics::from_opencv(m.camera_matrix, &m.dist_coeffs)
                .with_context(|| format!("camera {index}: field `opencv_model_optional`"))?,
        ),
        None => None,
    };
    let rods = inputs
        .rods
        .iter()
        .map(|r| {
            calibrate_rod(r, view, intrinsics.as_ref())
                .with_context(|| format!("camera {index}: calibrating rod {}", r.rod))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(CameraCalibration {
        name: inputs.camera_name.clone(),
        index,
        image_width: view.width(),
        image_height: view.height(),
        pixel_format: view.format().name().to_string(),
        fps: inputs.fps.unwrap_or(default_fps),
        opencv_model: inputs.opencv_model_optional.clone(),
        rods,
    })
}

/// Prints per-rod residuals and warnings.
pub fn print_report(cam: &CameraCalibration) {
    println!("camera {} ({}):", cam.index, cam.name);
    println!(
        "  rod  line    path rms/max px  edge rms mm  ref ncc  code-phase steps  radius ratio  paper"
    );
    for r in &cam.rods {
        let s = &r.residuals;
        println!(
            "  {:>3}  {:<6}  {:>6.2} / {:<6.2}  {:>11.3}  {:>7.3}  {:>16.2}  {:>12.3}  {}",
            r.rod,
            r.line_model,
            s.path_rms_px,
            s.path_max_px,
            s.edge_rms_mm,
            s.reference_ncc,
            s.reference_code_phase_steps,
            s.radius_ratio,
            if r.paper.is_some() { "yes" } else { "no" }
        );
        for w in &s.warnings {
            println!("       warning: {w}");
        }
    }
}
