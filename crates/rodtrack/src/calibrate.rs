//! `rodtrack calibrate`: from calibration-inputs files (clicked path points and a reference
//! frame), or automatically (`--auto`) from recordings in which every rod sweeps its travel.
//!
//! The automatic mode, per camera (cameras in parallel):
//! 1. reads the input (an image folder, `raw:`, `video:`, `sim://`, ...; of an image folder only
//!    the frames it analyses are decoded: every `--every`-th, by default about 150 of them);
//! 2. finds every marker in the reference frame (`--reference-frame`, default 0, where every
//!    rod is at its reference pose, 0 mm and 0 rad): a full scan of the frame in both
//!    orientations (`find_markers`); the rods, in image order, get the ids of `--rods`;
//! 3. follows each rod through the analysed frames, forward and backward from the reference,
//!    with a scan of the few image lines around its last detection at scales near its last one
//!    (`find_markers_in`, about 10x faster than a full scan); the detections are its path
//!    points (`path_points_from_sweep`), those of a rod at rest merged into one;
//! 4. measures each rod's travel from its detections unless `--travel-mm` gives it;
//! 5. writes the calibration inputs it derived (`--save-inputs`, by default
//!    `<out>.<camera>.json`, with the reference frame beside it as `<inputs>_ref/000000.png`),
//!    so that an operator can inspect or edit them and rerun `calibrate --inputs`, which then
//!    gives the same calibration; then calibrates every rod from them (`calibrate_rod`),
//!    prints the residuals and warns (stderr) about badly spread path points and doubtful
//!    references.

use anyhow::{anyhow, bail, Context, Result};
use rodtrack_core::calib::validate::{MAX_RODS_PER_CAMERA, MAX_ROD_ID, MAX_TRAVEL_MM};
use rodtrack_core::calib::CameraCalibration;
use rodtrack_core::{MarkerSpec, PixelFormat};
use rodtrack_sdk::auto::{auto_camera, open_sweep, save_auto_inputs, AutoCamera, AutoConfig};
use rodtrack_sdk::{
    calibrate_camera_file, calibration_file, print_warning, read_inputs, read_opencv_model,
    write_calibration,
};
use std::path::{Path, PathBuf};

/// Arguments of `rodtrack calibrate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Calibration-inputs JSON, one per camera (repeat for several cameras).
    #[arg(
        long = "inputs",
        required_unless_present = "auto",
        conflicts_with = "auto"
    )]
    pub inputs: Vec<PathBuf>,
    /// Output calibration file (TOML).
    #[arg(long)]
    pub out: PathBuf,
    /// Automatic calibration from recordings in which every rod sweeps its travel (`--input`
    /// per camera) instead of calibration inputs.
    #[arg(long, requires = "input")]
    pub auto: bool,
    /// `--auto`: frame source per camera, in camera order (as `rodtrack track --input`: a
    /// folder of images, `raw:...`, `video:...`, `sim://sweep?camera=N`, ...).
    #[arg(long = "input", requires = "auto")]
    pub input: Vec<String>,
    /// `--auto`: the frame (index in reading order) in which every rod is at its reference pose
    /// (0 mm, 0 rad).
    #[arg(long, default_value_t = 0)]
    pub reference_frame: usize,
    /// `--auto`: travel of every rod, mm, as `MIN,MAX` (default: measured from the sweep, per
    /// rod).
    #[arg(long, requires = "auto", allow_hyphen_values = true, value_parser = parse_travel)]
    pub travel_mm: Option<[f64; 2]>,
    /// `--auto`: the marker description (JSON or TOML, the `marker` object of the calibration
    /// inputs); default marker v1 on a 16 mm rod.
    #[arg(long, requires = "auto")]
    pub marker: Option<PathBuf>,
    /// `--auto`: the camera model as OpenCV's `cv::FileStorage` wrote it after
    /// `calibrateCamera` (YAML or JSON), one per `--input` in the same order.
    #[arg(long = "opencv-model", requires = "auto")]
    pub opencv_model: Vec<PathBuf>,
    /// `--auto`: how to read grey images (`bayer_rggb8`, `mono8`, ...); default: 8-bit grey
    /// images are Bayer RGGB (the reference camera), other images as they are.
    #[arg(long, requires = "auto")]
    pub pixel_format: Option<String>,
    /// `--auto`: the ids of the rods a camera sees, in image order (left to right for rods along
    /// image rows, top to bottom otherwise), e.g. `0-6`, `7-1` or `0,1,2`; one per `--input`.
    /// Default: 0, 1, 2, ...
    #[arg(long = "rods", requires = "auto")]
    pub rods: Vec<String>,
    /// `--auto`: where to write the calibration inputs derived, one per `--input` (default
    /// `<out without extension>.<camera>.json`).
    #[arg(long = "save-inputs", requires = "auto")]
    pub save_inputs: Vec<PathBuf>,
    /// `--auto`: analyse every N-th frame (default: about 150 frames of the recording).
    #[arg(long, requires = "auto", value_parser = clap::value_parser!(u64).range(1..))]
    pub every: Option<u64>,
    /// `--auto`: frame rate written to the calibration (default: the source's, else 200).
    #[arg(long, requires = "auto")]
    pub fps: Option<f64>,
    /// `--auto`: read at most this many frames per camera (needed for live sources).
    #[arg(long, requires = "auto")]
    pub max_frames: Option<u64>,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    if args.auto {
        return run_auto(&args);
    }
    let mut cameras = Vec::new();
    for (index, path) in args.inputs.iter().enumerate() {
        let inputs = read_inputs(path, &mut print_warning)?;
        let cam = calibrate_camera_file(&inputs, path, index as u32)?;
        print_report(&cam);
        cameras.push(cam);
    }
    write_file(&args.out, cameras)
}

/// Validates and writes the calibration file.
fn write_file(out: &Path, cameras: Vec<CameraCalibration>) -> Result<()> {
    let file = calibration_file(cameras)?;
    write_calibration(out, &file)?;
    println!("wrote {}", out.display());
    Ok(())
}

/// Prints per-rod residuals and warnings.
pub fn print_report(cam: &CameraCalibration) {
    println!("camera {} ({}):", cam.index, cam.name);
    if let Some(r) = cam
        .rods
        .iter()
        .find(|r| !r.residuals.common_direction.is_empty())
    {
        println!(
            "  the rods' common direction: {}",
            r.residuals.common_direction
        );
    }
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
        if !s.travel_model.is_empty() {
            let rods = s
                .depth_change_per_m_from_rods
                .map(|d| format!(" (the parallel rods give {d:+.4})"))
                .unwrap_or_default();
            println!(
                "       along the travel: {}, depth change {:+.4} per m{rods}",
                s.travel_model, s.depth_change_per_m
            );
        }
        for [frame, err] in &s.known_pose_errors_mm {
            println!("       known pose in frame {frame}: position read {err:+.3} mm off");
        }
        if !r.enhanced.angle_bias_rad.is_empty() {
            let pts: Vec<String> = r
                .enhanced
                .angle_bias_rad
                .iter()
                .map(|[p, b]| format!("{b:+.4} rad at {p:.1} mm"))
                .collect();
            println!(
                "       angle bias along the travel (removed): {}",
                pts.join(", ")
            );
        }
        for w in &s.warnings {
            println!("       warning: {w}");
        }
    }
}

// ---- automatic calibration (`--auto`) ----

/// `MIN,MAX` in mm.
fn parse_travel(s: &str) -> Result<[f64; 2], String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("`{s}`: expected MIN,MAX in mm, e.g. -100,100"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && v.abs() <= MAX_TRAVEL_MM)
            .ok_or_else(|| format!("`{t}` is not a number of mm within +-{MAX_TRAVEL_MM}"))
    };
    let (a, b) = (p(a)?, p(b)?);
    if a >= b {
        return Err(format!("`{s}`: MIN must be below MAX"));
    }
    Ok([a, b])
}

/// `0-6`, `7-1`, `0,2,4-5`: rod ids in image order.
fn parse_rod_list(s: &str) -> Result<Vec<u32>> {
    let mut ids = Vec::new();
    for part in s.split(',') {
        let part = part.trim();
        let num = |t: &str| {
            t.trim()
                .parse::<u32>()
                .ok()
                .filter(|id| *id <= MAX_ROD_ID)
                .ok_or_else(|| anyhow!("--rods {s}: `{t}` is not a rod id (0 to {MAX_ROD_ID})"))
        };
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b) = (num(a)?, num(b)?);
                // Before any allocation sized by the range.
                if a.abs_diff(b) as usize + ids.len() >= MAX_RODS_PER_CAMERA {
                    bail!("--rods {s}: more than {MAX_RODS_PER_CAMERA} rods");
                }
                if a <= b {
                    ids.extend(a..=b);
                } else {
                    ids.extend((b..=a).rev());
                }
            }
            None => {
                if ids.len() >= MAX_RODS_PER_CAMERA {
                    bail!("--rods {s}: more than {MAX_RODS_PER_CAMERA} rods");
                }
                ids.push(num(part)?)
            }
        }
    }
    let mut sorted = ids.clone();
    sorted.sort_unstable();
    sorted.dedup();
    if sorted.len() != ids.len() {
        bail!("--rods {s}: a rod id is given twice");
    }
    Ok(ids)
}

/// A marker description file (JSON, or TOML by its extension).
fn read_marker(path: &Path) -> Result<MarkerSpec> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the marker description {}", path.display()))?;
    let toml_file = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let spec: MarkerSpec = if toml_file {
        toml::from_str(&text)
            .with_context(|| format!("marker description {} is malformed", path.display()))?
    } else {
        serde_json::from_str(&text)
            .with_context(|| format!("marker description {} is malformed", path.display()))?
    };
    Ok(spec)
}

/// `rodtrack calibrate --auto`.
fn run_auto(args: &Args) -> Result<()> {
    let n = args.input.len();
    let per_input = |len: usize, what: &str| -> Result<()> {
        if len != 0 && len != n {
            bail!("give one {what} per --input ({n} input(s), {len} {what})");
        }
        Ok(())
    };
    per_input(args.opencv_model.len(), "--opencv-model")?;
    per_input(args.rods.len(), "--rods")?;
    per_input(args.save_inputs.len(), "--save-inputs")?;
    if args.fps.is_some_and(|f| !(f > 0.0 && f.is_finite())) {
        bail!("--fps must be a positive number of frames per second");
    }
    let marker_spec = match &args.marker {
        Some(p) => read_marker(p)?,
        None => MarkerSpec::default(),
    };
    let marker = marker_spec.validate().with_context(|| match &args.marker {
        Some(p) => format!("marker description {}", p.display()),
        None => "the default marker".into(),
    })?;
    let format = args
        .pixel_format
        .as_deref()
        .map(|f| {
            PixelFormat::from_name(f).ok_or_else(|| {
                anyhow!(
                    "--pixel-format {f}: unknown (known: {})",
                    PixelFormat::ALL.map(|p| p.name()).join(", ")
                )
            })
        })
        .transpose()?;
    let models = args
        .opencv_model
        .iter()
        .map(|p| read_opencv_model(p).map_err(anyhow::Error::from))
        .collect::<Result<Vec<_>>>()?;
    let rod_ids = args
        .rods
        .iter()
        .map(|s| parse_rod_list(s))
        .collect::<Result<Vec<_>>>()?;
    if rod_ids.is_empty() && n > 1 {
        eprintln!(
            "note: rods are numbered 0, 1, 2, ... in image order in every camera: give --rods \
             per camera so that a rod seen by two cameras has one id"
        );
    }
    let cfg = AutoConfig {
        marker_spec,
        marker,
        reference_frame: args.reference_frame,
        travel_mm: args.travel_mm,
        max_frames: args.max_frames,
        fps: args.fps,
        note: rodtrack_sdk::auto::print_note,
    };
    let sources = args
        .input
        .iter()
        .enumerate()
        .map(|(i, input)| open_sweep(input, i, format, args.every, &cfg))
        .collect::<Result<Vec<_>, _>>()?;
    let started = std::time::Instant::now();
    let results: Vec<Result<AutoCamera, rodtrack_sdk::SdkError>> = std::thread::scope(|s| {
        let handles: Vec<_> = sources
            .into_iter()
            .enumerate()
            .map(|(i, src)| {
                let cfg = &cfg;
                let model = models.get(i).cloned();
                let ids = rod_ids.get(i).cloned();
                s.spawn(move || auto_camera(i, src, cfg, model, ids))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join().unwrap_or_else(|_| {
                    Err(rodtrack_sdk::SdkError::Runtime(
                        "a camera's thread panicked".into(),
                    ))
                })
            })
            .collect()
    });
    let mut cameras = Vec::new();
    for r in results {
        cameras.push(r?);
    }
    let stem = args
        .out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "calib".into());
    let mut calibrations = Vec::new();
    for (i, cam) in cameras.iter_mut().enumerate() {
        for line in &cam.summary {
            println!("{line}");
        }
        print_report(&cam.calibration);
        for w in &cam.warnings {
            eprintln!("warning: camera {i}: {w}");
        }
        let path = match args.save_inputs.get(i) {
            Some(p) => p.clone(),
            None => args
                .out
                .with_file_name(format!("{stem}.{}.json", cam.inputs.camera_name)),
        };
        save_auto_inputs(&path, cam)?;
        println!(
            "wrote {} (calibration inputs; edit and rerun with --inputs)",
            path.display()
        );
        calibrations.push(cam.calibration.clone());
    }
    eprintln!(
        "automatic calibration of {n} camera(s) in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    write_file(&args.out, calibrations)
}
