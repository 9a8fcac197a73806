//! Which cameras the fusion node hears from: each camera's last message, its state, and the
//! loss rule (a camera silent while the others go on past its frames).

use rodtrack_io::runtime::PipelineCounters;
use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

/// A camera's state at the fusion node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraState {
    /// No message yet.
    Waiting,
    /// Sending.
    Ok,
    /// Silent while others send: sets go on without it.
    Lost,
    /// Its node ended its run.
    Ended,
}

impl CameraState {
    pub(super) fn code(self) -> u8 {
        match self {
            CameraState::Waiting => 0,
            CameraState::Ok => 1,
            CameraState::Lost => 2,
            CameraState::Ended => 3,
        }
    }
    fn from_code(c: u8) -> CameraState {
        match c {
            1 => CameraState::Ok,
            2 => CameraState::Lost,
            3 => CameraState::Ended,
            _ => CameraState::Waiting,
        }
    }
    /// `waiting`, `ok`, `lost`, `ended`.
    pub fn name(self) -> &'static str {
        match self {
            CameraState::Waiting => "waiting",
            CameraState::Ok => "ok",
            CameraState::Lost => "lost",
            CameraState::Ended => "ended",
        }
    }
}

/// What the fusion node knows of one camera.
#[derive(Debug)]
pub(super) struct CameraWatch {
    pub(super) name: String,
    pub(super) index: u32,
    pub(super) state: AtomicU8,
    /// ns since the node started of its last message (0: none yet).
    pub(super) last_seen_ns: AtomicU64,
    /// The grouping key (frame id or timestamp) of its last frame taken.
    pub(super) last_key: AtomicU64,
    pub(super) last_frame: AtomicU64,
    pub(super) losses: AtomicU64,
    pub(super) returns: AtomicU64,
    /// Frames it did not deliver while lost (frame-id grouping).
    pub(super) frames_missed: AtomicU64,
    /// Messages refused (bad layout, wrong camera) or dropped (queue full).
    pub(super) refused: AtomicU64,
    /// ns since start when the others were first seen past its last frame, this time (0: not
    /// behind).
    pub(super) behind_since_ns: AtomicU64,
    /// ns since start when its source last ran (a message or a check; 0: not yet).
    pub(super) awake_ns: AtomicU64,
}

impl CameraWatch {
    /// A camera not heard from yet.
    pub(super) fn new(name: String, index: u32) -> CameraWatch {
        CameraWatch {
            name,
            index,
            state: AtomicU8::new(CameraState::Waiting.code()),
            last_seen_ns: AtomicU64::new(0),
            last_key: AtomicU64::new(0),
            last_frame: AtomicU64::new(0),
            losses: AtomicU64::new(0),
            returns: AtomicU64::new(0),
            frames_missed: AtomicU64::new(0),
            refused: AtomicU64::new(0),
            behind_since_ns: AtomicU64::new(0),
            awake_ns: AtomicU64::new(0),
        }
    }
    pub(super) fn state(&self) -> CameraState {
        CameraState::from_code(self.state.load(Ordering::Relaxed))
    }
    pub(super) fn set_state(&self, s: CameraState) {
        self.state.store(s.code(), Ordering::Relaxed);
    }
}

/// What the node's threads share.
pub(super) struct Watch {
    pub(super) started: Instant,
    pub(super) cameras: Vec<CameraWatch>,
    /// ns since start of the first message of any camera (0: none yet).
    pub(super) first_any_ns: AtomicU64,
    pub(super) loss_ns: u64,
    pub(super) period_ns: u64,
    /// How far another camera's grouping key must be past a camera's last one to count as a
    /// newer frame: 0 by frame id, half a period by timestamp (the same frame's window).
    pub(super) key_slack: u64,
    pub(super) log: Box<dyn Fn(&str) + Send + Sync>,
    pub(super) counters: OnceLock<Arc<PipelineCounters>>,
}

impl Watch {
    pub(super) fn now_ns(&self) -> u64 {
        (self.started.elapsed().as_nanos() as u64).max(1)
    }

    pub(super) fn set_absent(&self, pos: usize, absent: bool) {
        if let Some(c) = self.counters.get().and_then(|c| c.cameras.get(pos)) {
            c.absent.store(absent, Ordering::Relaxed);
        }
    }

    /// Marks camera `pos` lost when it has been silent for the loss time, and another camera,
    /// sending within it, has been past its last frame for a frame period: the frame sets are
    /// then waiting for it. (A camera whose run ends with the others', its `end` message still
    /// on its way, is not lost: nobody has gone past its last frame.)
    ///
    /// Silence alone is not enough: when the machine stalls, every camera node is silent, and
    /// the first one to send again must not make the others lost (they send a moment later).
    /// Nor does the time the fusion node itself did not run count: its source checks every
    /// quarter period, and a check that comes the loss time or more after the previous one
    /// only restarts the watch.
    pub(super) fn check_loss(&self, pos: usize) {
        self.check_loss_at(pos, self.now_ns());
    }

    /// [`Watch::check_loss`] at `now` (ns since the node started).
    fn check_loss_at(&self, pos: usize, now: u64) {
        let me = &self.cameras[pos];
        if !matches!(me.state(), CameraState::Ok | CameraState::Waiting) {
            return;
        }
        let first = self.first_any_ns.load(Ordering::Relaxed);
        if first == 0 {
            return;
        }
        let awake = me.awake_ns.swap(now, Ordering::Relaxed);
        if awake != 0 && now.saturating_sub(awake) >= self.loss_ns {
            // This node did not run: its silence is not the camera's.
            me.behind_since_ns.store(0, Ordering::Relaxed);
            return;
        }
        let last = match me.last_seen_ns.load(Ordering::Relaxed) {
            0 => first,
            t => t,
        };
        let silent = now.saturating_sub(last);
        let seen_any = me.last_seen_ns.load(Ordering::Relaxed) != 0;
        let mine = me.last_key.load(Ordering::Relaxed);
        let others = self.cameras.iter().enumerate().any(|(i, c)| {
            i != pos
                && c.state() == CameraState::Ok
                && now.saturating_sub(c.last_seen_ns.load(Ordering::Relaxed)) < self.loss_ns
                && (!seen_any
                    || c.last_key.load(Ordering::Relaxed) > mine.saturating_add(self.key_slack))
        });
        if !others {
            me.behind_since_ns.store(0, Ordering::Relaxed);
            return;
        }
        let since = match me.behind_since_ns.load(Ordering::Relaxed) {
            0 => {
                me.behind_since_ns.store(now, Ordering::Relaxed);
                now
            }
            t => t,
        };
        if silent < self.loss_ns || now - since < self.period_ns {
            return;
        }
        me.set_state(CameraState::Lost);
        me.losses.fetch_add(1, Ordering::Relaxed);
        self.set_absent(pos, true);
        (self.log)(&format!(
            "fusion: camera {} ({}) lost: no rows for {:.1} ms ({:.1} frame periods) after frame {}; frame sets go on without it, marked incomplete",
            me.index,
            me.name,
            silent as f64 * 1e-6,
            silent as f64 / self.period_ns as f64,
            me.last_frame.load(Ordering::Relaxed)
        ));
    }

    /// A message of camera `pos` arrived at `now` (ns since the node started).
    pub(super) fn heard(&self, pos: usize, now: u64) {
        let _ = self
            .first_any_ns
            .compare_exchange(0, now, Ordering::Relaxed, Ordering::Relaxed);
        let me = &self.cameras[pos];
        me.last_seen_ns.store(now, Ordering::Relaxed);
        me.awake_ns.store(now, Ordering::Relaxed);
        me.behind_since_ns.store(0, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    const PERIOD_NS: u64 = 5_000_000;
    const TICK_NS: u64 = PERIOD_NS / 4;

    fn watch(log: Arc<Mutex<Vec<String>>>) -> Watch {
        let camera = |index: u32| CameraWatch::new(format!("cam{index}"), index);
        Watch {
            started: Instant::now(),
            cameras: vec![camera(0), camera(1)],
            first_any_ns: AtomicU64::new(0),
            loss_ns: PERIOD_NS * 5 / 2,
            period_ns: PERIOD_NS,
            key_slack: 0,
            log: Box::new(move |l| log.lock().unwrap().push(l.to_string())),
            counters: OnceLock::new(),
        }
    }

    /// Camera `pos`'s frame `frame` arrives at `now`, as the node's source takes it.
    fn deliver(w: &Watch, pos: usize, frame: u64, now: u64) {
        w.heard(pos, now);
        let c = &w.cameras[pos];
        if c.state() == CameraState::Waiting {
            c.set_state(CameraState::Ok);
        }
        c.last_key.store(frame, Ordering::Relaxed);
        c.last_frame.store(frame, Ordering::Relaxed);
    }

    /// Runs both cameras' sources from `from_ns` to `to_ns`: a camera's frame `f` arrives at
    /// `arrival(pos, f)` (None: never), each source checks for a loss every tick in between
    /// (`awake(now)`: whether the node's threads run at `now`). Returns the time camera 1 was
    /// found lost, if it was.
    fn run(
        w: &Watch,
        to_ns: u64,
        arrival: impl Fn(usize, u64) -> Option<u64>,
        awake: impl Fn(u64) -> bool,
    ) -> Option<u64> {
        let mut next = [0u64; 2];
        let mut now = 0;
        while now <= to_ns {
            if awake(now) {
                for (pos, next) in next.iter_mut().enumerate() {
                    while arrival(pos, *next).is_some_and(|t| t <= now) {
                        deliver(w, pos, *next, now);
                        *next += 1;
                    }
                    w.check_loss_at(pos, now);
                }
                if w.cameras[1].state() == CameraState::Lost {
                    return Some(now);
                }
            }
            now += TICK_NS / 5;
        }
        None
    }

    #[test]
    fn a_camera_that_stops_is_lost_within_three_periods() {
        let log = Arc::default();
        let w = watch(Arc::clone(&log));
        // Camera 1 killed after frame 46 (at 230 ms); camera 0 goes on.
        let lost = run(
            &w,
            400_000_000,
            |pos, f| (pos == 0 || f <= 46).then_some(f * PERIOD_NS + 300_000),
            |_| true,
        )
        .expect("camera 1 lost");
        let silent = lost - (46 * PERIOD_NS + 300_000);
        assert!(
            (PERIOD_NS * 2..=PERIOD_NS * 3).contains(&silent),
            "lost after {silent} ns: {:?}",
            log.lock().unwrap()
        );
        assert_eq!(w.cameras[0].state(), CameraState::Ok);
    }

    #[test]
    fn cameras_that_stall_together_are_not_lost() {
        // Both camera nodes stall 33 ms after frame 46 (the machine was busy), then deliver
        // their late frames: camera 0 first, camera 1 up to 4 ms later.
        for lag_ns in [0, 500_000, 2_000_000, 4_000_000] {
            let log = Arc::default();
            let w = watch(Arc::clone(&log));
            let resume = 46 * PERIOD_NS + 33_000_000;
            let lost = run(
                &w,
                400_000_000,
                |pos, f| {
                    let t = f * PERIOD_NS + 300_000;
                    let t = if f > 46 { t.max(resume) } else { t };
                    Some(if pos == 1 && f > 46 {
                        t.max(resume + lag_ns)
                    } else {
                        t
                    })
                },
                |_| true,
            );
            assert_eq!(lost, None, "lag {lag_ns} ns: {:?}", log.lock().unwrap());
        }
    }

    #[test]
    fn a_stall_of_the_fusion_node_itself_loses_no_camera() {
        // The fusion node's threads do not run for 33 ms; both cameras went on, their
        // messages queued, camera 1's taken a little after camera 0's on wake-up.
        let log = Arc::default();
        let w = watch(Arc::clone(&log));
        let (from, to) = (230_000_000, 263_000_000);
        let lost = run(
            &w,
            400_000_000,
            |pos, f| {
                let t = f * PERIOD_NS + 300_000;
                Some(if pos == 1 && (from..to + 1_000_000).contains(&t) {
                    to + 1_000_000
                } else {
                    t
                })
            },
            |now| !(from..to).contains(&now),
        );
        assert_eq!(lost, None, "{:?}", log.lock().unwrap());
    }
}
