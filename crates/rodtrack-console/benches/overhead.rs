//! The console's cost to the tracking, as a share of the pipeline's own time: the simulated demo
//! (two calibrated 1440x1080 Bayer cameras, 8 rods) tracked and published at 200 frame sets/s
//! with a live WebSocket client connected (so frames are copied at the live rate), once through
//! the buffer-swap path ([`ConsoleHandle::publish_frame_buffer`], what `rodtrack demo`,
//! `rodtrack console --demo` and `rodtrack track --console` use) and once through the copy
//! path ([`ConsoleHandle::publish_frame`], a decimated copy of a borrowed frame, for callers
//! that cannot hand over their frame buffers), several runs each, alternating.
//!
//! The share of one run comes from the medians of each kind of call, which a loaded machine
//! preempts less than it does wall-clock totals: `(copies/s x copy + (frames/s - copies/s) x
//! skip + sets/s x rows) / (sets/s x tracking per set)`, at 200 sets/s and the console's live
//! rate per camera ([`LIVE_FPS`] for swapped frames, [`LIVE_COPY_FPS`] for copied ones). Making
//! the overlays on the tracking side (`CameraOverlays::fill`) counts as part of a live frame's
//! call; the marker's pixels are computed when the console serialises the frame, on its thread.
//!
//! ```sh
//! cargo bench -p rodtrack-console --bench overhead                 # 5 runs of 400 frame sets
//! cargo bench -p rodtrack-console --bench overhead -- --runs 9 --frames 600 --max-percent 2
//! ```
//! `--max-percent P` exits with status 1 when a path's median share is above `P` %.
#![allow(missing_docs, clippy::unwrap_used)]

#[path = "../tests/common/mod.rs"]
mod common;

use common::{median, Demo, Timings};
use rodtrack_console::{Console, ConsoleHandle, LIVE_COPY_FPS, LIVE_FPS};
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Frame sets per second the demo is paced at (the cameras' rate).
const SETS_PER_S: f64 = 200.0;

struct Options {
    runs: usize,
    frames: usize,
    max_percent: Option<f64>,
}

fn options() -> Options {
    let mut o = Options {
        runs: 5,
        frames: 400,
        max_percent: None,
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || -> f64 {
            args.next()
                .and_then(|v| v.parse().ok())
                .unwrap_or_else(|| panic!("{arg} wants a number"))
        };
        match arg.as_str() {
            "--runs" => o.runs = (value() as usize).max(1),
            "--frames" => o.frames = (value() as usize).max(10),
            "--max-percent" => o.max_percent = Some(value()),
            // `cargo bench` passes `--bench`; test-harness filters are ignored.
            _ => {}
        }
    }
    o
}

/// One path's run, times in s: [share of the tracking time, tracking per set, live frame call,
/// skipped frame (mean of the cameras' medians), `publish_rows` per set, the clock's cost in one
/// interval]; calls and tracking are medians net of the clock's cost.
fn summarise(tm: &Timings, cameras: f64, live_fps: f64) -> [f64; 6] {
    [
        tm.share_at(SETS_PER_S, cameras, cameras * live_fps),
        tm.track_net(),
        tm.net(&tm.frame_copy_s),
        tm.skip_net(),
        tm.net(&tm.rows_s),
        tm.clock_s(),
    ]
}

fn run_paths(demo: &mut Demo, console: &ConsoleHandle, o: &Options) -> Vec<[[f64; 6]; 2]> {
    let cameras = demo.cals.len() as f64;
    let mut runs = Vec::new();
    for r in 0..o.runs {
        let swap = demo.run(console, o.frames, true, true);
        let copy = demo.run(console, o.frames, true, false);
        let (s, c) = (
            summarise(&swap, cameras, LIVE_FPS),
            summarise(&copy, cameras, LIVE_COPY_FPS),
        );
        eprintln!(
            "run {}: swap {:.2} % (live {:.0} us, {} live), copy {:.2} % (live {:.0} us, {} live); \
             tracking {:.0} / {:.0} us per set; skip {:.3} / {:.3} us, rows {:.3} / {:.3} us, \
             clock {:.3} us (net of the clock)",
            r + 1,
            s[0] * 100.0,
            s[2] * 1e6,
            swap.frame_copy_s.len(),
            c[0] * 100.0,
            c[2] * 1e6,
            copy.frame_copy_s.len(),
            s[1] * 1e6,
            c[1] * 1e6,
            s[3] * 1e6,
            c[3] * 1e6,
            s[4] * 1e6,
            c[4] * 1e6,
            c[5] * 1e6,
        );
        runs.push([s, c]);
    }
    runs
}

fn main() {
    let o = options();
    let mut demo = Demo::new(o.frames);
    let console = Console::start("127.0.0.1:0".parse().unwrap(), None).unwrap();
    let url = format!("ws://{}/ws", console.addr());
    let stop = AtomicBool::new(false);
    let (runs, received) = std::thread::scope(|s| {
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
        let runs = run_paths(&mut demo, &console, &o);
        std::thread::sleep(Duration::from_millis(300));
        stop.store(true, Ordering::Relaxed);
        (runs, reader.join().unwrap())
    });
    let pick = |path: usize, k: usize| -> Vec<f64> { runs.iter().map(|r| r[path][k]).collect() };
    let range = |path: usize| -> (f64, f64) {
        let v = pick(path, 0);
        (
            v.iter().copied().fold(f64::INFINITY, f64::min) * 100.0,
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max) * 100.0,
        )
    };
    let (swap, copy) = (median(&pick(0, 0)), median(&pick(1, 0)));
    let (swap_range, copy_range) = (range(0), range(1));
    println!(
        "console overhead, median of {} runs of {} frame sets at {SETS_PER_S:.0} sets/s, 2 cameras:",
        o.runs, o.frames
    );
    println!(
        "  publish_frame_buffer (swap, {LIVE_FPS} live frames/s):  {:.2} % of the tracking time \
         (runs {:.2} to {:.2} %; live frame call {:.1} us)",
        swap * 100.0,
        swap_range.0,
        swap_range.1,
        median(&pick(0, 2)) * 1e6
    );
    println!(
        "  publish_frame (copy, {LIVE_COPY_FPS} live frames/s):        {:.2} % of the tracking time \
         (runs {:.2} to {:.2} %; live frame call {:.1} us)",
        copy * 100.0,
        copy_range.0,
        copy_range.1,
        median(&pick(1, 2)) * 1e6
    );
    let both = |k: usize| -> f64 {
        let mut v = pick(0, k);
        v.extend(pick(1, k));
        median(&v)
    };
    println!(
        "  per call (medians, both paths): frame not wanted {:.3} us, publish_rows {:.3} us per \
         set; the clock's own {:.3} us taken out of every interval",
        both(3) * 1e6,
        both(4) * 1e6,
        both(5) * 1e6
    );
    println!(
        "  tracking {:.0} us per frame set (median); {received} live frames received by the client",
        median(&pick(1, 1)) * 1e6
    );
    let o_all = console.overhead();
    println!(
        "  publish calls {}, longest {:.0} us",
        o_all.calls,
        o_all.max_ns as f64 / 1e3
    );
    let mut failed = received == 0;
    if received == 0 {
        eprintln!("the client got no frames");
    }
    if let Some(max) = o.max_percent {
        for (name, share) in [("swap", swap), ("copy", copy)] {
            if share * 100.0 > max {
                eprintln!("the {name} path costs {:.2} % > {max} %", share * 100.0);
                failed = true;
            }
        }
    }
    if failed {
        std::process::exit(1);
    }
}
