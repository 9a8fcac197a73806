//! The console's cost to the tracking: time inside the publish calls over the pipeline's own
//! time, on the simulated demo with a live client connected (frames copied at the live rate).
#![allow(clippy::unwrap_used)]

mod common;

use common::{median, Demo};
use rodtrack_console::{Console, LIVE_FPS};
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

#[test]
fn console_costs_under_two_percent_of_the_pipeline() {
    let mut demo = Demo::new(400);
    let console = Console::start("127.0.0.1:0".parse().unwrap(), None).unwrap();
    let url = format!("ws://{}/ws", console.addr());
    let stop = AtomicBool::new(false);
    let (tm, copy, received) = std::thread::scope(|s| {
        // A client that reads everything, as a browser does.
        let reader = s.spawn(|| {
            let stream = TcpStream::connect(console.addr()).unwrap();
            stream
                .set_read_timeout(Some(Duration::from_millis(200)))
                .unwrap();
            let (mut ws, _) = tungstenite::client::client(url.as_str(), stream).unwrap();
            let mut frames = 0usize;
            while !stop.load(Ordering::Relaxed) {
                if let Ok(tungstenite::Message::Binary(_)) = ws.read() {
                    frames += 1;
                }
            }
            frames
        });
        while console.clients() == 0 {
            std::thread::sleep(Duration::from_millis(10));
        }
        // Paced at the camera rate (200 fps) where the renderer keeps up.
        let swap = demo.run(&console, 400, true, true);
        let copy = demo.run(&console, 400, true, false);
        std::thread::sleep(Duration::from_millis(300));
        stop.store(true, Ordering::Relaxed);
        (swap, copy, reader.join().unwrap())
    });
    let o = console.overhead();
    let cameras = 2.0;
    let share = tm.share_at(200.0, cameras, cameras * LIVE_FPS);
    eprintln!(
        "publish_frame_buffer (swap): per frame set: tracking {:.0} us (median); publish: frame copy {:.0} us ({} calls), \
         frame skip {:.2} us, rows {:.2} us (medians); at 200 frame sets/s with {} copies/s: \
         console = {:.2} % of the tracking time; wall-clock totals on this (shared) machine: \
         tracking {:.1} ms, publish {:.2} ms ({:.2} %), {} calls, longest {:.0} us; \
         {received} frames received by the client",
        median(&tm.track_s) * 1e6,
        median(&tm.frame_copy_s) * 1e6,
        tm.frame_copy_s.len(),
        median(&tm.frame_skip_s) * 1e6,
        median(&tm.rows_s) * 1e6,
        cameras * LIVE_FPS,
        share * 100.0,
        tm.total_track_s * 1e3,
        tm.total_publish_s * 1e3,
        100.0 * tm.total_publish_s / tm.total_track_s,
        o.calls,
        o.max_ns as f64 / 1e3
    );
    let copy_share = copy.share_at(200.0, cameras, cameras * LIVE_FPS);
    eprintln!(
        "publish_frame (copying a borrowed view): frame copy {:.0} us (median of {}); \
         console = {:.2} % of the tracking time at 200 frame sets/s",
        median(&copy.frame_copy_s) * 1e6,
        copy.frame_copy_s.len(),
        copy_share * 100.0
    );
    assert!(received >= 2, "the client got no frames");
    assert!(
        copy_share < 0.04,
        "copying frames costs {:.2} % of the pipeline",
        copy_share * 100.0
    );
    assert!(
        share < 0.02,
        "the console costs {:.2} % of the pipeline",
        share * 100.0
    );
}
