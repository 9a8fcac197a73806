//! A software trigger clock shared by the cameras of one synchronised group.
//!
//! Each source with `trigger=software` waits for the clock's next tick, fires its camera's
//! software trigger and reads the frame, which gets the tick's number as frame id. Sources
//! sharing a clock (same `sync` name) run in their own capture threads and fire tick `k` at
//! the same instant, so the frames with id `k` of all cameras answer the same trigger: the
//! runtime's grouping by frame id turns them into synchronised frame sets. A source that
//! falls behind skips ticks (its frames keep their tick numbers; the set misses that camera).
//!
//! With real hardware the better way is a master camera in free run whose exposure output
//! drives the slaves' `Line0` input (`trigger=line0` on the slaves).

use std::collections::HashMap;
use std::sync::{Arc, Mutex, Weak};
use std::time::{Duration, Instant};

/// Ticks at a fixed rate from a common start.
#[derive(Debug)]
pub struct TriggerClock {
    fps: f64,
    t0: Instant,
}

impl TriggerClock {
    /// A clock ticking `fps` times a second from now (tick 0 is now).
    pub fn new(fps: f64) -> Arc<TriggerClock> {
        Arc::new(TriggerClock {
            fps,
            t0: Instant::now(),
        })
    }

    /// The rate, ticks per second.
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// The first tick after `after` (or the next one from now) that has not passed yet, and
    /// its time.
    pub fn next_tick(&self, after: Option<u64>) -> (u64, Instant) {
        let elapsed = Instant::now().saturating_duration_since(self.t0);
        let by_time = (elapsed.as_secs_f64() * self.fps).ceil() as u64;
        let k = after.map_or(by_time, |a| by_time.max(a + 1));
        (k, self.t0 + Duration::from_secs_f64(k as f64 / self.fps))
    }

    /// Sleeps until tick `k`'s time.
    pub fn wait_for(&self, at: Instant) {
        let now = Instant::now();
        if at > now {
            std::thread::sleep(at - now);
        }
    }
}

static GROUPS: Mutex<Vec<(String, Weak<TriggerClock>)>> = Mutex::new(Vec::new());

/// The clock of sync group `name` at `fps`: shared with the other living sources of the group
/// (`Err` with the group's rate when it differs), or a new one.
pub fn group_clock(name: &str, fps: f64) -> Result<Arc<TriggerClock>, f64> {
    let mut groups = GROUPS.lock().unwrap_or_else(|e| e.into_inner());
    groups.retain(|(_, w)| w.strong_count() > 0);
    let live: HashMap<&str, Arc<TriggerClock>> = groups
        .iter()
        .filter_map(|(n, w)| w.upgrade().map(|c| (n.as_str(), c)))
        .collect();
    if let Some(c) = live.get(name) {
        if (c.fps - fps).abs() > 1e-9 * fps {
            return Err(c.fps);
        }
        return Ok(Arc::clone(c));
    }
    drop(live);
    let c = TriggerClock::new(fps);
    groups.push((name.to_string(), Arc::downgrade(&c)));
    Ok(c)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn ticks_advance_and_never_repeat() {
        let c = TriggerClock::new(1000.0);
        let (k0, _) = c.next_tick(None);
        let (k1, t1) = c.next_tick(Some(k0));
        assert!(k1 > k0);
        c.wait_for(t1);
        let (k2, _) = c.next_tick(Some(k1));
        assert!(k2 > k1);
        // Falling behind skips ticks.
        std::thread::sleep(Duration::from_millis(20));
        let (k3, _) = c.next_tick(Some(k2));
        assert!(k3 >= k2 + 15, "{k2} -> {k3}");
    }

    #[test]
    fn groups_share_one_clock() {
        let a = group_clock("test-group", 50.0).unwrap();
        let b = group_clock("test-group", 50.0).unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        assert_eq!(group_clock("test-group", 60.0).unwrap_err(), 50.0);
        let other = group_clock("other-group", 60.0).unwrap();
        assert!(!Arc::ptr_eq(&a, &other));
        drop((a, b));
        // The group ends with its last source.
        let c = group_clock("test-group", 60.0).unwrap();
        assert_eq!(c.fps(), 60.0);
    }
}
