//! The camera network's options (`--publish zenoh`, `--zenoh-listen`, ...) shared by `track`
//! and `fuse`, and the glue to `rodtrack-zenoh` (feature `zenoh`; without it the options are
//! refused with a message saying how to build with it).

use anyhow::Result;
use clap::ValueEnum;
use rodtrack_io::MeasurementSink;
use rodtrack_sdk::Hooks;
use std::path::PathBuf;
use std::sync::Arc;

/// `--publish` / `--subscribe`: the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum NetworkArg {
    /// zenoh (peer to peer; key expressions `rodtrack/<table>/...`, docs/network.md).
    Zenoh,
}

/// `--zenoh-format`: the rows' encoding on the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WireArg {
    /// The binary layout (docs/network.md).
    Binary,
    /// JSON, for scripts.
    Json,
}

/// Where a node connects and what it calls its table.
#[derive(Debug, Clone, clap::Args)]
pub struct NetArgs {
    /// zenoh endpoint to listen on, e.g. `tcp/0.0.0.0:7447` (repeat for several). With an
    /// endpoint given (and no --zenoh-config), multicast scouting is off.
    #[arg(long = "zenoh-listen")]
    pub listen: Vec<String>,
    /// zenoh endpoint to connect to, e.g. `tcp/HOST:7447` (repeat for several).
    #[arg(long = "zenoh-connect")]
    pub connect: Vec<String>,
    /// zenoh's own configuration file (JSON5); --zenoh-listen and --zenoh-connect add to it.
    #[arg(long = "zenoh-config")]
    pub config: Option<PathBuf>,
    /// The table's name in the key expressions `rodtrack/<table>/...`.
    #[arg(long, default_value = "default")]
    pub table: String,
    /// The rows' encoding on the network.
    #[arg(long = "zenoh-format", value_enum, default_value_t = WireArg::Binary)]
    pub zenoh_format: WireArg,
}

/// A camera node on the network.
#[cfg(feature = "zenoh")]
pub type Node = Arc<rodtrack_zenoh::camera::CameraNode>;
/// A camera node on the network (none in a build without the `zenoh` feature).
#[cfg(not(feature = "zenoh"))]
pub enum Node {}

#[cfg(feature = "zenoh")]
pub fn network_options(a: &NetArgs) -> rodtrack_zenoh::net::NetworkOptions {
    rodtrack_zenoh::net::NetworkOptions {
        listen: a.listen.clone(),
        connect: a.connect.clone(),
        config_file: a.config.clone(),
        table: a.table.clone(),
        format: match a.zenoh_format {
            WireArg::Binary => rodtrack_zenoh::net::WireFormat::Binary,
            WireArg::Json => rodtrack_zenoh::net::WireFormat::Json,
        },
    }
}

/// Opens the node of camera `name` (index `index` in the calibration).
#[cfg(feature = "zenoh")]
pub fn open_camera_node(
    a: &NetArgs,
    name: &str,
    index: u32,
    preview_fps: f64,
    ros2_domain: Option<u32>,
    ball_diameter_mm: Option<f64>,
) -> Result<Node> {
    use anyhow::Context;
    let node = rodtrack_zenoh::camera::CameraNode::open(
        &network_options(a),
        name,
        index,
        preview_fps,
        ros2_domain,
        ball_diameter_mm,
    )
    .with_context(|| format!("camera {index} ({name}): joining the zenoh network"))?;
    eprintln!(
        "publishing on {} (and .../raw, .../status)",
        node.rows_key()
    );
    Ok(node)
}

/// Opens the node of camera `name` (index `index` in the calibration).
#[cfg(not(feature = "zenoh"))]
pub fn open_camera_node(
    _a: &NetArgs,
    _name: &str,
    _index: u32,
    _preview_fps: f64,
    _ros2_domain: Option<u32>,
    _ball_diameter_mm: Option<f64>,
) -> Result<Node> {
    Err(no_zenoh())
}

/// The error of a build without the `zenoh` feature.
#[cfg(not(feature = "zenoh"))]
pub fn no_zenoh() -> anyhow::Error {
    anyhow::anyhow!(
        "this build has no camera network: build rodtrack with `--features zenoh` (docs/network.md)"
    )
}

/// The sink that publishes the camera's rows.
pub fn node_sink(node: &Node) -> Box<dyn MeasurementSink> {
    #[cfg(feature = "zenoh")]
    return Box::new(node.sink());
    #[cfg(not(feature = "zenoh"))]
    match *node {}
}

/// The ball sink that publishes the camera's ball rows on `.../ball`.
pub fn node_ball_sink(node: &Node) -> Box<dyn rodtrack_io::BallSink> {
    #[cfg(feature = "zenoh")]
    return Box::new(node.ball_sink());
    #[cfg(not(feature = "zenoh"))]
    match *node {}
}

/// The event sink that publishes the events detected from the camera on `.../events`.
pub fn node_event_sink(node: &Node) -> Box<dyn rodtrack_io::EventSink> {
    #[cfg(feature = "zenoh")]
    return Box::new(node.event_sink());
    #[cfg(not(feature = "zenoh"))]
    match *node {}
}

/// The hooks that publish the measured rows and the status, then call `inner`.
pub fn node_hooks(node: &Node, inner: Arc<dyn Hooks>) -> Arc<dyn Hooks> {
    #[cfg(feature = "zenoh")]
    return node.hooks(inner);
    #[cfg(not(feature = "zenoh"))]
    {
        let _ = inner;
        match *node {}
    }
}

/// Says on the network that the run ended; prints the messages that could not be published.
pub fn node_end(node: &Node) -> Result<()> {
    #[cfg(feature = "zenoh")]
    {
        use anyhow::Context;
        node.end().context("publishing the end of the run")?;
        if node.publish_errors() > 0 {
            eprintln!(
                "{} message(s) could not be published",
                node.publish_errors()
            );
        }
        Ok(())
    }
    #[cfg(not(feature = "zenoh"))]
    match *node {}
}
