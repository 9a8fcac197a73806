//! `rodtrack bench-latency`: the live path's latency, frame available to measurement written.
//!
//! The real-time simulator (`sim://SCENARIO?camera=N&realtime=1`, paced at the scenario's
//! 200 fps, `live`) feeds the runtime pipeline in Live mode, with the real per-camera
//! [`CameraPipeline`]s, the [`FrameSetFilter`] (filter and fusion) and a CSV sink (to a file
//! with `--out`, else to a null writer), exactly as `rodtrack track` runs. The latency of a
//! frame is measured by the pipeline from the moment the source delivered it to the return of
//! the sink's `write` for its frame set: queue hand-off, tracking, grouping, filter, fusion
//! and CSV formatting (and the write system call with `--out`).
//!
//! The simulator renders on the host CPU (a real camera does not), so by default each camera's
//! first `--prerender` frames are rendered before the run and cycled through (frame ids keep
//! counting; the rods jump back at each wrap, which the tracker takes as fast motion); with
//! `--prerender 0` every frame is rendered in its capture thread, which on a small machine
//! competes with tracking for the CPU.

use crate::track::{install_ctrlc, run_cameras, FilterSink, TrackCamera};
use anyhow::{Context, Result};
use rodtrack_core::calib::CameraCalibration;
use rodtrack_core::{CameraPipeline, FrameSetFilter, Mode};
use rodtrack_io::source::OpenOptions;
use rodtrack_io::CsvSink;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

/// The latency target, p99.
const TARGET_P99: Duration = Duration::from_micros(200);

/// Arguments of `rodtrack bench-latency`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Frames per camera (at 200 fps, 1000 frames are 5 s).
    #[arg(long, default_value_t = 1000)]
    pub frames: usize,
    /// Scenario of the simulator.
    #[arg(long, default_value = "gameplay", value_parser = rodtrack_sim::SCENARIO_NAMES)]
    pub scenario: String,
    /// Number of cameras (1 or 2; the simulated table has 2).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=2))]
    pub cameras: u32,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the measurements to this CSV file (default: a null writer).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Render this many distinct frames per camera before starting and cycle through them
    /// (frame ids keep counting), so that the host CPU only copies frames, as with a real
    /// camera; 0: render every frame on demand in the capture threads (on a small machine the
    /// rendering then competes with tracking).
    #[arg(long, default_value_t = 200)]
    pub prerender: usize,
    /// Release frames as fast as they render instead of at the scenario's frame rate (the
    /// pipeline still runs in Live mode and drops what it cannot take).
    #[arg(long)]
    pub unpaced: bool,
}

/// Calibrates camera `c` of the simulation from its simulated clicks and reference frame.
fn calibrate_sim_camera(
    sim: &mut rodtrack_sim::Simulation,
    c: usize,
    seed: u64,
) -> Result<CameraCalibration> {
    Ok(crate::simulate::calibrate_sim_camera(sim, c, seed)?.3)
}

/// Runs the benchmark.
pub fn run(args: Args) -> Result<()> {
    let ncam = args.cameras as usize;
    eprintln!("calibrating {ncam} simulated camera(s) ...");
    let mut sim = crate::simulate::build(&args.scenario, Some(args.frames), args.seed, false)?;
    let cals = (0..ncam)
        .map(|c| calibrate_sim_camera(&mut sim, c, args.seed))
        .collect::<Result<Vec<_>>>()?;
    drop(sim);
    let factory = crate::track::source_factory();
    let mut cameras = Vec::new();
    for cal in &cals {
        let input = format!(
            "sim://{}?camera={}&frames={}&seed={}&realtime={}&prerender={}",
            args.scenario,
            cal.index,
            args.frames,
            args.seed,
            u8::from(!args.unpaced),
            args.prerender
        );
        let opts = OpenOptions {
            format: Some(cal.format()?),
            fps: Some(cal.fps),
            size: Some((cal.image_width, cal.image_height)),
        };
        let mut source = factory
            .open(&input, &opts)
            .with_context(|| format!("opening {input}"))?;
        if args.unpaced {
            source = Box::new(LiveAnyway(source));
        }
        cameras.push(TrackCamera {
            label: format!("camera {} ({})", cal.index, cal.name),
            source,
            pipe: CameraPipeline::new(cal, Mode::Enhanced)?,
            console: None,
        });
    }
    let csv = match &args.out {
        Some(p) => CsvSink::new(
            Box::new(
                std::fs::File::create(p)
                    .with_context(|| format!("cannot create {}", p.display()))?,
            ) as Box<dyn std::io::Write + Send>,
            p.clone(),
        )?,
        None => CsvSink::new(
            Box::new(std::io::sink()) as Box<dyn std::io::Write + Send>,
            "null writer",
        )?,
    };
    let mut sink = FilterSink::new(Some(FrameSetFilter::new(Mode::Enhanced, ncam > 1)), csv);
    let stop = Arc::new(AtomicBool::new(false));
    install_ctrlc(stop.clone());
    eprintln!(
        "running {} frames x {ncam} camera(s) of `{}` ({}) through the pipeline, Live mode{} ...",
        args.frames,
        args.scenario,
        if args.prerender > 0 {
            format!(
                "{} pre-rendered frames, cycled",
                args.prerender.min(args.frames)
            )
        } else {
            "rendered on demand".to_string()
        },
        if args.unpaced {
            ", unpaced"
        } else {
            ", 200 fps"
        }
    );
    let outcome = run_cameras(cameras, &mut sink, &stop, None, true)?;
    sink.print_summary();
    let r = &outcome.report;
    let l = &r.latency;
    let us = |d: Duration| d.as_secs_f64() * 1e6;
    println!("{}", outcome.summary().trim_start());
    println!();
    println!(
        "latency, frame available -> measurement written ({} frames): p50 {:.0} us, p90 {:.0} us, p99 {:.0} us, max {:.0} us (mean {:.0} us)",
        l.count,
        us(l.p50),
        us(l.p90),
        us(l.p99),
        us(l.max),
        us(l.mean)
    );
    let secs = r.elapsed.as_secs_f64().max(1e-9);
    let sets = r.sets_complete + r.sets_incomplete;
    let processed: u64 = r.cameras.iter().map(|c| c.frames_processed).sum();
    let dropped: u64 = r.cameras.iter().map(|c| c.frames_dropped).sum();
    println!(
        "throughput: {:.1} frame sets/s, {:.1} camera frames/s ({} sets, {} incomplete, {} frames dropped, {} rows)",
        sets as f64 / secs,
        processed as f64 / secs,
        sets,
        r.sets_incomplete,
        dropped,
        r.rows_written
    );
    let tracker_p50 = outcome
        .process
        .iter()
        .map(|p| p.p50)
        .max()
        .unwrap_or_default();
    let tracker_p99 = outcome
        .process
        .iter()
        .map(|p| p.p99)
        .max()
        .unwrap_or_default();
    if l.p99 <= TARGET_P99 {
        println!(
            "target p99 <= {:.0} us: met ({:.0} us)",
            us(TARGET_P99),
            us(l.p99)
        );
    } else {
        println!(
            "target p99 <= {:.0} us: NOT met, p99 is {:.0} us ({:.0} us over, x{:.1})",
            us(TARGET_P99),
            us(l.p99),
            us(l.p99 - TARGET_P99),
            l.p99.as_secs_f64() / TARGET_P99.as_secs_f64()
        );
    }
    let w = sink.write_times();
    println!(
        "of which: tracker (CameraPipeline::process, per camera frame) p50 {:.0} us, p99 {:.0} us; filter + fusion + CSV (per frame set) p50 {:.0} us, p99 {:.0} us; the rest (queue hand-offs, thread wake-ups, waiting for the other camera, grouping) about {:.0} us at p50",
        us(tracker_p50),
        us(tracker_p99),
        us(w.p50),
        us(w.p99),
        us(l.p50.saturating_sub(tracker_p50 + w.p50))
    );
    Ok(())
}

/// Reports a source as live (for `--unpaced`: a real-time-less simulator in Live mode).
struct LiveAnyway(Box<dyn rodtrack_io::FrameSource>);

impl rodtrack_io::FrameSource for LiveAnyway {
    fn info(&self) -> rodtrack_io::source::SourceInfo {
        let mut i = self.0.info();
        i.live = true;
        i
    }
    fn next_frame(
        &mut self,
        buf: &mut rodtrack_io::FrameBuffer,
    ) -> Result<Option<()>, rodtrack_io::SourceError> {
        self.0.next_frame(buf)
    }
}
