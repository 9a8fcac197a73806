//! The progress bar of a run of several scenarios, on stderr.

use std::collections::BTreeMap;
use std::io::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Progress shared by the jobs.
pub(crate) struct Progress {
    done: AtomicUsize,
    total: usize,
    start: Instant,
    current: Mutex<BTreeMap<String, (usize, usize)>>,
    last: Mutex<Instant>,
    enabled: bool,
}

impl Progress {
    /// A bar for `total` units of work, drawn when `enabled`.
    pub(crate) fn new(total: usize, enabled: bool) -> Progress {
        Progress {
            done: AtomicUsize::new(0),
            total,
            start: Instant::now(),
            current: Mutex::new(BTreeMap::new()),
            last: Mutex::new(Instant::now()),
            enabled,
        }
    }
    /// Scenario `name` has done `done` of its `total` units, `step` more than before.
    pub(crate) fn update(&self, name: &str, done: usize, total: usize, step: usize) {
        self.done.fetch_add(step, Ordering::Relaxed);
        if let Ok(mut c) = self.current.lock() {
            if done >= total {
                c.remove(name);
            } else {
                c.insert(name.to_string(), (done, total));
            }
        }
        self.draw(false);
    }
    /// Draws the bar (at most every 200 ms unless `force`).
    pub(crate) fn draw(&self, force: bool) {
        if !self.enabled {
            return;
        }
        let Ok(mut last) = self.last.lock() else {
            return;
        };
        if !force && last.elapsed().as_millis() < 200 {
            return;
        }
        *last = Instant::now();
        let done = self.done.load(Ordering::Relaxed).min(self.total);
        let frac = done as f64 / self.total.max(1) as f64;
        let width = 30;
        let filled = (frac * width as f64).round() as usize;
        let running = self
            .current
            .lock()
            .map(|c| {
                c.iter()
                    .map(|(n, (d, t))| format!("{n} {d}/{t}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default();
        let mut err = std::io::stderr().lock();
        let _ = write!(
            err,
            "\r[{}{}] {:>3.0}%  {:>5.1} s  {:<48.48}",
            "#".repeat(filled),
            ".".repeat(width - filled),
            100.0 * frac,
            self.start.elapsed().as_secs_f64(),
            running
        );
        let _ = err.flush();
    }
}
