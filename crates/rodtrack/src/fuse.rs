//! `rodtrack fuse`: the fusion node of a camera network. Takes the camera nodes' measured rows
//! from the network, fuses them as `track` fuses local cameras, writes every camera's rows and
//! the fused rows to `--out`, and publishes the fused rows (docs/network.md).

use crate::choices::{FormatArg, ModeArg};
use crate::network::{NetArgs, NetworkArg};
use anyhow::{bail, Result};
use clap::ValueEnum;
use std::path::PathBuf;

/// `--group-by`: how the cameras' frames are matched into frame sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GroupArg {
    /// Same frame id (hardware-triggered cameras).
    FrameId,
    /// Capture timestamps within half a frame period (cameras not triggered together).
    Timestamp,
}

/// Arguments of `rodtrack fuse`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Calibration file (TOML) of the whole table: every camera node's camera.
    #[arg(long)]
    pub calib: PathBuf,
    /// Where the camera nodes' rows come from.
    #[arg(long, value_enum)]
    pub subscribe: NetworkArg,
    /// Output file: every camera's rows and the fused rows, as `track` writes them (optional
    /// with --publish).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Output format; by default from the file extension (`.jsonl` is JSON Lines, else CSV).
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// Write the ball's rows (the camera nodes' `--zenoh-ball` rows, each camera's and the
    /// fused one per frame) to this file: CSV, or JSON Lines for `.jsonl`, as `track
    /// --ball-out`. With --publish they go on `rodtrack/<table>/fused/ball` too.
    #[arg(long)]
    pub ball_out: Option<PathBuf>,
    /// The ball's events, from the fused ball rows (and the camera nodes' rods for the
    /// shot's rod) as `track` detects them; with --publish they go on
    /// `rodtrack/<table>/fused/events` too.
    #[command(flatten)]
    pub events: crate::event_args::EventArgs,
    /// With --publish: detect the ball's events and publish them on
    /// `rodtrack/<table>/fused/events` (one JSON object per event, as a line of
    /// --events-out), with or without --events-out.
    #[arg(long, requires = "publish")]
    pub zenoh_events: bool,
    /// Publish the fused rows on `rodtrack/<table>/fused/rows`.
    #[arg(long, value_enum)]
    pub publish: Option<NetworkArg>,
    /// Algorithm the camera nodes run (it tunes the filters): `enhanced` (default) or `paper`.
    #[arg(long, value_enum, default_value_t = ModeArg::Enhanced)]
    pub mode: ModeArg,
    /// How frames are matched into sets.
    #[arg(long, value_enum, default_value_t = GroupArg::FrameId)]
    pub group_by: GroupArg,
    /// A camera silent for this many frame periods, while another one sends, is lost: the
    /// sets go on without it, marked incomplete.
    #[arg(long, default_value_t = 3.0)]
    pub loss_frames: f64,
    /// Also record every camera's rows, the fused rows, the rods as joints and, when the
    /// calibration has a ball, the ball's rows to this MCAP file, for Foxglove or Rerun
    /// (docs/network.md).
    #[arg(long)]
    pub mcap: Option<PathBuf>,
    /// With --mcap: write a ROS 2 bag instead (MCAP profile ros2): the rods as
    /// sensor_msgs/msg/JointState in CDR, per camera and fused, and the ball as
    /// geometry_msgs/msg/PointStamped and Vector3Stamped.
    #[arg(long, requires = "mcap")]
    pub mcap_ros2: bool,
    /// With --mcap: how the file's chunks are compressed.
    #[arg(long, value_enum, default_value_t = crate::recording::CompressionArg::None, requires = "mcap")]
    pub mcap_compression: crate::recording::CompressionArg,
    /// With --publish zenoh: also publish the fused rods for ROS 2 over rmw_zenoh in this
    /// domain (ROS_DOMAIN_ID), as sensor_msgs/msg/JointState on
    /// `/rodtrack/<table>/joint_states`, and, when the calibration has a ball, the fused
    /// ball as geometry_msgs/msg/PointStamped on `/rodtrack/<table>/ball` and its velocity as
    /// geometry_msgs/msg/Vector3Stamped on `/rodtrack/<table>/ball/velocity`
    /// (docs/network.md).
    #[arg(long, requires = "publish")]
    pub ros2_domain: Option<u32>,
    /// The network's endpoints and table.
    #[command(flatten)]
    pub net: NetArgs,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    crate::interrupt::catch_early();
    if args.out.is_none() && args.publish.is_none() && args.mcap.is_none() {
        bail!("give --out FILE for the fused rows, or --mcap FILE, or --publish zenoh");
    }
    if let Some(out) = &args.out {
        rodtrack_sdk::check_out_is_not_an_input(out, &[&args.calib])?;
    }
    if let Some(b) = &args.ball_out {
        let out = args.out.clone().unwrap_or_default();
        rodtrack_sdk::check_out_is_not_an_input(b, &[&args.calib, &out])?;
    }
    if let Some(m) = &args.mcap {
        let out = args.out.clone().unwrap_or_default();
        rodtrack_sdk::check_out_is_not_an_input(m, &[&args.calib, &out])?;
    }
    if let Some(e) = &args.events.events_out {
        let out = args.out.clone().unwrap_or_default();
        let mut taken: Vec<&std::path::Path> = vec![&args.calib, &out];
        taken.extend(args.ball_out.as_deref());
        taken.extend(args.mcap.as_deref());
        rodtrack_sdk::check_out_is_not_an_input(e, &taken)?;
    }
    // The events' rules, read and checked before the network is joined.
    let detected = args.events.events_out.is_some() || args.zenoh_events;
    let rules = args
        .events
        .config(detected, "--events-out FILE or --zenoh-events")?;
    run_node(args, detected.then_some(rules))
}

#[cfg(not(feature = "zenoh"))]
fn run_node(_args: Args, _rules: Option<rodtrack_core::ball::events::EventConfig>) -> Result<()> {
    Err(crate::network::no_zenoh())
}

/// Runs the fusion node; `rules`: the events' rules when the events are detected.
#[cfg(feature = "zenoh")]
fn run_node(args: Args, rules: Option<rodtrack_core::ball::events::EventConfig>) -> Result<()> {
    use anyhow::Context;
    use rodtrack_sdk::{open_sinks, RowFormat};
    use rodtrack_zenoh::fusion::{
        run_fusion, BallOutputs, FusionEvents, FusionOptions, SetGrouping,
    };
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    let cal = rodtrack_sdk::read_calibration(&args.calib)?;
    let mut sink = match &args.out {
        Some(out) => {
            let format = args
                .format
                .map_or_else(|| RowFormat::from_path(out), RowFormat::from);
            open_sinks(out, format, None)?
        }
        None => rodtrack_io::MultiSink::new(),
    };
    let recording = crate::recording::open(
        &crate::recording::McapArgs {
            mcap: args.mcap.clone(),
            mcap_frames: 0.0,
            mcap_ros2: args.mcap_ros2,
            mcap_compression: args.mcap_compression,
        },
        &args.net.table,
        cal.cameras
            .iter()
            .map(|c| (c.index, c.name.clone()))
            .collect(),
    )?;
    if let Some(r) = &recording {
        sink.push(Box::new(r.sink()));
    }
    let options = FusionOptions {
        mode: args.mode.into(),
        grouping: match args.group_by {
            GroupArg::FrameId => SetGrouping::FrameId,
            GroupArg::Timestamp => SetGrouping::Timestamp,
        },
        loss_periods: args.loss_frames,
        publish: args.publish.is_some(),
        ros2_domain: args.ros2_domain,
    };
    let stop = Arc::new(AtomicBool::new(false));
    crate::interrupt::install(stop.clone());
    let net = crate::network::network_options(&args.net);
    let table = net.table()?.to_string();
    eprintln!(
        "fusion of {} camera(s) on rodtrack/{table}/cam/*/raw{}; Ctrl-C to stop",
        cal.cameras.len(),
        if options.publish {
            format!(", publishing rodtrack/{table}/fused/rows")
        } else {
            String::new()
        }
    );
    if let Some(d) = options.ros2_domain {
        let names = rodtrack_zenoh::ros2::Ros2Names::fused(d, &table)?;
        eprintln!(
            "ROS 2 (rmw_zenoh, domain {d}): sensor_msgs/msg/JointState on {}",
            names.topic
        );
        if cal.cameras.iter().any(|c| c.ball.is_some()) {
            eprintln!(
                "ROS 2 (rmw_zenoh, domain {d}): the ball as geometry_msgs/msg/PointStamped on {}, its velocity as geometry_msgs/msg/Vector3Stamped on {}",
                names.ball_topic(),
                names.ball_velocity_topic()
            );
        }
    }
    let ball: Option<Box<dyn rodtrack_io::BallSink>> = match &args.ball_out {
        Some(path) => {
            if cal.cameras.iter().all(|c| c.ball.is_none()) {
                bail!(
                    "--ball-out {}: no camera of {} has a ball calibration (`[cameras.ball]`)",
                    path.display(),
                    args.calib.display()
                );
            }
            let created: Result<Box<dyn rodtrack_io::BallSink>, _> =
                match RowFormat::from_path(path) {
                    RowFormat::Csv => {
                        rodtrack_io::BallCsvSink::create(path).map(|s| Box::new(s) as _)
                    }
                    RowFormat::Jsonl => {
                        rodtrack_io::BallJsonlSink::create(path).map(|s| Box::new(s) as _)
                    }
                };
            Some(created.with_context(|| format!("creating the ball output {}", path.display()))?)
        }
        None => None,
    };
    // A recording holds the ball's rows when the calibration has a ball (the node fuses them).
    let recorded = recording
        .as_ref()
        .and_then(|r| crate::recording::ball_sink(r, &cal));
    let ball = match (recorded, ball) {
        (Some(recorded), ball) => {
            let mut sink = rodtrack_io::BallMultiSink::new();
            sink.push(recorded);
            if let Some(b) = ball {
                sink.push(b);
            }
            Some(Box::new(sink) as Box<dyn rodtrack_io::BallSink>)
        }
        (None, ball) => ball,
    };
    let events = if let Some(config) = rules {
        if cal.cameras.iter().all(|c| c.ball.is_none()) {
            bail!(
                "the events (--events-out, --zenoh-events) need the ball: no camera of {} has a ball calibration (`[cameras.ball]`)",
                args.calib.display()
            );
        }
        let mut sink = rodtrack_io::EventMultiSink::new();
        if let Some(path) = &args.events.events_out {
            sink.push(Box::new(
                rodtrack_io::EventJsonlSink::create(path)
                    .with_context(|| format!("creating the events output {}", path.display()))?,
            ));
        }
        // A recording holds the events when they are detected.
        if let Some(r) = &recording {
            sink.push(Box::new(r.event_sink()));
        }
        if options.publish {
            eprintln!("the ball's events on rodtrack/{table}/fused/events");
        }
        Some(FusionEvents {
            config,
            sink: Some(Box::new(sink)),
        })
    } else {
        None
    };
    let (report, sink) = run_fusion(
        &cal,
        &net,
        &options,
        sink,
        BallOutputs { rows: ball, events },
        stop,
        Box::new(|msg: &str| eprintln!("{msg}")),
    )
    .context("fusion node")?;
    drop(sink);
    crate::recording::finish(recording.as_ref())?;
    eprint!("{report}");
    eprintln!("{}", report.pipeline);
    if report.pipeline.sink_errors > 0 {
        bail!(
            "{} write(s) to the output failed (first: {})",
            report.pipeline.sink_errors,
            report.pipeline.first_sink_error.as_deref().unwrap_or("?")
        );
    }
    if let (Some(path), Some(e)) = (
        &args.events.events_out,
        report.ball.as_ref().and_then(|b| b.events),
    ) {
        println!("{}", crate::event_args::written(path, &e));
    }
    for out in args.out.iter().chain(&args.ball_out) {
        println!("wrote {}", out.display());
    }
    Ok(())
}
