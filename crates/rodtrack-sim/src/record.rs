//! Writing a recording to disk: frames as PNG, reference frames, calibration inputs, truth CSV.
//!
//! Layout (`out_dir`):
//! - `<cam>/NNNNNN.png`: every frame written (Bayer raw as 8-bit grey, mono8 grey, rgb8
//!   colour); the number is the frame id, the frame's index in the scenario's timeline (so
//!   `id / fps` is its capture time even when only every K-th frame is written);
//! - `<cam>_ref/000000.png`: the reference frame (rods at their reference poses, no hands),
//!   and with known poses `000001.png` ...: one rod at a time at its travel's ends and middle;
//! - `<cam>.json`: calibration inputs (SPEC section 5);
//! - `<cam>_intrinsics.yml`: the camera's true model as OpenCV's `cv::FileStorage` writes it
//!   after `calibrateCamera` (when the calibration inputs hold the model);
//! - `truth.csv`: SPEC section 6 columns plus `visible`, `camera` = camera index; rows of the
//!   frames written only;
//! - `ball_truth.csv` (scenarios with a ball): per frame written, the ball's centre and
//!   velocity in the table frame and the fraction of it each camera sees
//!   ([`crate::ball::BallTruthRow`]);
//! - `events_truth.jsonl` (scenarios with scripted events, `goals`): the ball's events as
//!   scripted, in the format of `track --events-out` ([`crate::Simulation::events_truth`]);
//! - `<cam>_ref/NNNNNN.png` also holds the ball's calibration frame (rods at their reference
//!   poses, the ball between two rods) named in the inputs' `ball.frame`;
//! - `sim.json`: the scene, cameras, scenario, seed and frames that made it.

use crate::ball::ball_truth_header;
use crate::sim::{CalibOptions, RenderInfo, Simulation, TruthRow};
use crate::SimError;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use rodtrack_core::measurement::CSV_COLUMNS;
use rodtrack_core::PixelFormat;
use std::fs;
use std::io::{BufWriter, Write};
use std::num::NonZeroUsize;
use std::ops::Range;
use std::path::Path;

/// Options for [`write_recording`].
#[derive(Debug, Clone, PartialEq)]
pub struct RecordOptions {
    /// Frames to write (default: all of the scenario).
    pub frames: Option<Range<usize>>,
    /// Write only every `every`-th frame of `frames` (its first, then every `every`-th after
    /// it), as a camera at `fps / every` would record the scenario. Frame ids and timestamps
    /// stay those of the scenario's timeline; the truth holds the written frames' rows only.
    pub every: NonZeroUsize,
    /// Seed for the calibration clicks.
    pub calib_seed: u64,
    /// Calibration options (omit the OpenCV model, click noise, ...).
    pub calib: CalibOptions,
    /// Render the cameras of a frame in parallel threads.
    pub parallel: bool,
    /// PNG compression: fast (deflate level 1, default) or default (5x slower, 3 % smaller).
    pub png_fast: bool,
}

impl Default for RecordOptions {
    fn default() -> Self {
        RecordOptions {
            frames: None,
            every: NonZeroUsize::MIN,
            calib_seed: 1,
            calib: CalibOptions::default(),
            parallel: true,
            png_fast: true,
        }
    }
}

/// What was written.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordSummary {
    /// Frames written per camera.
    pub frames: usize,
    /// Cameras.
    pub cameras: usize,
    /// Truth rows written.
    pub truth_rows: usize,
}

fn io_err(path: &Path, e: impl std::fmt::Display) -> SimError {
    SimError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    }
}

/// Writes one frame as PNG.
pub fn write_png(
    path: &Path,
    data: &[u8],
    width: usize,
    height: usize,
    format: PixelFormat,
    fast: bool,
) -> Result<(), SimError> {
    let f = fs::File::create(path).map_err(|e| io_err(path, e))?;
    let w = BufWriter::new(f);
    let (ct, bpp) = match format {
        PixelFormat::Rgb8 => (ExtendedColorType::Rgb8, 3),
        _ => (ExtendedColorType::L8, 1),
    };
    // Noisy Bayer frames hardly compress: deflate level 1 without filtering gives 70 % of the
    // raw size in about 15 ms per 1440 x 1080 frame; the default level saves 3 % more at 5x
    // the time; `Fast` stores them uncompressed.
    let enc = if fast {
        PngEncoder::new_with_quality(w, CompressionType::Level(1), FilterType::NoFilter)
    } else {
        PngEncoder::new_with_quality(w, CompressionType::Default, FilterType::Adaptive)
    };
    enc.write_image(
        &data[..width * height * bpp],
        width as u32,
        height as u32,
        ct,
    )
    .map_err(|e| io_err(path, e))
}

/// One CSV line of a truth row.
pub fn truth_csv_line(r: &TruthRow) -> String {
    let m = &r.m;
    format!(
        "{},{:.6},{},{},{:.6},{:.9},{:.9},{:.6},{:.6},{:.3},{},{}",
        m.frame,
        m.timestamp_s(),
        m.camera,
        m.rod,
        m.position_mm,
        m.angle_rad,
        m.angle_unwrapped_rad,
        m.velocity_mm_s,
        m.angular_velocity_rad_s,
        m.quality,
        m.status,
        r.visible
    )
}

/// The truth CSV header.
pub fn truth_csv_header() -> String {
    let mut h = CSV_COLUMNS.join(",");
    h.push_str(",visible");
    h
}

/// Writes a whole recording (see the module docs). `progress(done, total)` is called after
/// every frame written. Deterministic for a seed.
pub fn write_recording(
    sim: &mut Simulation,
    out_dir: &Path,
    opts: &RecordOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<RecordSummary, SimError> {
    let ncam = sim.ctx.cameras.len();
    let frames = opts.frames.clone().unwrap_or(0..sim.frame_count());
    let frames = frames.start..frames.end.min(sim.frame_count());
    fs::create_dir_all(out_dir).map_err(|e| io_err(out_dir, e))?;
    // Description of the run.
    let desc = serde_json::json!({
        "scene": sim.ctx.scene,
        "cameras": sim.ctx.cameras,
        "scenario": sim.ctx.scenario.name,
        "duration_s": sim.ctx.scenario.duration_s,
        "fps": sim.ctx.scenario.fps,
        "mode": sim.ctx.mode,
        "seed": sim.ctx.seed,
        "frames": [frames.start, frames.end],
        "every": opts.every,
    });
    let p = out_dir.join("sim.json");
    fs::write(
        &p,
        serde_json::to_string_pretty(&desc).map_err(|e| io_err(&p, e))?,
    )
    .map_err(|e| io_err(&p, e))?;
    let mut bufs: Vec<Vec<u8>> = sim
        .ctx
        .cameras
        .iter()
        .map(|c| vec![0u8; c.frame_bytes()])
        .collect();
    for (ci, buf) in bufs.iter_mut().enumerate() {
        let cam = sim.ctx.cameras[ci].clone();
        let dir = out_dir.join(&cam.name);
        fs::create_dir_all(&dir).map_err(|e| io_err(&dir, e))?;
        let rdir = out_dir.join(format!("{}_ref", cam.name));
        fs::create_dir_all(&rdir).map_err(|e| io_err(&rdir, e))?;
        // Frame 0: the reference; then, with known poses, one rod at a time at its poses.
        let known = if opts.calib.known_poses {
            sim.known_pose_frames()
        } else {
            Vec::new()
        };
        let png_fast = opts.png_fast;
        let write_ref = |frame: u64, buf: &[u8], meta: &RenderInfo| {
            write_png(
                &rdir.join(format!("{frame:06}.png")),
                buf,
                meta.width,
                meta.height,
                meta.format,
                png_fast,
            )
        };
        for pose in std::iter::once(None).chain(known.into_iter().map(Some)) {
            let (frame, meta) = match pose {
                None => (0, sim.render_reference(ci, buf)?),
                Some((frame, rod, position_mm)) => {
                    (frame, sim.render_known_pose(ci, rod, position_mm, buf)?)
                }
            };
            write_ref(frame as u64, buf, &meta)?;
        }
        let inputs = sim.calibration_inputs_with(ci, opts.calib_seed, &opts.calib)?;
        if let Some(b) = &inputs.ball {
            if let Some(p) = sim.ctx.ball_click_position(ci) {
                let meta = sim.render_ball_frame(ci, p, buf)?;
                write_ref(b.frame as u64, buf, &meta)?;
            }
        }
        let p = out_dir.join(format!("{}.json", cam.name));
        let text = serde_json::to_string_pretty(&inputs).map_err(|e| io_err(&p, e))?;
        fs::write(&p, text).map_err(|e| io_err(&p, e))?;
        if let Some(model) = &inputs.opencv_model_optional {
            let p = out_dir.join(format!("{}_intrinsics.yml", cam.name));
            fs::write(&p, model.to_file_storage_yaml(inputs.image_size))
                .map_err(|e| io_err(&p, e))?;
        }
    }
    let tp = out_dir.join("truth.csv");
    let tf = fs::File::create(&tp).map_err(|e| io_err(&tp, e))?;
    let mut truth = BufWriter::new(tf);
    writeln!(truth, "{}", truth_csv_header()).map_err(|e| io_err(&tp, e))?;
    let mut ball_truth = match sim.ctx.scenario.ball {
        Some(_) => {
            let bp = out_dir.join("ball_truth.csv");
            let f = fs::File::create(&bp).map_err(|e| io_err(&bp, e))?;
            let mut w = BufWriter::new(f);
            writeln!(w, "{}", ball_truth_header(ncam)).map_err(|e| io_err(&bp, e))?;
            Some((bp, w))
        }
        None => None,
    };
    let total = frames.len().div_ceil(opts.every.get());
    let mut rows = 0usize;
    let names: Vec<String> = sim.ctx.cameras.iter().map(|c| c.name.clone()).collect();
    for (done, fi) in frames.step_by(opts.every.get()).enumerate() {
        let ctx = &sim.ctx;
        let results: Vec<Result<(), SimError>> = if opts.parallel && ncam > 1 {
            std::thread::scope(|s| {
                let handles: Vec<_> = sim
                    .renderers
                    .iter_mut()
                    .zip(bufs.iter_mut())
                    .enumerate()
                    .map(|(ci, (r, buf))| {
                        let dir = out_dir.join(&names[ci]);
                        s.spawn(move || -> Result<(), SimError> {
                            let m = ctx.render_frame(r, fi, ci, buf)?;
                            write_png(
                                &dir.join(format!("{:06}.png", m.frame_id)),
                                buf,
                                m.width,
                                m.height,
                                m.format,
                                opts.png_fast,
                            )
                        })
                    })
                    .collect();
                handles
                    .into_iter()
                    .map(|h| h.join().expect("render thread panicked"))
                    .collect()
            })
        } else {
            sim.renderers
                .iter_mut()
                .zip(bufs.iter_mut())
                .enumerate()
                .map(|(ci, (r, buf))| {
                    let m = ctx.render_frame(r, fi, ci, buf)?;
                    write_png(
                        &out_dir
                            .join(&names[ci])
                            .join(format!("{:06}.png", m.frame_id)),
                        buf,
                        m.width,
                        m.height,
                        m.format,
                        opts.png_fast,
                    )
                })
                .collect()
        };
        for r in results {
            r?;
        }
        for ci in 0..ncam {
            for row in sim.ctx.truth(fi, ci)? {
                writeln!(truth, "{}", truth_csv_line(&row)).map_err(|e| io_err(&tp, e))?;
                rows += 1;
            }
        }
        if let (Some((bp, w)), Some(row)) = (&mut ball_truth, sim.ctx.ball_truth(fi)) {
            writeln!(w, "{}", row.csv_line()).map_err(|e| io_err(bp, e))?;
        }
        progress(done + 1, total);
    }
    truth.flush().map_err(|e| io_err(&tp, e))?;
    if let Some((bp, mut w)) = ball_truth {
        w.flush().map_err(|e| io_err(&bp, e))?;
    }
    if !sim.ctx.scenario.events.is_empty() {
        let ep = out_dir.join("events_truth.jsonl");
        let mut text = String::new();
        for e in sim.events_truth() {
            e.push_json(&mut text);
            text.push('\n');
        }
        fs::write(&ep, text).map_err(|e| io_err(&ep, e))?;
    }
    Ok(RecordSummary {
        frames: total,
        cameras: ncam,
        truth_rows: rows,
    })
}
