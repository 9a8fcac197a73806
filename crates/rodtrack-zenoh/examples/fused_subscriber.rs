//! Each rod's fused position from a rodtrack fusion node, through `rodtrack-zenoh`: the Rust
//! twin of `python/examples/zenoh_subscriber.py` (docs/network.md).
//!
//! ```sh
//! cargo run --release -p rodtrack-zenoh --features zenoh --example fused_subscriber -- tcp/127.0.0.1:7447 10
//! ```
//!
//! Arguments: an endpoint to connect to (multicast scouting then off; none: zenoh's multicast
//! discovery) and the seconds to run (default: until killed).

use rodtrack_zenoh::net::NetworkOptions;
use rodtrack_zenoh::subscriber::RowSubscriber;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let net = NetworkOptions {
        connect: args.next().into_iter().collect(),
        ..NetworkOptions::default()
    };
    let seconds: f64 = args.next().map_or(Ok(1e9), |s| s.parse())?;
    let sub = RowSubscriber::open(&net, "rodtrack/*/fused/rows", |r| match r.message {
        Ok(m) => {
            for row in &m.rows {
                println!(
                    "frame {} t_ns {} rod {} position_mm {:.4} turn_rad {:.5} status {}",
                    row.frame,
                    row.timestamp_ns.as_nanos(),
                    row.rod,
                    row.position_mm,
                    row.angle_unwrapped_rad,
                    row.status
                );
            }
        }
        Err(e) => eprintln!("{}: {e}", r.key),
    })?;
    std::thread::sleep(std::time::Duration::from_secs_f64(seconds));
    sub.close();
    Ok(())
}
