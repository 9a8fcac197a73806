//! `ball_stopped`: the ball's speed, fitted over a short window of `ok` rows, is not
//! distinguishable from zero given the positions' noise, measured from the same rows, for
//! [`EventConfig::stopped_min_s`].
//!
//! Over the `ok` rows younger than [`EventConfig::stopped_window_s`] the velocity is the
//! least-squares slope of `x` and `y` against time; it is the velocity at the rows' mean time
//! (exactly so for a constant deceleration), which is the time the window stands for. The
//! positions' noise `sigma` is measured from the same rows: each row's distance from the line
//! through its two neighbours (second differences, blind to a smooth motion's speed and
//! nearly to its deceleration: `a dt^2`, 0.05 mm at 2 m/s^2 and 200 fps), scaled by that
//! distance's standard deviation for independent noise. The slope's standard error is
//! `sigma / sqrt(sum (t - mean t)^2)`. The ball is still when its fitted speed is within
//! [`EventConfig::stopped_sigmas`] standard errors of zero, and moves again beyond three times
//! that (hysteresis: a still ball's noise does not end its rest: the fitted speed of a ball at
//! rest over its standard error has Rayleigh's distribution, beyond 9 once in 10^17 windows)
//! for a window's length (a step in the positions, as when a camera drops out of the fused
//! rows, moves only the windows that hold it). A rest lasting
//! [`EventConfig::stopped_min_s`] (in the windows' times) is a stop, at the first still
//! window's time.
//!
//! A ball slowing at `a` is reported `sigmas * se / a` before it rests at most (the speed
//! still below the threshold): a few milliseconds at the noise of a fraction of a millimetre.
//! A ball stopped dead (pinned, or caught by a foot) is reported up to half a window late:
//! the windows holding its last motion are not still.

use super::{BallEvent, EventConfig, EventKind, Sample};

/// `ok` rows kept for the window (0.32 s at 200 fps; a faster camera's window is cut to the
/// last this many rows).
const ROWS: usize = 64;

/// A window needs this many rows for a slope and a noise (two second differences per axis).
const MIN_ROWS: usize = 4;

#[derive(Debug, Clone, Copy)]
struct Rest {
    /// The first still window's row nearest its mean time.
    frame: u64,
    t: crate::Timestamp,
    /// The first still window's mean position, mm.
    x_mm: f64,
    y_mm: f64,
    /// The noise measured then, mm.
    sigma_mm: f64,
    reported: bool,
}

/// What one window says.
#[derive(Debug, Clone, Copy)]
struct Window {
    /// Fitted speed over its standard error.
    speed_over_se: f64,
    centre: Sample,
    mean: [f64; 2],
    sigma_mm: f64,
}

/// The stop rule's state (see the module's documentation); no allocation.
#[derive(Debug, Clone)]
pub(super) struct StopRule {
    ring: [Sample; ROWS],
    len: usize,
    next: usize,
    rest: Option<Rest>,
    /// The rows were dropped after a gap while at rest: the next window says whether the
    /// ball still lies there.
    after_gap: bool,
    /// At rest, the first row of the windows moving since (a rest ends once they span a
    /// window: a step in the positions, as when a camera drops out of the fused rows, moves
    /// only the windows that hold it).
    moving_since: Option<crate::Timestamp>,
}

impl StopRule {
    pub(super) fn new() -> StopRule {
        StopRule {
            ring: [Sample::default(); ROWS],
            len: 0,
            next: 0,
            rest: None,
            after_gap: false,
            moving_since: None,
        }
    }

    /// Forgets the rows and the rest (the ball went into a goal, or out).
    pub(super) fn clear(&mut self) {
        self.len = 0;
        self.rest = None;
        self.after_gap = false;
        self.moving_since = None;
    }

    /// Takes the next `ok` row; returns the stop it decides.
    pub(super) fn push(&mut self, cfg: &EventConfig, s: Sample) -> Option<BallEvent> {
        // Unseen for longer than a window: the rows before say nothing of the ball now.
        if self.len > 0 {
            let last = self.ring[(self.next + ROWS - 1) % ROWS];
            if s.t.seconds_since(last.t) > cfg.stopped_window_s {
                self.len = 0;
                self.after_gap = self.rest.is_some();
            }
        }
        self.ring[self.next] = s;
        self.next = (self.next + 1) % ROWS;
        self.len = (self.len + 1).min(ROWS);
        let w = self.window(cfg, s)?;
        let k = cfg.stopped_sigmas;
        if let Some(r) = self.rest {
            // The first window after a gap: the same rest if the ball lies where it lay.
            let moved = (w.mean[0] - r.x_mm).hypot(w.mean[1] - r.y_mm);
            let elsewhere = self.after_gap && moved > 3.0 * k * r.sigma_mm.max(w.sigma_mm);
            let moving = w.speed_over_se > 3.0 * k;
            let since = match (moving, self.moving_since) {
                (false, _) => None,
                (true, None) => Some(s.t),
                (true, Some(t)) => Some(t),
            };
            self.moving_since = since;
            let moved_on = since.is_some_and(|t| s.t.seconds_since(t) >= cfg.stopped_window_s);
            if moved_on || elsewhere {
                self.rest = None;
                self.moving_since = None;
            }
        }
        self.after_gap = false;
        if self.rest.is_none() && w.speed_over_se <= k {
            self.rest = Some(Rest {
                frame: w.centre.frame,
                t: w.centre.t,
                x_mm: w.mean[0],
                y_mm: w.mean[1],
                sigma_mm: w.sigma_mm,
                reported: false,
            });
        }
        let r = self.rest.as_mut()?;
        if r.reported || w.centre.t.seconds_since(r.t) < cfg.stopped_min_s {
            return None;
        }
        r.reported = true;
        Some(BallEvent {
            frame: r.frame,
            timestamp_ns: r.t,
            kind: EventKind::BallStopped {
                x_mm: r.x_mm,
                y_mm: r.y_mm,
            },
        })
    }

    /// The kept row `i`, oldest first.
    fn row(&self, i: usize) -> Sample {
        self.ring[(self.next + ROWS - self.len + i) % ROWS]
    }

    /// The window of rows younger than `stopped_window_s` ending at `s`: its fitted speed over
    /// the speed's standard error, its mean time's row, its mean position, its noise; `None`
    /// with fewer than [`MIN_ROWS`] rows or rows spanning under half the window.
    fn window(&self, cfg: &EventConfig, s: Sample) -> Option<Window> {
        let first = (0..self.len)
            .find(|&i| s.t.seconds_since(self.row(i).t) < cfg.stopped_window_s)
            .unwrap_or(self.len);
        let n = self.len - first;
        if n < MIN_ROWS || s.t.seconds_since(self.row(first).t) < 0.5 * cfg.stopped_window_s {
            return None;
        }
        // Times relative to the newest row, s.
        let age = |i: usize| -s.t.seconds_since(self.row(i).t);
        let (mut st, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for i in first..self.len {
            let r = self.row(i);
            st += age(i);
            sx += r.x_mm;
            sy += r.y_mm;
        }
        let nf = n as f64;
        let (tm, xm, ym) = (st / nf, sx / nf, sy / nf);
        let (mut stt, mut stx, mut sty) = (0.0, 0.0, 0.0);
        for i in first..self.len {
            let r = self.row(i);
            let dt = age(i) - tm;
            stt += dt * dt;
            stx += dt * (r.x_mm - xm);
            sty += dt * (r.y_mm - ym);
        }
        if stt <= 0.0 {
            return None;
        }
        // The noise: each inner row against the line through its neighbours.
        let (mut e2, mut weight) = (0.0, 0.0);
        for i in first + 1..self.len - 1 {
            let (a, b, c) = (self.row(i - 1), self.row(i), self.row(i + 1));
            let (ta, tb, tc) = (age(i - 1), age(i), age(i + 1));
            if tc <= ta {
                continue;
            }
            let (wa, wc) = ((tc - tb) / (tc - ta), (tb - ta) / (tc - ta));
            let ex = b.x_mm - (wa * a.x_mm + wc * c.x_mm);
            let ey = b.y_mm - (wa * a.y_mm + wc * c.y_mm);
            e2 += ex * ex + ey * ey;
            // Per axis: var(e) = sigma^2 (1 + wa^2 + wc^2).
            weight += 2.0 * (1.0 + wa * wa + wc * wc);
        }
        if weight <= 0.0 {
            return None;
        }
        let sigma_mm = (e2 / weight).sqrt();
        let speed = (stx / stt).hypot(sty / stt);
        let se = sigma_mm / stt.sqrt();
        let speed_over_se = if se > 0.0 {
            speed / se
        } else if speed > 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
        let centre = (first..self.len)
            .min_by(|&i, &j| (age(i) - tm).abs().total_cmp(&(age(j) - tm).abs()))
            .map(|i| self.row(i))
            .unwrap_or(s);
        Some(Window {
            speed_over_se,
            centre,
            mean: [xm, ym],
            sigma_mm,
        })
    }
}
