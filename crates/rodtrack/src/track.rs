//! `rodtrack track`.

use crate::calibration_io::read_calibration;
use anyhow::{anyhow, bail, Context, Result};
use rodtrack_core::{CameraPipeline, FrameSetFilter, Measurement, Mode, PixelFormat};
use rodtrack_io::source::OpenOptions;
use rodtrack_io::{
    CsvSink, FrameBuffer, FrameSource, JsonlSink, MeasurementSink, MultiSink, SourceFactory,
    UdpSink,
};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// Arguments of `rodtrack track`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Calibration file (TOML) from `rodtrack calibrate`.
    #[arg(long)]
    pub calib: PathBuf,
    /// Frame source per camera, in the calibration's camera order: a folder of images,
    /// `raw:FILE?width=W&height=H&format=F`, ... (repeat for several cameras).
    #[arg(long = "input", required = true)]
    pub inputs: Vec<String>,
    /// Output file for measurements.
    #[arg(long)]
    pub out: PathBuf,
    /// Output format; by default from the file extension (`.jsonl` is JSON Lines, else CSV).
    #[arg(long, value_parser = ["csv", "jsonl"])]
    pub format: Option<String>,
    /// Also stream every frame set over UDP to this address (e.g. 127.0.0.1:9870).
    #[arg(long)]
    pub udp: Option<String>,
    /// Algorithm: `enhanced` (default) or `paper` (the published method, as a baseline).
    #[arg(long, default_value = "enhanced", value_parser = ["paper", "enhanced"])]
    pub mode: String,
    /// Write each camera's raw measurements, without the temporal filter and fusion.
    #[arg(long)]
    pub raw: bool,
    /// Stop after this many frames per camera.
    #[arg(long)]
    pub max_frames: Option<u64>,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let cal = read_calibration(&args.calib)?;
    let mode = Mode::from_name(&args.mode).ok_or_else(|| anyhow!("unknown mode {}", args.mode))?;
    if args.inputs.len() != cal.cameras.len() {
        bail!(
            "{} has {} camera(s) but {} --input given: give one input per camera, in order",
            args.calib.display(),
            cal.cameras.len(),
            args.inputs.len()
        );
    }
    let factory = source_factory();
    let mut sources: Vec<Box<dyn FrameSource>> = Vec::new();
    let mut pipes = Vec::new();
    for (cam, input) in cal.cameras.iter().zip(&args.inputs) {
        let format: PixelFormat = cam.format()?;
        let opts = OpenOptions {
            format: Some(format),
            fps: Some(cam.fps),
            size: Some((cam.image_width, cam.image_height)),
        };
        let src = factory
            .open(input, &opts)
            .with_context(|| format!("camera {} ({}): input {input}", cam.index, cam.name))?;
        sources.push(src);
        pipes.push(
            CameraPipeline::new(cam, mode)
                .with_context(|| format!("camera {} ({})", cam.index, cam.name))?,
        );
    }
    let mut sink = open_sinks(&args.out, args.format.as_deref(), args.udp.as_deref())?;
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        // A second Ctrl-C while stopping ends the process the usual way.
        let _ = ctrlc::set_handler(move || {
            if stop.swap(true, Ordering::SeqCst) {
                std::process::exit(130);
            }
        });
    }
    let total = sources[0].info().frame_count;
    let mut filter = (!args.raw).then(|| FrameSetFilter::new(mode, cal.cameras.len() > 1));
    let stats = track_sources(
        &mut sources,
        &mut pipes,
        filter.as_mut(),
        &mut sink,
        &stop,
        args.max_frames,
        total,
    )?;
    sink.flush().context("flushing the output")?;
    eprintln!(
        "\n{} frame sets, {} rows, {} bad frames, median {:.1} us per camera frame, {:.0} frame sets/s",
        stats.sets, stats.rows, stats.bad_frames, stats.median_us, stats.sets_per_s
    );
    println!("wrote {}", args.out.display());
    Ok(())
}

/// The frame sources of this build: image sequences and raw files always; video files and
/// GenICam cameras with the `video` and `genicam` features.
pub fn source_factory() -> SourceFactory {
    #[allow(unused_mut)]
    let mut factory = SourceFactory::new();
    #[cfg(feature = "video")]
    rodtrack_video::register(&mut factory);
    #[cfg(feature = "genicam")]
    rodtrack_genicam::register(&mut factory);
    factory
}

/// Opens the file sink (and the UDP sink).
pub fn open_sinks(
    out: &std::path::Path,
    format: Option<&str>,
    udp: Option<&str>,
) -> Result<MultiSink> {
    let jsonl = match format {
        Some(f) => f == "jsonl",
        None => out.extension().is_some_and(|e| e == "jsonl" || e == "json"),
    };
    let mut sink = MultiSink::new();
    if jsonl {
        sink.push(Box::new(JsonlSink::create(out)?));
    } else {
        sink.push(Box::new(CsvSink::create(out)?));
    }
    if let Some(addr) = udp {
        sink.push(Box::new(UdpSink::new(addr)?));
    }
    Ok(sink)
}

/// Counters of a tracking run.
#[derive(Debug, Default, Clone, Copy)]
pub struct TrackStats {
    /// Frame sets processed.
    pub sets: u64,
    /// Rows written.
    pub rows: u64,
    /// Frames that could not be used.
    pub bad_frames: u64,
    /// Median processing time of one camera frame, us.
    pub median_us: f64,
    /// Frame sets per second, end to end.
    pub sets_per_s: f64,
}

/// Reads every source in lockstep, groups frames by frame id, measures, writes. A bad frame is
/// marked and the run goes on; a source that ends ends the run.
pub fn track_sources(
    sources: &mut [Box<dyn FrameSource>],
    pipes: &mut [CameraPipeline],
    mut filter: Option<&mut FrameSetFilter>,
    sink: &mut dyn MeasurementSink,
    stop: &AtomicBool,
    max_frames: Option<u64>,
    total: Option<u64>,
) -> Result<TrackStats> {
    let n = sources.len();
    let mut bufs: Vec<FrameBuffer> = (0..n).map(|_| FrameBuffer::new()).collect();
    let mut rows: Vec<Measurement> = Vec::with_capacity(64);
    let mut filtered: Vec<Measurement> = Vec::with_capacity(64);
    let mut times_us: Vec<f64> = Vec::new();
    let mut stats = TrackStats::default();
    let mut next_id: Vec<u64> = vec![0; n];
    let t0 = Instant::now();
    let mut last_print = Instant::now();
    'outer: loop {
        if stop.load(Ordering::SeqCst) || max_frames.is_some_and(|m| stats.sets >= m) {
            break;
        }
        rows.clear();
        for c in 0..n {
            match sources[c].next_frame(&mut bufs[c]) {
                Ok(Some(())) => {
                    let meta = bufs[c].meta;
                    next_id[c] = meta.frame_id + 1;
                    let ts = meta.timestamp_ns.as_secs_f64();
                    let start = Instant::now();
                    let res = match bufs[c].view() {
                        Ok(view) => pipes[c].process(&view, meta.frame_id, ts, &mut rows),
                        Err(e) => Err(e),
                    };
                    if let Err(e) = res {
                        eprintln!("\ncamera {c}: frame {}: {e}", meta.frame_id);
                        stats.bad_frames += 1;
                        pipes[c].bad_frame(meta.frame_id, ts, &mut rows);
                    } else {
                        times_us.push(start.elapsed().as_secs_f64() * 1e6);
                    }
                }
                Ok(None) => break 'outer,
                Err(e) if e.is_fatal() => {
                    return Err(anyhow::Error::new(e).context(format!("camera {c}")));
                }
                Err(e) => {
                    // One bad frame: mark it and go on with the next.
                    eprintln!("\ncamera {c}: {e}");
                    stats.bad_frames += 1;
                    let id = next_id[c];
                    next_id[c] += 1;
                    pipes[c].bad_frame(id, 0.0, &mut rows);
                }
            }
        }
        let out = match filter.as_deref_mut() {
            Some(f) => {
                filtered.clear();
                f.process(&rows, &mut filtered);
                for d in f.disagreements() {
                    eprintln!(
                        "\nframe {}: rod {}: cameras {} and {} disagree by {:.2} mm / {:.3} rad",
                        d.frame,
                        d.rod,
                        d.cameras[0],
                        d.cameras[1],
                        d.position_diff_mm,
                        d.angle_diff_rad
                    );
                }
                for o in f.out_of_sync() {
                    eprintln!(
                        "\nframe {}: camera {} out of sync by {:.2} ms",
                        o.frame,
                        o.camera,
                        o.offset_s * 1e3
                    );
                }
                &filtered
            }
            None => &rows,
        };
        sink.write(out).context("writing measurements")?;
        stats.rows += out.len() as u64;
        stats.sets += 1;
        if last_print.elapsed().as_millis() > 250 {
            last_print = Instant::now();
            match total {
                Some(t) if t > 0 => eprint!(
                    "\r{:>6}/{t} frames [{:<30}]",
                    stats.sets,
                    "#".repeat((30 * stats.sets / t).min(30) as usize)
                ),
                _ => eprint!("\r{:>6} frames", stats.sets),
            }
        }
    }
    times_us.sort_by(|a, b| a.total_cmp(b));
    stats.median_us = times_us.get(times_us.len() / 2).copied().unwrap_or(0.0);
    stats.sets_per_s = stats.sets as f64 / t0.elapsed().as_secs_f64().max(1e-9);
    Ok(stats)
}
