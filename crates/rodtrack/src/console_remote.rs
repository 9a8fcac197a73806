//! `rodtrack console --subscribe zenoh`: the web console fed from a camera network: every
//! camera node's rows, status and preview frames, the fusion node's fused rows and status,
//! and the ball: the fusion node's, or a camera node's where the table has no fusion node
//! publishing one, with the events and score of the same rule: the fusion node's once it sends
//! one, else a camera node's (`track --publish zenoh --zenoh-events`) (docs/network.md).

use crate::console::Args;
use anyhow::Result;

/// Malformed messages printed (the rest are counted).
#[cfg(feature = "zenoh")]
const PRINTED_MALFORMED: u64 = 5;

/// Runs the console on the network (a build without the `zenoh` feature refuses).
#[cfg(not(feature = "zenoh"))]
pub fn run(_args: &Args) -> Result<()> {
    Err(crate::network::no_zenoh())
}

/// Runs the console on the network.
#[cfg(feature = "zenoh")]
pub fn run(args: &Args) -> Result<()> {
    use anyhow::Context;
    use rodtrack_console::{Console, ConsoleOptions, Preview};
    use rodtrack_zenoh::monitor::{Monitor, NodeEvent};
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use std::time::{Duration, Instant};

    crate::interrupt::catch_early();
    let net = crate::network::network_options(&args.net);
    let table = net.table()?.to_string();
    let console = Arc::new(
        Console::start_with(
            args.addr,
            None,
            &ConsoleOptions {
                allowed_hosts: args.allow_host.clone(),
            },
        )
        .context("cannot start the console")?,
    );
    let c = console.clone();
    // The node whose ball is shown: the fusion node once it sends one, else the first camera
    // node that does (each frame's rows shown once, not once per node).
    // The events likewise (a camera node's own events count the score of its camera alone).
    let (ball_from, events_from) = (Shown::default(), Shown::default());
    let monitor = Monitor::open(&net, move |event| match event {
        NodeEvent::Rows { message, .. } => c.publish_rows(&message.rows),
        NodeEvent::Ball { node, rows, .. } => {
            if ball_from.shows(node) {
                c.publish_ball(&rows);
            }
        }
        NodeEvent::Event { node, event, .. } => {
            if events_from.shows(node) {
                c.publish_events(&[event]);
            }
        }
        NodeEvent::Status { node, status, .. } => c.publish_node_status(&node.label(), status),
        NodeEvent::Preview { key, preview, .. } => {
            let h = preview.header;
            let p = Preview {
                width: h.width_px as usize,
                height: h.height_px as usize,
                channels: h.format.channels(),
                factor: 1,
                pixels: preview.pixels,
            };
            let source = (h.source_width_px as usize, h.source_height_px as usize);
            if let Err(e) =
                c.publish_preview(h.camera, &p, source, h.frame, h.timestamp_ns.as_secs_f64())
            {
                c.note_malformed(key, &e.to_string());
                eprintln!("preview on {key} not shown: {e}");
            }
        }
        NodeEvent::Malformed { key, error, count } => {
            c.note_malformed(key, &error.to_string());
            if count <= PRINTED_MALFORMED {
                eprintln!("malformed message on {key}: {error}");
            }
            if count == PRINTED_MALFORMED {
                eprintln!("(further malformed messages are counted, not printed)");
            }
        }
    })
    .context("joining the zenoh network")?;
    println!(
        "rodtrack console: {} (camera network, table `{table}`)",
        console.url()
    );
    eprintln!("subscribed to {}", monitor.keys().join(", "));
    let stop = Arc::new(AtomicBool::new(false));
    crate::interrupt::install(stop.clone());
    let until = args
        .seconds
        .map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
    while !stop.load(Ordering::SeqCst) && until.is_none_or(|u| Instant::now() < u) {
        std::thread::sleep(Duration::from_millis(50));
    }
    let malformed = monitor.malformed();
    monitor.close();
    if malformed > 0 {
        eprintln!("{malformed} malformed message(s) received");
    }
    Ok(())
}

/// Which node's ball (or events) the console shows: the fusion node's once it sends one, else
/// the first camera node's that does; each frame's rows (each event) shown once, not once per
/// node.
#[cfg(feature = "zenoh")]
#[derive(Default)]
struct Shown(std::sync::Mutex<Option<rodtrack_zenoh::monitor::Node>>);

#[cfg(feature = "zenoh")]
impl Shown {
    /// Whether a message of `node` is shown (and from then on the node shown).
    fn shows(&self, node: rodtrack_zenoh::monitor::Node) -> bool {
        use rodtrack_zenoh::monitor::Node;
        let mut from = self.0.lock().unwrap_or_else(|e| e.into_inner());
        let shown = match (&*from, &node) {
            (_, Node::Fusion) | (None, _) => true,
            (Some(f), n) => f == n,
        };
        if shown {
            *from = Some(node);
        }
        shown
    }
}
