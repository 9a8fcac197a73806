//! Ctrl-C for the commands that run until stopped (`track`, `fuse`, `replay`, `console`,
//! `bench-latency`): the first Ctrl-C sets the run's stop flag, so that the run ends cleanly
//! with everything written; a second one while stopping ends the process at once (exit 130).
//!
//! A Ctrl-C that comes while the run is still being set up (sources opening, a simulator
//! rendering ahead, a zenoh session starting) is remembered from [`catch_early`] on and
//! passed to the stop flag when [`install`] gives it: the run then stops at once, cleanly,
//! instead of the process dying by the signal.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, Once};

/// What Ctrl-C has done so far: presses counted, and the run's stop flag once given.
struct State {
    pressed: u32,
    stop: Option<Arc<AtomicBool>>,
}

static STATE: Mutex<State> = Mutex::new(State {
    pressed: 0,
    stop: None,
});
static HANDLER: Once = Once::new();

/// Catches Ctrl-C from now on (a command calls it first thing): presses before [`install`]
/// are remembered; a second press before it ends the process.
pub fn catch_early() {
    HANDLER.call_once(|| {
        let _ = ctrlc::set_handler(|| {
            let end = {
                let mut s = STATE.lock().unwrap_or_else(|e| e.into_inner());
                s.pressed += 1;
                match &s.stop {
                    Some(stop) => stop.swap(true, Ordering::SeqCst),
                    None => s.pressed >= 2,
                }
            };
            if end {
                std::process::exit(130);
            }
        });
    });
}

/// Gives the run's stop flag: Ctrl-C sets it (and did already, if pressed during the setup);
/// a Ctrl-C while it is set ends the process.
pub fn install(stop: Arc<AtomicBool>) {
    catch_early();
    let mut s = STATE.lock().unwrap_or_else(|e| e.into_inner());
    if s.pressed > 0 {
        stop.store(true, Ordering::SeqCst);
    }
    s.stop = Some(stop);
}
