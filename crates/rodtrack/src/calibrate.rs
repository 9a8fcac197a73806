//! `rodtrack calibrate`: from calibration-inputs files (clicked path points and a reference
//! frame), or automatically (`--auto`) from recordings in which every rod sweeps its travel.
//!
//! The automatic mode, per camera (cameras in parallel):
//! 1. reads the input (an image folder, `raw:`, `video:`, `sim://`, ...; of an image folder only
//!    the frames it analyses are decoded: every `--every`-th, by default about 150 of them);
//! 2. finds every marker in the reference frame (`--reference-frame`, default 0, where every
//!    rod is at its reference pose, 0 mm and 0 rad): a full scan of the frame in both
//!    orientations ([`find_markers`]); the rods, in image order, get the ids of `--rods`;
//! 3. follows each rod through the analysed frames, forward and backward from the reference,
//!    with a scan of the few image lines around its last detection at scales near its last one
//!    ([`find_markers_in`], about 10x faster than a full scan); the detections are its path
//!    points ([`path_points_from_sweep`]), those of a rod at rest merged into one;
//! 4. measures each rod's travel from its detections unless `--travel-mm` gives it;
//! 5. writes the calibration inputs it derived (`--save-inputs`, by default
//!    `<out>.<camera>.json`, with the reference frame beside it as `<inputs>_ref/000000.png`),
//!    so that an operator can inspect or edit them and rerun `calibrate --inputs`, which then
//!    gives the same calibration; then calibrates every rod from them ([`calibrate_rod`]),
//!    prints the residuals and warns (stderr) about badly spread path points and doubtful
//!    references.

use anyhow::{anyhow, bail, Context, Result};
use rodtrack_core::calib::find::{
    find_markers, find_markers_in, path_points_from_sweep, FoundMarker,
};
use rodtrack_core::calib::validate::{MAX_RODS_PER_CAMERA, MAX_ROD_ID, MAX_TRAVEL_MM};
use rodtrack_core::calib::{
    calibrate_rod, calibrate_rods, CalibrationInputs, CameraCalibration, ImageSize, OpencvModel,
    ReferenceFrames, ReferencePose, RodCalibration, RodInputs,
};
use rodtrack_core::{CameraIntrinsics, FrameView, Marker, MarkerSpec, PixelFormat};
use rodtrack_io::source::{
    decode_image_file, frame_ids_from_names, list_image_files, ImageSequence, ImageSequenceOptions,
    InputKind, InputSpec, OpenOptions,
};
use rodtrack_io::{FrameBuffer, FrameSource};
use rodtrack_sdk::{
    calibrate_camera_file, calibration_file, print_warning, read_inputs, read_opencv_model,
    source_factory, write_calibration,
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

/// The camera's calibration from its inputs and its rods' calibrations.
fn camera_calibration(
    inputs: &CalibrationInputs,
    index: u32,
    format: PixelFormat,
    default_fps: f64,
    rods: Vec<RodCalibration>,
) -> CameraCalibration {
    CameraCalibration {
        name: inputs.camera_name.clone(),
        index,
        image_width: inputs.image_size.width,
        image_height: inputs.image_size.height,
        pixel_format: format.name().to_string(),
        fps: inputs.fps.unwrap_or(default_fps),
        opencv_model: inputs.opencv_model_optional.clone(),
        rods,
    }
}

fn intrinsics_of(model: Option<&OpencvModel>, what: &str) -> Result<Option<CameraIntrinsics>> {
    model
        .map(|m| {
            CameraIntrinsics::from_opencv(m.camera_matrix, &m.dist_coeffs)
                .with_context(|| format!("{what}: field `opencv_model_optional`"))
        })
        .transpose()
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
        for w in &s.warnings {
            println!("       warning: {w}");
        }
    }
}

// ---- automatic calibration (`--auto`) ----

/// Frames analysed by default per camera.
const DEFAULT_ANALYSED_FRAMES: u64 = 150;
/// Smallest barcode correlation accepted as a marker.
const MIN_NCC: f64 = 0.7;
/// Below this correlation a reference marker is doubtful...
const DOUBTFUL_NCC: f64 = 0.8;
/// ... and so it is when its barcode edges lie this far (RMS, mm) from their fit (0.01-0.02 mm
/// on a sharp frame)...
const DOUBTFUL_EDGE_MM: f64 = 0.1;
/// ... or its Gray code and phase disagree by this many steps (up to 0.5 when they agree).
const DOUBTFUL_CODE_PHASE: f64 = 0.75;
/// Detections closer than this along the rod (px) are one path point (a rod at rest).
const MERGE_PX: f64 = 1.5;
/// Margin added to a travel measured from the sweep, mm.
const TRAVEL_MARGIN_MM: f64 = 2.0;
/// A rod is looked for this far (px) beyond its width around its last line coordinate...
const FOLLOW_MARGIN_PX: f64 = 8.0;
/// ... at barcode cells this factor smaller or larger than its last ones...
const FOLLOW_SCALE: f64 = 1.15;
/// ... first within this many px (beyond the barcode's length) of its last place along the rod.
const FOLLOW_REACH_PX: f64 = 120.0;

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

/// What every camera shares.
struct AutoConfig {
    marker_spec: MarkerSpec,
    marker: Marker,
    reference_frame: usize,
    travel_mm: Option<[f64; 2]>,
    max_frames: Option<u64>,
    fps: Option<f64>,
}

/// One camera's input, opened.
struct SweepInput {
    input: String,
    camera_name: String,
    source: Box<dyn FrameSource>,
    /// Index (in the input's reading order) of each frame the source delivers; `None`: the
    /// source delivers every frame.
    indices: Option<Vec<usize>>,
    every: usize,
    total: Option<u64>,
    fps: Option<f64>,
}

/// Opens one camera's input; of an image folder only the frames analysed are kept.
fn open_sweep(
    input: &str,
    index: usize,
    format: Option<PixelFormat>,
    every: Option<u64>,
    cfg: &AutoConfig,
) -> Result<SweepInput> {
    let factory = source_factory();
    let spec = InputSpec::parse(input).with_context(|| format!("camera {index}: --input"))?;
    let images = spec.kind() == InputKind::Images;
    let mut format = format;
    if format.is_none() && images && spec.param("format").is_none() {
        // Grey 8-bit images are Bayer RGGB raw frames (the reference camera) unless told.
        let probe = factory
            .open(input, &OpenOptions::default())
            .with_context(|| format!("camera {index}: input {input}"))?;
        if probe.info().format == PixelFormat::Mono8 {
            eprintln!(
                "camera {index}: reading the grey images of {input} as bayer_rggb8 (give \
                 --pixel-format mono8 for a mono camera)"
            );
            format = Some(PixelFormat::BayerRggb8);
        }
    }
    let opts = OpenOptions {
        format,
        fps: cfg.fps,
        size: None,
    };
    let mut source = factory
        .open(input, &opts)
        .with_context(|| format!("camera {index}: input {input}"))?;
    let info = source.info();
    let total = match (info.frame_count, cfg.max_frames) {
        (Some(n), Some(m)) => Some(n.min(m)),
        (n, m) => n.or(m),
    };
    if total.is_none() {
        bail!(
            "camera {index}: input {input} does not say how many frames it has: give \
             --max-frames"
        );
    }
    let every = every
        .or_else(|| total.map(|n| (n / DEFAULT_ANALYSED_FRAMES).max(1)))
        .unwrap_or(1) as usize;
    let dir = Path::new(&spec.target);
    let camera_name = match dir.file_name() {
        Some(n) if images && dir.is_dir() => n.to_string_lossy().into_owned(),
        _ => format!("cam{index}"),
    };
    let mut indices = None;
    if images && every > 1 {
        // Decode only the frames analysed: the sequence's files in reading order, subsampled.
        let files = list_image_files(dir).with_context(|| format!("camera {index}: {input}"))?;
        let (ids, from_names) = frame_ids_from_names(&files);
        let mut files: Vec<(u64, PathBuf)> = ids.into_iter().zip(files).collect();
        if from_names {
            files.sort_by_key(|(id, _)| *id);
        }
        let keep: Vec<usize> = (0..files.len())
            .filter(|i| i % every == 0 || *i == cfg.reference_frame)
            .collect();
        let options = ImageSequenceOptions {
            format: Some(info.format),
            fps: info.fps,
            size: Some((info.width, info.height)),
            ignore_sidecar: true,
        };
        let picked = keep.iter().map(|&i| files[i].1.clone()).collect();
        source = Box::new(
            ImageSequence::from_files(info.name.clone(), picked, &options, None)
                .with_context(|| format!("camera {index}: input {input}"))?,
        );
        indices = Some(keep);
    }
    Ok(SweepInput {
        input: input.to_string(),
        camera_name,
        source,
        indices,
        every,
        total,
        fps: info.fps,
    })
}

fn line_of(f: &FoundMarker, along_rows: bool) -> f64 {
    if along_rows {
        f.x_px
    } else {
        f.y_px
    }
}

fn along_of(f: &FoundMarker, along_rows: bool) -> f64 {
    if along_rows {
        f.y_px
    } else {
        f.x_px
    }
}

/// One rod followed through the sweep.
struct RodSweep {
    id: u32,
    reference: FoundMarker,
    /// The last detection going forward and backward in time.
    forward: Last,
    backward: Last,
    found: Vec<FoundMarker>,
}

/// The rods of one camera, found in the reference frame.
struct Sweep {
    along_rows: bool,
    rods: Vec<RodSweep>,
    analysed: usize,
}

impl Sweep {
    /// Finds the markers of the reference frame and names them.
    fn from_reference(
        view: &FrameView,
        marker: &Marker,
        ids: Option<&[u32]>,
        camera: &str,
    ) -> Result<Sweep> {
        // Rods along image rows (the usual mounting), else along columns.
        let mut along_rows = true;
        let mut found = find_markers(view, marker, true, MIN_NCC);
        if found.is_empty() {
            along_rows = false;
            found = find_markers(view, marker, false, MIN_NCC);
        }
        if found.is_empty() {
            bail!(
                "{camera}: no marker found in the reference frame: are the markers in view, \
                 lit, and of the --marker description?"
            );
        }
        found.sort_by(|a, b| line_of(a, along_rows).total_cmp(&line_of(b, along_rows)));
        let ids: Vec<u32> = match ids {
            Some(ids) => {
                if ids.len() != found.len() {
                    let at: Vec<String> = found
                        .iter()
                        .map(|f| format!("({:.0}, {:.0})", f.x_px, f.y_px))
                        .collect();
                    bail!(
                        "{camera}: --rods names {} rod(s) but the reference frame shows {} \
                         marker(s), at {} px",
                        ids.len(),
                        found.len(),
                        at.join(", ")
                    );
                }
                ids.to_vec()
            }
            None => (0..found.len() as u32).collect(),
        };
        let rods = found
            .iter()
            .zip(ids)
            .map(|(f, id)| {
                let start = Last {
                    line: line_of(f, along_rows),
                    along: along_of(f, along_rows),
                    cell: f.cell_px,
                };
                RodSweep {
                    id,
                    reference: *f,
                    forward: start,
                    backward: start,
                    found: vec![*f],
                }
            })
            .collect();
        Ok(Sweep {
            along_rows,
            rods,
            analysed: 1,
        })
    }

    /// Looks for every rod near where it was last seen (forward or backward in time).
    fn follow(&mut self, view: &FrameView, marker: &Marker, backward: bool) {
        self.analysed += 1;
        let along_rows = self.along_rows;
        for rod in &mut self.rods {
            let last = if backward { rod.backward } else { rod.forward };
            // Near its last detection first (a sweep moves little between analysed frames),
            // then along the whole image.
            let f = follow_rod(
                view,
                marker,
                along_rows,
                rod.reference.direction,
                last,
                true,
            )
            .or_else(|| {
                follow_rod(
                    view,
                    marker,
                    along_rows,
                    rod.reference.direction,
                    last,
                    false,
                )
            });
            if let Some(f) = f {
                let state = Last {
                    line: line_of(&f, along_rows),
                    along: along_of(&f, along_rows),
                    cell: f.cell_px,
                };
                if backward {
                    rod.backward = state;
                } else {
                    rod.forward = state;
                }
                rod.found.push(f);
            }
        }
    }
}

/// Where a rod was last seen.
#[derive(Debug, Clone, Copy)]
struct Last {
    /// Line coordinate (image x for rods along rows), px.
    line: f64,
    /// Along the rod (image y for rods along rows), px.
    along: f64,
    /// Barcode cell, px.
    cell: f64,
}

/// Looks for one rod's marker on the few scan lines around its last line coordinate, at scales
/// near its last one: within `FOLLOW_REACH_PX` of its last place along the rod (`near`), or
/// along the whole image. Scans a crop of the frame (the luminance is the same inside it).
fn follow_rod(
    view: &FrameView,
    marker: &Marker,
    along_rows: bool,
    direction: i32,
    last: Last,
    near: bool,
) -> Option<FoundMarker> {
    // The rod's half width plus a margin for its line bending between analysed frames.
    let r_px = marker.radius_mm() * last.cell / marker.cell_mm();
    let half = r_px + FOLLOW_MARGIN_PX;
    // The crop: the scan lines and the silhouette beside them (2 radii out) across the rod;
    // the barcode's length and the reach along it. Even offsets keep a Bayer mosaic's phase.
    let (n_lines, len) = if along_rows {
        (view.width(), view.height())
    } else {
        (view.height(), view.width())
    };
    let even = |v: f64, max: usize| ((v.max(0.0) as usize) & !1).min(max);
    let l0 = even(last.line - half - 2.0 * r_px, n_lines);
    let l1 = ((last.line + half + 2.0 * r_px).ceil() as usize + 1).min(n_lines);
    let (a0, a1) = if near {
        let reach = 16.0 * last.cell + FOLLOW_REACH_PX;
        (
            even(last.along - reach, len),
            ((last.along + reach).ceil() as usize + 1).min(len),
        )
    } else {
        (0, len)
    };
    if l1 < l0 + 4 || a1 < a0 + 4 {
        return None;
    }
    let (x0, y0, w, h) = if along_rows {
        (l0, a0, l1 - l0, a1 - a0)
    } else {
        (a0, l0, a1 - a0, l1 - l0)
    };
    let bpp = view.format().bytes_per_pixel();
    let data = view.data().get(y0 * view.stride() + x0 * bpp..)?;
    let crop = FrameView::new(data, w, h, view.stride(), view.format()).ok()?;
    let lines_lo = (last.line - half).max(0.0) as usize;
    let lines_hi = (last.line + half).ceil() as usize + 1;
    let hits = find_markers_in(
        &crop,
        marker,
        along_rows,
        MIN_NCC,
        lines_lo.saturating_sub(l0)..lines_hi.saturating_sub(l0),
        (last.cell / FOLLOW_SCALE, last.cell * FOLLOW_SCALE),
    );
    hits.into_iter()
        .filter(|f| f.direction == direction)
        .map(|mut f| {
            f.x_px += x0 as f64;
            f.y_px += y0 as f64;
            f
        })
        .map(|f| ((line_of(&f, along_rows) - last.line).abs(), f))
        .filter(|(d, _)| *d <= half)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, f)| f)
}

/// What the sweep gave for one rod.
struct RodResult {
    inputs: RodInputs,
    span_px: f64,
    /// Travel measured from the detections, mm.
    measured_mm: [f64; 2],
    points: usize,
    /// Too few detections were centred on the rod's silhouette: all were used.
    unrefined_used: bool,
}

/// Path points (detections merged where the rod rested) and the travel measured, of one rod.
fn rod_result(
    rod: &RodSweep,
    along_rows: bool,
    spec: &MarkerSpec,
    marker: &Marker,
    travel: Option<[f64; 2]>,
) -> RodResult {
    let line = line_of(&rod.reference, along_rows);
    // Path points: the detections centred on the rod's silhouette (the others are +/- 1 px
    // across it), unless too few are.
    let refined: Vec<FoundMarker> = rod.found.iter().filter(|f| f.refined).copied().collect();
    let unrefined_used = refined.len() < 3;
    let use_found = if unrefined_used { &rod.found } else { &refined };
    let sorted = path_points_from_sweep(use_found, line, along_rows, f64::INFINITY);
    let key = |p: &[f64; 2]| if along_rows { p[1] } else { p[0] };
    let mut points: Vec<[f64; 2]> = Vec::new();
    let mut group: Vec<[f64; 2]> = Vec::new();
    // (Rounded to 0.001 px for the saved inputs' sake.)
    let flush = |group: &mut Vec<[f64; 2]>, points: &mut Vec<[f64; 2]>| {
        if !group.is_empty() {
            let n = group.len() as f64;
            let mean = |k: usize| (group.iter().map(|p| p[k]).sum::<f64>() / n * 1e3).round() / 1e3;
            points.push([mean(0), mean(1)]);
            group.clear();
        }
    };
    for p in sorted {
        if group.first().is_some_and(|g| key(&p) - key(g) > MERGE_PX) {
            flush(&mut group, &mut points);
        }
        group.push(p);
    }
    flush(&mut group, &mut points);
    let span_px = match (points.first(), points.last()) {
        (Some(a), Some(b)) => key(b) - key(a),
        _ => 0.0,
    };
    // Position of each detection: its distance from the reference along the rod, over the
    // mean of the two scales (each barcode's cells give the local mm scale).
    let r = &rod.reference;
    let ppm = |f: &FoundMarker| f.cell_px / marker.cell_mm();
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for f in &rod.found {
        let d = along_of(f, along_rows) - along_of(r, along_rows);
        let mm = r.direction as f64 * d / (0.5 * (ppm(f) + ppm(r)));
        lo = lo.min(mm);
        hi = hi.max(mm);
    }
    let measured_mm = [lo, hi];
    let travel_mm = travel.unwrap_or([
        (lo - TRAVEL_MARGIN_MM).floor(),
        (hi + TRAVEL_MARGIN_MM).ceil(),
    ]);
    RodResult {
        inputs: RodInputs {
            rod: rod.id,
            path_points_px: points.clone(),
            travel_mm,
            reference: ReferencePose {
                frame: 0,
                position_mm: 0.0,
                angle_rad: 0.0,
            },
            known_poses: Vec::new(),
            travel_frames: None,
            marker: spec.clone(),
        },
        span_px,
        measured_mm,
        points: points.len(),
        unrefined_used,
    }
}

/// `value` as it reads back from the calibration-inputs JSON: the calibration made here must be
/// the one `calibrate --inputs` makes from the saved file, to the last bit (a decimal written
/// for a double need not read back as that double with every JSON parser).
fn as_saved<T: serde::Serialize + serde::de::DeserializeOwned>(value: &T) -> Result<T> {
    let text = serde_json::to_string(value).context("cannot serialise the inputs")?;
    serde_json::from_str(&text).context("the inputs do not read back")
}

/// One camera's automatic calibration.
struct AutoCamera {
    inputs: CalibrationInputs,
    reference: FrameBuffer,
    calibration: CameraCalibration,
    /// Printed before the residual table.
    summary: Vec<String>,
    warnings: Vec<String>,
}

/// Reads one camera's sweep and calibrates its rods.
fn auto_camera(
    index: usize,
    mut src: SweepInput,
    cfg: &AutoConfig,
    model: Option<OpencvModel>,
    ids: Option<Vec<u32>>,
) -> Result<AutoCamera> {
    let label = format!("camera {index} ({})", src.input);
    let marker = &cfg.marker;
    let mut buf = FrameBuffer::new();
    let mut delivered = 0usize;
    let mut pending: Vec<FrameBuffer> = Vec::new();
    let mut reference: Option<FrameBuffer> = None;
    let mut sweep: Option<Sweep> = None;
    let mut warnings = Vec::new();
    let mut bad = 0usize;
    let mut reference_error = None;
    let mut frames_read = 0u64;
    let mut last_report = std::time::Instant::now();
    loop {
        if last_report.elapsed().as_secs_f64() > 5.0 {
            last_report = std::time::Instant::now();
            eprintln!(
                "{label}: {frames_read}{} frames read",
                src.total.map(|t| format!("/{t}")).unwrap_or_default()
            );
        }
        if cfg.max_frames.is_some_and(|m| frames_read >= m) {
            break;
        }
        let slot = delivered;
        let idx = match &src.indices {
            Some(v) => match v.get(slot) {
                Some(i) => *i,
                None => break,
            },
            None => slot,
        };
        let got = src.source.next_frame(&mut buf);
        if matches!(got, Ok(None)) {
            break;
        }
        delivered += 1;
        frames_read = idx as u64 + 1;
        match got {
            Ok(None) => break,
            Ok(Some(())) => {}
            Err(e) => {
                if idx == cfg.reference_frame {
                    reference_error = Some(e.to_string());
                }
                if e.is_fatal() {
                    warnings.push(format!("the input failed after frame {idx}: {e}"));
                    break;
                }
                bad += 1;
                if bad <= 5 {
                    warnings.push(format!("frame {idx} left out: {e}"));
                }
                continue;
            }
        }
        if idx % src.every != 0 && idx != cfg.reference_frame {
            continue;
        }
        if idx == cfg.reference_frame {
            let view = buf
                .view()
                .with_context(|| format!("{label}: reference frame"))?;
            let mut s = Sweep::from_reference(&view, marker, ids.as_deref(), &label)?;
            // The frames before the reference, nearest first.
            while let Some(f) = pending.pop() {
                s.follow(&f.view()?, marker, true);
            }
            sweep = Some(s);
            reference = Some(buf.clone());
        } else if let Some(s) = &mut sweep {
            let view = buf
                .view()
                .with_context(|| format!("{label}: frame {idx}"))?;
            s.follow(&view, marker, false);
        } else {
            pending.push(buf.clone());
        }
    }
    if bad > 5 {
        warnings.push(format!("{bad} frames left out in all"));
    }
    let (Some(reference), Some(sweep)) = (reference, sweep) else {
        bail!(
            "{label}: the reference frame {} was not read{}",
            cfg.reference_frame,
            match reference_error {
                Some(e) => format!(": {e}"),
                None => format!(" (the input ended after {delivered} frame(s))"),
            }
        );
    };
    let view = reference.view()?;
    let format = view.format();
    let model = model.as_ref().map(as_saved).transpose()?;
    let intrinsics = intrinsics_of(model.as_ref(), &format!("{label}: --opencv-model"))?;
    let mut summary = vec![format!(
        "{label}: {} frames analysed (every {}{}), rods along image {}",
        sweep.analysed,
        src.every,
        src.total.map(|t| format!(" of {t}")).unwrap_or_default(),
        if sweep.along_rows { "rows" } else { "columns" }
    )];
    summary.push(
        "  rod  reference x, y px  ncc    points  span px  measured travel mm  travel mm".into(),
    );
    let mut rods_in = Vec::new();
    let mut rods_cal = Vec::new();
    for rod in &sweep.rods {
        let r = rod_result(
            rod,
            sweep.along_rows,
            &cfg.marker_spec,
            marker,
            cfg.travel_mm,
        );
        let f = &rod.reference;
        summary.push(format!(
            "  {:>3}  {:>7.1}, {:<7.1}  {:.3}  {:>6}  {:>7.0}  {:>8.1} .. {:<7.1}  {:.0} .. {:.0}",
            r.inputs.rod,
            f.x_px,
            f.y_px,
            f.ncc,
            r.points,
            r.span_px,
            r.measured_mm[0],
            r.measured_mm[1],
            r.inputs.travel_mm[0],
            r.inputs.travel_mm[1]
        ));
        let id = r.inputs.rod;
        if f.ncc < DOUBTFUL_NCC {
            warnings.push(format!(
                "rod {id}: its marker reads weakly in the reference frame (correlation {:.2}): \
                 check that it is clean, lit and at rest",
                f.ncc
            ));
        }
        if r.points < 3 {
            warnings.push(format!(
                "rod {id}: only {} path point(s) from the sweep, 3 needed: did it sweep its \
                 travel? Not calibrated",
                r.points
            ));
            continue;
        }
        if r.unrefined_used {
            warnings.push(format!(
                "rod {id}: the rod's silhouette did not stand out in the sweep: path points \
                 only +/- 1 px across the rod"
            ));
        }
        // (How well the points cover the travel, `calibrate_rod` checks and reports.)
        if cfg.travel_mm.is_none() && r.measured_mm[1] - r.measured_mm[0] < 20.0 {
            warnings.push(format!(
                "rod {id}: it moved only {:.0} mm in the sweep: sweep the whole travel",
                r.measured_mm[1] - r.measured_mm[0]
            ));
        }
        let rod_inputs = as_saved(&r.inputs)?;
        match calibrate_rod(&rod_inputs, &view, intrinsics.as_ref()) {
            Ok(cal) => {
                let s = &cal.residuals;
                let mut doubts = Vec::new();
                if s.reference_ncc < DOUBTFUL_NCC {
                    doubts.push(format!("barcode correlation {:.2}", s.reference_ncc));
                }
                if s.edge_rms_mm > DOUBTFUL_EDGE_MM {
                    doubts.push(format!(
                        "barcode edges {:.2} mm (RMS) off their fit",
                        s.edge_rms_mm
                    ));
                }
                if s.reference_code_phase_steps > DOUBTFUL_CODE_PHASE {
                    doubts.push(format!(
                        "Gray code and phase {:.2} steps apart",
                        s.reference_code_phase_steps
                    ));
                }
                if !doubts.is_empty() {
                    warnings.push(format!(
                        "rod {id}: doubtful reference ({}): was the rod at rest at its reference \
                         pose, its marker clean and well lit?",
                        doubts.join(", ")
                    ));
                }
                if s.path_rms_px > 0.5 {
                    warnings.push(format!(
                        "rod {id}: the path points lie {:.2} px (RMS) off the fitted path",
                        s.path_rms_px
                    ));
                }
                rods_in.push(rod_inputs);
                rods_cal.push(cal);
            }
            Err(e) => warnings.push(format!("rod {id}: not calibrated: {e}")),
        }
    }
    if rods_cal.is_empty() {
        bail!(
            "{label}: no rod could be calibrated{}",
            if warnings.is_empty() {
                String::new()
            } else {
                format!(":\n  {}", warnings.join("\n  "))
            }
        );
    }
    let inputs = CalibrationInputs {
        camera_name: src.camera_name.clone(),
        image_size: ImageSize {
            width: view.width(),
            height: view.height(),
        },
        pixel_format: format.name().to_string(),
        opencv_model_optional: model,
        reference_frames: ReferenceFrames {
            dir: String::new(),
            reference_frame: 0,
        },
        fps: Some(cfg.fps.or(src.fps).unwrap_or(200.0)),
        rods: rods_in,
    };
    // All rods again together, as `calibrate --inputs` does with the inputs saved here (the
    // rods' common direction carries each one's scale along the travel).
    let frames = [(0usize, view)];
    let rods_cal: Vec<RodCalibration> = calibrate_rods(&inputs.rods, &frames, intrinsics.as_ref())
        .into_iter()
        .zip(rods_cal)
        .map(|(together, alone)| together.unwrap_or(alone))
        .collect();
    let calibration = camera_calibration(&inputs, index as u32, format, 200.0, rods_cal);
    Ok(AutoCamera {
        inputs,
        reference,
        calibration,
        summary,
        warnings,
    })
}

/// Writes a frame as PNG (8-bit grey, 16-bit grey or RGB), rows packed.
fn write_frame_png(path: &Path, buf: &FrameBuffer) -> Result<()> {
    let m = &buf.meta;
    let bpp = m.format.bytes_per_pixel();
    let mut packed = Vec::with_capacity(m.width * m.height * bpp);
    for y in 0..m.height {
        let row = buf
            .row(y)
            .ok_or_else(|| anyhow!("the reference frame is shorter than its size"))?;
        packed.extend_from_slice(&row[..m.width * bpp]);
    }
    let (w, h) = (m.width as u32, m.height as u32);
    let result = match bpp {
        1 => image::save_buffer_with_format(
            path,
            &packed,
            w,
            h,
            image::ExtendedColorType::L8,
            image::ImageFormat::Png,
        ),
        3 => image::save_buffer_with_format(
            path,
            &packed,
            w,
            h,
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        ),
        _ => {
            let words: Vec<u16> = packed
                .chunks_exact(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]))
                .collect();
            image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(w, h, words)
                .ok_or_else(|| anyhow!("the reference frame is shorter than its size"))?
                .save_with_format(path, image::ImageFormat::Png)
        }
    };
    result.with_context(|| format!("cannot write {}", path.display()))
}

/// Writes a camera's derived calibration inputs and its reference frame beside them.
fn save_auto_inputs(path: &Path, cam: &mut AutoCamera) -> Result<()> {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "inputs".into());
    let ref_dir_name = format!("{stem}_ref");
    let ref_dir = path.with_file_name(&ref_dir_name);
    std::fs::create_dir_all(&ref_dir)
        .with_context(|| format!("cannot create {}", ref_dir.display()))?;
    // Only this frame: frame 0 of the folder is the reference.
    for old in list_image_files(&ref_dir).unwrap_or_default() {
        std::fs::remove_file(&old).with_context(|| format!("cannot remove {}", old.display()))?;
    }
    let frame_path = ref_dir.join("000000.png");
    write_frame_png(&frame_path, &cam.reference)?;
    // Check that the frame reads back as it was (the rerun must see the same pixels).
    let mut back = FrameBuffer::new();
    let format = cam.reference.meta.format;
    decode_image_file(&frame_path, Some(format), &mut back)
        .with_context(|| format!("reading back {}", frame_path.display()))?;
    if back.view()?.width() != cam.reference.meta.width {
        bail!(
            "{}: the reference frame did not read back",
            frame_path.display()
        );
    }
    cam.inputs.reference_frames.dir = ref_dir_name;
    let text = serde_json::to_string_pretty(&cam.inputs).context("cannot serialise the inputs")?;
    std::fs::write(path, text + "\n").with_context(|| format!("cannot write {}", path.display()))
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
    };
    let sources = args
        .input
        .iter()
        .enumerate()
        .map(|(i, input)| open_sweep(input, i, format, args.every, &cfg))
        .collect::<Result<Vec<_>>>()?;
    let started = std::time::Instant::now();
    let results: Vec<Result<AutoCamera>> = std::thread::scope(|s| {
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
                h.join()
                    .unwrap_or_else(|_| Err(anyhow!("a camera's thread panicked")))
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
