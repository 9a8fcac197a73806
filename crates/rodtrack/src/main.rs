//! `rodtrack`: visual encoders for rods that slide and turn.

mod bench_frames;
mod bench_latency;
#[cfg(feature = "zenoh")]
mod bench_zenoh;
mod calibrate;
mod choices;
mod console;
mod console_hooks;
mod console_remote;
mod demo;
mod evaluate;
mod event_args;
mod fuse;
mod interrupt;
mod marker;
mod network;
mod recording;
mod replay;
mod score;
mod simulate;
mod track;

use anyhow::Result;
use clap::{Parser, Subcommand};

/// rodtrack: measure the translation and rotation of rods from camera images.
#[derive(Debug, Parser)]
#[command(name = "rodtrack", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the whole job on the built-in simulator: simulate, calibrate, track, score.
    Demo(demo::Args),
    /// Render a simulated recording with ground truth and calibration inputs.
    Simulate(simulate::Args),
    /// Calibrate from calibration-inputs files (one JSON per camera) into a calibration file.
    Calibrate(calibrate::Args),
    /// Track rods in recordings or live sources and write measurements.
    Track(track::Args),
    /// Write the printable marker (SVG or PDF at exact physical size).
    Marker(marker::Args),
    /// List the GenICam cameras (USB3 Vision, GigE Vision) that are connected.
    Cameras,
    /// Serve the web console: live view, plots and calibration in the browser.
    Console(console::Args),
    /// Run every simulator scenario in paper and enhanced mode; write a report with plots.
    Evaluate(evaluate::Args),
    /// Time the per-frame processing on recorded frames (median us as JSON on stdout).
    BenchFrames(bench_frames::Args),
    /// Score measurements against ground truth.
    Score(score::Args),
    /// Latency of the live path on the real-time simulator (frame available to row written).
    BenchLatency(bench_latency::Args),
    /// Latency of the camera network across processes on loopback (camera frame to fused row
    /// received; feature `zenoh`).
    #[cfg(feature = "zenoh")]
    BenchZenoh(bench_zenoh::Args),
    /// Fusion node of a camera network: fuse the camera nodes' rows (docs/network.md).
    Fuse(fuse::Args),
    /// Play an MCAP recording's rows back on the camera network in real time.
    Replay(replay::Args),
}

#[cfg(feature = "genicam")]
fn cameras() -> Result<()> {
    let list = rodtrack_genicam::list_cameras()?;
    if list.is_empty() {
        println!("no GenICam camera found");
    }
    for c in list {
        println!(
            "{}  serial {}  {} {}  {}  {}",
            c.id, c.serial, c.vendor, c.model, c.protocol, c.address
        );
    }
    Ok(())
}

#[cfg(not(feature = "genicam"))]
fn cameras() -> Result<()> {
    anyhow::bail!(
        "this build has no GenICam support: build with `--features genicam` (needs libaravis)"
    )
}

fn main() {
    let cli = Cli::parse();
    let result: Result<()> = match cli.command {
        Command::Demo(a) => demo::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Calibrate(a) => calibrate::run(a),
        Command::Track(a) => track::run(a),
        Command::Score(a) => score::run(a),
        Command::Marker(a) => marker::run(a),
        Command::Cameras => cameras(),
        Command::Console(a) => console::run(a),
        Command::Evaluate(a) => evaluate::run(a),
        Command::BenchFrames(a) => bench_frames::run(a),
        Command::BenchLatency(a) => bench_latency::run(a),
        #[cfg(feature = "zenoh")]
        Command::BenchZenoh(a) => bench_zenoh::run(a),
        Command::Fuse(a) => fuse::run(a),
        Command::Replay(a) => replay::run(a),
    };
    if let Err(e) = result {
        eprintln!("error: {}", error_chain(&e));
        std::process::exit(2);
    }
}

/// The error and its causes joined by `: `, leaving out a cause whose text the message before
/// already holds (library errors such as "cannot create: No such file" carry their OS error).
fn error_chain(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}
