//! `rodtrack bench-frames`: per-frame processing time on recorded frames, as JSON, so that
//! other tools (bench/compare_opencv.py) can compare on the very same frames.

use anyhow::{bail, Context, Result};
use rodtrack_core::{CameraPipeline, FrameView, Measurement, Mode, PixelFormat};
use rodtrack_io::source::{decode_image_file, list_image_files};
use rodtrack_io::FrameBuffer;
use rodtrack_sdk::read_calibration;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `rodtrack bench-frames`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Calibration file (from `rodtrack calibrate`).
    #[arg(long)]
    pub calib: PathBuf,
    /// Folder of one camera's frames (PNG, PGM, TIFF).
    #[arg(long)]
    pub input: PathBuf,
    /// Camera of the calibration file the frames come from (index in the file).
    #[arg(long, default_value_t = 0)]
    pub camera: usize,
    /// Times every frame is processed (after one warm-up pass).
    #[arg(long, default_value_t = 20)]
    pub repeat: usize,
    /// Use at most this many frames of the folder.
    #[arg(long, default_value_t = 50)]
    pub max_frames: usize,
}

/// Timing of one mode.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ModeTiming {
    /// Median time per frame (every rod of the camera), us.
    pub median_us: f64,
    /// 10th percentile, us.
    pub p10_us: f64,
    /// 90th percentile, us.
    pub p90_us: f64,
    /// Rows reported ok per frame, on average.
    pub ok_rows_per_frame: f64,
    /// Median of the thread's CPU time per frame, us: unlike the wall time, it leaves out the
    /// time the thread waited for a core on a loaded machine.
    pub cpu_median_us: f64,
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

fn time_mode(
    cal: &rodtrack_core::calib::CameraCalibration,
    mode: Mode,
    frames: &[FrameBuffer],
    repeat: usize,
) -> Result<ModeTiming> {
    let mut pipe = CameraPipeline::new(cal, mode)
        .with_context(|| format!("building the {mode:?} pipeline"))?;
    let views: Vec<FrameView> = frames.iter().map(|f| f.view()).collect::<Result<_, _>>()?;
    let mut rows: Vec<Measurement> = Vec::with_capacity(cal.rods.len());
    let mut times = Vec::with_capacity(views.len() * repeat);
    let mut ok = 0usize;
    let mut cpu_times = Vec::with_capacity(views.len() * repeat);
    // One warm-up pass (caches, lazily built tables), then the timed passes.
    for pass in 0..=repeat {
        for (i, v) in views.iter().enumerate() {
            rows.clear();
            let cpu = cpu_time::ThreadTime::now();
            let t = Instant::now();
            pipe.process(
                v,
                i as u64,
                rodtrack_core::Timestamp::from_secs_f64(i as f64 / cal.fps),
                &mut rows,
            )?;
            let us = t.elapsed().as_secs_f64() * 1e6;
            let cpu_us = cpu.elapsed().as_secs_f64() * 1e6;
            std::hint::black_box(&rows);
            if pass > 0 {
                times.push(us);
                cpu_times.push(cpu_us);
                ok += rows
                    .iter()
                    .filter(|m| m.status == rodtrack_core::Status::Ok)
                    .count();
            }
        }
    }
    times.sort_by(|a, b| a.total_cmp(b));
    cpu_times.sort_by(|a, b| a.total_cmp(b));
    let cpu_median_us = percentile(&cpu_times, 0.5);
    Ok(ModeTiming {
        median_us: percentile(&times, 0.5),
        p10_us: percentile(&times, 0.1),
        p90_us: percentile(&times, 0.9),
        ok_rows_per_frame: ok as f64 / times.len().max(1) as f64,
        cpu_median_us,
    })
}

/// Runs the command: prints one JSON object on stdout.
pub fn run(args: Args) -> Result<()> {
    let file = read_calibration(&args.calib)?;
    let Some(cal) = file.cameras.get(args.camera) else {
        bail!(
            "--camera {}: the calibration file {} holds {} camera(s)",
            args.camera,
            args.calib.display(),
            file.cameras.len()
        );
    };
    let format = PixelFormat::from_name(&cal.pixel_format);
    let files = list_image_files(&args.input)
        .with_context(|| format!("listing frames in {}", args.input.display()))?;
    if files.is_empty() {
        bail!("no frames in {}", args.input.display());
    }
    let mut frames = Vec::new();
    for f in files.iter().take(args.max_frames.max(1)) {
        let mut buf = FrameBuffer::new();
        decode_image_file(f, format, &mut buf).with_context(|| format!("frame {}", f.display()))?;
        let v = buf.view()?;
        if v.width() != cal.image_width || v.height() != cal.image_height {
            bail!(
                "frame {} is {}x{}, the calibration says {}x{}",
                f.display(),
                v.width(),
                v.height(),
                cal.image_width,
                cal.image_height
            );
        }
        frames.push(buf);
    }
    let repeat = args.repeat.max(1);
    let enhanced = time_mode(cal, Mode::Enhanced, &frames, repeat)?;
    let paper = if cal.rods.iter().all(|r| r.paper.is_some()) {
        Some(time_mode(cal, Mode::Paper, &frames, repeat)?)
    } else {
        None
    };
    let out = serde_json::json!({
        "frames": frames.len(),
        "repeat": repeat,
        "rods": cal.rods.len(),
        "width": cal.image_width,
        "height": cal.image_height,
        "pixel_format": cal.pixel_format,
        "enhanced": enhanced,
        "paper": paper,
    });
    println!("{}", serde_json::to_string(&out)?);
    Ok(())
}
