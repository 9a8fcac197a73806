//! `rodtrack replay FILE.mcap --publish zenoh`: plays a recording's rows back on the camera
//! network, in real time by their capture timestamps, on the keys the camera nodes and the
//! fusion node use (docs/network.md).

use crate::network::{NetArgs, NetworkArg};
use anyhow::Result;
use std::path::PathBuf;

/// Arguments of `rodtrack replay`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The MCAP recording (`track --mcap`, `fuse --mcap`).
    pub file: PathBuf,
    /// Where the rows go.
    #[arg(long, value_enum)]
    pub publish: NetworkArg,
    /// Playback speed: 1 is real time, 2 twice as fast.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Seconds to wait after joining the network before the first message, so that the
    /// subscribers are known (messages nobody is known to want are dropped).
    #[arg(long, default_value_t = 1.0)]
    pub start_delay_s: f64,
    /// Also publish the recording's fused rows for ROS 2 over rmw_zenoh in this domain
    /// (ROS_DOMAIN_ID), as `fuse --ros2-domain` does: sensor_msgs/msg/JointState on
    /// `/rodtrack/<table>/joint_states`, the table from the recording (docs/network.md).
    #[arg(long)]
    pub ros2_domain: Option<u32>,
    /// The network's endpoints (the keys are the recording's topics; --table is not used).
    #[command(flatten)]
    pub net: NetArgs,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    crate::interrupt::catch_early();
    if !(args.start_delay_s.is_finite() && args.start_delay_s >= 0.0) {
        anyhow::bail!(
            "--start-delay-s {}: expected seconds, 0 or more",
            args.start_delay_s
        );
    }
    run_replay(args)
}

#[cfg(not(feature = "zenoh"))]
fn run_replay(_args: Args) -> Result<()> {
    Err(crate::network::no_zenoh())
}

#[cfg(feature = "zenoh")]
fn run_replay(args: Args) -> Result<()> {
    use anyhow::Context;
    use rodtrack_zenoh::replay::{replay, ReplayOptions};
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    let NetworkArg::Zenoh = args.publish;
    let file = rodtrack_io::mcap::read_mcap(&args.file)?;
    if file.profile == "ros2" {
        anyhow::bail!(
            "{} is a ROS 2 bag (--mcap-ros2: joint states only); replay plays the rows of a recording made without --mcap-ros2",
            args.file.display()
        );
    }
    if let Some(cut) = &file.cut {
        eprintln!("warning: {}: {cut}", args.file.display());
    }
    let stop = Arc::new(AtomicBool::new(false));
    crate::interrupt::install(stop.clone());
    let options = ReplayOptions {
        speed: args.speed,
        start_delay: std::time::Duration::from_secs_f64(args.start_delay_s),
        ros2_domain: args.ros2_domain,
    };
    eprintln!(
        "replaying {} ({} messages); Ctrl-C to stop",
        args.file.display(),
        file.messages.len()
    );
    let report = replay(
        &file,
        &crate::network::network_options(&args.net),
        &options,
        &stop,
        &mut |msg: &str| eprintln!("skipped: {msg}"),
    )
    .with_context(|| format!("replaying {}", args.file.display()))?;
    println!("{report}");
    Ok(())
}
