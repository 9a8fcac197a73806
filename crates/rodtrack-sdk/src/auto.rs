//! `calibrate --auto`: each camera's sweep read from its source (of an image folder only the
//! frames analysed are decoded), its rods found and followed ([`rodtrack_core::calib::auto`]),
//! their calibration inputs derived and saved beside the reference frame, and the rods
//! calibrated from them.
//!
//! ```no_run
//! use rodtrack_core::MarkerSpec;
//! use rodtrack_sdk::auto::{auto_camera, open_sweep, print_note, save_auto_inputs, AutoConfig};
//! let marker_spec = MarkerSpec::default();
//! let cfg = AutoConfig {
//!     marker: marker_spec.validate().map_err(|e| rodtrack_sdk::SdkError::Invalid(e.to_string()))?,
//!     marker_spec,
//!     reference_frame: 0,
//!     travel_mm: None,
//!     max_frames: None,
//!     fps: None,
//!     note: print_note,
//! };
//! let mut cam = auto_camera(0, open_sweep("sweep/cam0", 0, None, None, &cfg)?, &cfg, None, None)?;
//! save_auto_inputs("sweep/cam0.json".as_ref(), &mut cam)?;
//! let file = rodtrack_sdk::calibration_file(vec![cam.calibration])?;
//! rodtrack_sdk::write_calibration("table.toml".as_ref(), &file)?;
//! # Ok::<(), rodtrack_sdk::SdkError>(())
//! ```

use crate::error::Context;
use crate::{source_factory, SdkError};
use rodtrack_core::calib::auto::*;
use rodtrack_core::calib::{
    calibrate_rod, calibrate_rods, CalibrationInputs, CameraCalibration, ImageSize, OpencvModel,
    ReferenceFrames, RodCalibration,
};
use rodtrack_core::{CameraIntrinsics, Marker, MarkerSpec, PixelFormat};
use rodtrack_io::source::{
    decode_image_file, frame_ids_from_names, list_image_files, ImageSequence, ImageSequenceOptions,
    InputKind, InputSpec, OpenOptions,
};
use rodtrack_io::{FrameBuffer, FrameSource};
use std::path::{Path, PathBuf};

/// An [`SdkError::Invalid`] with a formatted message.
macro_rules! invalid {
    ($($t:tt)*) => { SdkError::Invalid(format!($($t)*)) };
}

/// Frames analysed by default per camera.
///
/// ```
/// assert_eq!(rodtrack_sdk::auto::DEFAULT_ANALYSED_FRAMES, 150);
/// ```
pub const DEFAULT_ANALYSED_FRAMES: u64 = 150;

/// What every camera shares.
///
/// ```
/// use rodtrack_core::MarkerSpec;
/// use rodtrack_sdk::auto::{print_note, AutoConfig};
/// let marker_spec = MarkerSpec::default();
/// let cfg = AutoConfig {
///     marker: marker_spec.validate()?,
///     marker_spec,
///     reference_frame: 0,
///     travel_mm: None,
///     max_frames: Some(100),
///     fps: None,
///     note: print_note,
/// };
/// assert_eq!(cfg.marker.steps(), 32);
/// # Ok::<(), rodtrack_core::CoreError>(())
/// ```
pub struct AutoConfig {
    /// The markers' description.
    pub marker_spec: MarkerSpec,
    /// The marker it describes, validated.
    pub marker: Marker,
    /// The frame in which every rod is at its reference pose (0 mm, 0 rad).
    pub reference_frame: usize,
    /// Every rod's travel, mm (default: measured from the sweep).
    pub travel_mm: Option<[f64; 2]>,
    /// Read at most this many frames per camera.
    pub max_frames: Option<u64>,
    /// Frame rate to write (default: the source's, else 200).
    pub fps: Option<f64>,
    /// Receives what the calibration notices on the way (a format assumed, progress about
    /// every 5 s); [`print_note`] prints it on standard error.
    pub note: fn(&str),
}

/// Prints a note of the automatic calibration on standard error.
///
/// ```
/// use rodtrack_sdk::auto::print_note;
/// let note: fn(&str) = print_note; // an AutoConfig's `note`
/// note("camera 0: 150 frames analysed");
/// ```
pub fn print_note(msg: &str) {
    eprintln!("{msg}");
}

/// One camera's input, opened.
///
/// ```no_run
/// use rodtrack_core::MarkerSpec;
/// use rodtrack_sdk::auto::{print_note, AutoConfig};
/// let marker_spec = MarkerSpec::default();
/// let cfg = AutoConfig {
///     marker: marker_spec.validate().map_err(|e| rodtrack_sdk::SdkError::Invalid(e.to_string()))?,
///     marker_spec,
///     reference_frame: 0,
///     travel_mm: None,
///     max_frames: Some(100),
///     fps: None,
///     note: print_note,
/// };
/// // Camera 0's sweep: a folder of images in which the rods are pushed and turned.
/// let sweep = rodtrack_sdk::auto::open_sweep("sweep/cam0", 0, None, None, &cfg)?;
/// println!("{}: {:?} frames, every {}", sweep.camera_name, sweep.total, sweep.every);
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub struct SweepInput {
    /// The input as given.
    pub input: String,
    /// The camera's name (the image folder's, else `camN`).
    pub camera_name: String,
    /// The source.
    pub source: Box<dyn FrameSource>,
    /// Index (in the input's reading order) of each frame the source delivers; `None`: the
    /// source delivers every frame.
    pub indices: Option<Vec<usize>>,
    /// Every `every`-th frame is analysed.
    pub every: usize,
    /// Frames the input has (or those read at most).
    pub total: Option<u64>,
    /// The source's frame rate.
    pub fps: Option<f64>,
}

/// Opens one camera's input; of an image folder only the frames analysed are kept.
///
/// ```no_run
/// use rodtrack_core::MarkerSpec;
/// use rodtrack_sdk::auto::{print_note, AutoConfig};
/// let marker_spec = MarkerSpec::default();
/// let cfg = AutoConfig {
///     marker: marker_spec.validate().map_err(|e| rodtrack_sdk::SdkError::Invalid(e.to_string()))?,
///     marker_spec,
///     reference_frame: 0,
///     travel_mm: None,
///     max_frames: Some(100),
///     fps: None,
///     note: print_note,
/// };
/// // Any input the sources take; with a pixel format for images that do not say theirs.
/// let fmt = rodtrack_core::PixelFormat::from_name("bayer_rggb8");
/// let sweep = rodtrack_sdk::auto::open_sweep("sweep/cam1", 1, fmt, Some(2), &cfg)?;
/// assert_eq!(sweep.every, 2);
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn open_sweep(
    input: &str,
    index: usize,
    format: Option<PixelFormat>,
    every: Option<u64>,
    cfg: &AutoConfig,
) -> Result<SweepInput, SdkError> {
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
            (cfg.note)(&format!(
                "camera {index}: reading the grey images of {input} as bayer_rggb8 (give \
                 --pixel-format mono8 for a mono camera)"
            ));
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
        return Err(invalid!(
            "camera {index}: input {input} does not say how many frames it has: give \
             --max-frames"
        ));
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

/// `value` as it reads back from the calibration-inputs JSON: the calibration made here must be
/// the one `calibrate --inputs` makes from the saved file, to the last bit (a decimal written
/// for a double need not read back as that double with every JSON parser).
fn as_saved<T: serde::Serialize + serde::de::DeserializeOwned>(value: &T) -> Result<T, SdkError> {
    let text = serde_json::to_string(value).context("cannot serialise the inputs")?;
    serde_json::from_str(&text).context("the inputs do not read back")
}

/// One camera's automatic calibration.
///
/// ```no_run
/// use rodtrack_sdk::auto::{auto_camera, open_sweep};
/// use rodtrack_core::MarkerSpec;
/// use rodtrack_sdk::auto::{print_note, AutoConfig};
/// let marker_spec = MarkerSpec::default();
/// let cfg = AutoConfig {
///     marker: marker_spec.validate().map_err(|e| rodtrack_sdk::SdkError::Invalid(e.to_string()))?,
///     marker_spec,
///     reference_frame: 0,
///     travel_mm: None,
///     max_frames: Some(100),
///     fps: None,
///     note: print_note,
/// };
/// let sweep = open_sweep("sweep/cam0", 0, None, None, &cfg)?;
/// let mut cam = auto_camera(0, sweep, &cfg, None, None)?;
/// for line in cam.summary.iter().chain(&cam.warnings) {
///     println!("{line}");
/// }
/// println!("{} rods calibrated", cam.calibration.rods.len());
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub struct AutoCamera {
    /// The calibration inputs derived (to save with [`save_auto_inputs`]).
    pub inputs: CalibrationInputs,
    /// The reference frame.
    pub reference: FrameBuffer,
    /// The camera's calibration.
    pub calibration: CameraCalibration,
    /// What was found, one line each, to print before the residual table.
    pub summary: Vec<String>,
    /// Doubts about the sweep and the references, one per line.
    pub warnings: Vec<String>,
}

/// Reads one camera's sweep and calibrates its rods.
///
/// ```no_run
/// use rodtrack_sdk::auto::{auto_camera, open_sweep};
/// use rodtrack_core::MarkerSpec;
/// use rodtrack_sdk::auto::{print_note, AutoConfig};
/// let marker_spec = MarkerSpec::default();
/// let cfg = AutoConfig {
///     marker: marker_spec.validate().map_err(|e| rodtrack_sdk::SdkError::Invalid(e.to_string()))?,
///     marker_spec,
///     reference_frame: 0,
///     travel_mm: None,
///     max_frames: Some(100),
///     fps: None,
///     note: print_note,
/// };
/// let sweep = open_sweep("sweep/cam0", 0, None, None, &cfg)?;
/// let mut cam = auto_camera(0, sweep, &cfg, None, None)?;
/// // One camera of a calibration file.
/// let file = rodtrack_sdk::calibration_file(vec![cam.calibration])?;
/// rodtrack_sdk::write_calibration("table.toml".as_ref(), &file)?;
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn auto_camera(
    index: usize,
    mut src: SweepInput,
    cfg: &AutoConfig,
    model: Option<OpencvModel>,
    ids: Option<Vec<u32>>,
) -> Result<AutoCamera, SdkError> {
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
            (cfg.note)(&format!(
                "{label}: {frames_read}{} frames read",
                src.total.map(|t| format!("/{t}")).unwrap_or_default()
            ));
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
            let mut s = Sweep::from_reference(&view, marker, ids.as_deref(), &label)
                .map_err(|e| SdkError::Invalid(e.to_string()))?;
            // The frames before the reference, nearest first.
            while let Some(f) = pending.pop() {
                s.follow(&f.view().context(&label)?, marker, true);
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
        return Err(invalid!(
            "{label}: the reference frame {} was not read{}",
            cfg.reference_frame,
            match reference_error {
                Some(e) => format!(": {e}"),
                None => format!(" (the input ended after {delivered} frame(s))"),
            }
        ));
    };
    let view = reference.view().context(&label)?;
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
        let r = swept_rod(
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
        return Err(invalid!(
            "{label}: no rod could be calibrated{}",
            if warnings.is_empty() {
                String::new()
            } else {
                format!(":\n  {}", warnings.join("\n  "))
            }
        ));
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
        table: None,
        ball: None,
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
fn write_frame_png(path: &Path, buf: &FrameBuffer) -> Result<(), SdkError> {
    let m = &buf.meta;
    let bpp = m.format.bytes_per_pixel();
    let mut packed = Vec::with_capacity(m.width * m.height * bpp);
    for y in 0..m.height {
        let row = buf
            .row(y)
            .ok_or_else(|| invalid!("the reference frame is shorter than its size"))?;
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
                .ok_or_else(|| invalid!("the reference frame is shorter than its size"))?
                .save_with_format(path, image::ImageFormat::Png)
        }
    };
    result.with_context(|| format!("cannot write {}", path.display()))
}

/// Writes a camera's derived calibration inputs and its reference frame beside them.
///
/// ```no_run
/// use rodtrack_sdk::auto::{auto_camera, open_sweep, save_auto_inputs};
/// use rodtrack_core::MarkerSpec;
/// use rodtrack_sdk::auto::{print_note, AutoConfig};
/// let marker_spec = MarkerSpec::default();
/// let cfg = AutoConfig {
///     marker: marker_spec.validate().map_err(|e| rodtrack_sdk::SdkError::Invalid(e.to_string()))?,
///     marker_spec,
///     reference_frame: 0,
///     travel_mm: None,
///     max_frames: Some(100),
///     fps: None,
///     note: print_note,
/// };
/// let sweep = open_sweep("sweep/cam0", 0, None, None, &cfg)?;
/// let mut cam = auto_camera(0, sweep, &cfg, None, None)?;
/// // cam0.json, and its reference frame in cam0_ref/: what `calibrate --inputs` reads back.
/// save_auto_inputs("cam0.json".as_ref(), &mut cam)?;
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn save_auto_inputs(path: &Path, cam: &mut AutoCamera) -> Result<(), SdkError> {
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
    if back.view().context(frame_path.display())?.width() != cam.reference.meta.width {
        return Err(invalid!(
            "{}: the reference frame did not read back",
            frame_path.display()
        ));
    }
    cam.inputs.reference_frames.dir = ref_dir_name;
    let text = serde_json::to_string_pretty(&cam.inputs).context("cannot serialise the inputs")?;
    std::fs::write(path, text + "\n").with_context(|| format!("cannot write {}", path.display()))
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
        table: None,
        ball: None,
        rods,
    }
}

fn intrinsics_of(
    model: Option<&OpencvModel>,
    what: &str,
) -> Result<Option<CameraIntrinsics>, SdkError> {
    model
        .map(|m| {
            CameraIntrinsics::from_opencv(m.camera_matrix, &m.dist_coeffs)
                .with_context(|| format!("{what}: field `opencv_model_optional`"))
        })
        .transpose()
}
