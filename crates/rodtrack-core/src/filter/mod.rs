//! Per-rod temporal filter (SPEC 4 step 6): position and velocity, unwrapped angle and angular
//! velocity with an exact multi-turn count, gating of implausible measurements, coasting on the
//! prediction through short occlusions, and confirmed re-acquisition.
//!
//! # Model
//!
//! Two independent constant-acceleration Kalman filters (state `[x, v, a]`, 3x3 covariance):
//! one for the position along `u` (mm), one for the *unwrapped* angle (rad). Process noise is a
//! white jerk (`jerk_std`), large enough that hand motion at the acceleration bounds is followed
//! without lag; the estimated acceleration is extrapolated over at most `accel_horizon_s` (one
//! frame), so a coast continues at constant speed. `dt` always comes from the measurement
//! timestamps. The measurement variance is `sigma^2 / quality^2`, so a doubtful decode counts
//! less and widens its own gate (up to the cap below).
//!
//! The decoder is already precise (enhanced mode: 0.02 mm, 0.002 rad per frame) compared with
//! what a hand does in 5 ms, so with the defaults the filter smooths little (std x0.96 on a
//! ramp); its work is gating, velocities, the turn count and coasting. Lower jerk stds smooth
//! more (x0.81 position, x0.85 angle at 2e5 mm/s^3 and 1e4 rad/s^3) at the cost of lag and
//! rejections in fast kicks.
//!
//! # Gating
//!
//! A measurement is accepted only when both innovations pass:
//!
//! ```text
//! |innovation| <= min(gate_sigma * sqrt(S) + max_accel * tau^2 / 2,  max_gate)
//! ```
//!
//! `S` is the predicted innovation variance, `tau` the time since the state's last update (the
//! prediction horizon) and `max_accel` the physical bound on the rod's acceleration (rods are moved
//! by hand). The angle innovation is wrapped to `(-pi, pi]` around the prediction. The cap
//! `max_gate` is what makes the filter catch the decoder's typical single-frame failures: it is
//! smaller than one Gray step (`2 pi / 32` = 0.196 rad) and than one barcode cell (4 mm),
//! so a measurement off by a stripe period (`pi / 4`), a Gray step or a barcode cell can never
//! pass, whatever the uncertainty. A measurement that fails is reported through
//! [`RodFilter::last_rejection`] and the row is `predicted`, never `ok`.
//!
//! # Occlusion, loss and re-acquisition
//!
//! Without an accepted measurement the filter coasts: the row carries the prediction with status
//! `predicted` and a quality decaying linearly to 0 over `max_coast_s`. After `max_coast_s`
//! without an accepted measurement the rod is `lost` (values 0).
//!
//! Every usable measurement the main track cannot take (no track yet, lost, or rejected by the
//! gate) feeds a *candidate* track, initialised from that single measurement at once. The
//! candidate becomes the track (status `ok` from that frame on) as soon as one further
//! measurement passes the candidate's own gate, so that a single wrong measurement is never
//! reported `ok`, even right after re-acquisition:
//!
//! * rod still or slow: the candidate starts with a small velocity prior, so the second frame
//!   confirms when it agrees with the first (re-acquired `ok` at the 2nd frame);
//! * rod moving: the second frame gives the velocity (two-point start) and the third frame
//!   confirms it (`ok` at the 3rd frame); a wrong first frame delays this to the 4th.
//!
//! The value is available at once: while the candidate waits, the row is `predicted` and holds
//! the candidate's estimate (the latest measurement). While the old track still coasts, a
//! confirmed candidate replaces it only when it lies within the old prediction's own uncertainty
//! plus the physical bound `max_accel tau^2 / 2`, or after `override_points` (4) mutually
//! consistent frames: a decoder wrong by a stripe period for up to 3 frames does not overrule a
//! confident prediction, and a track that diverged is replaced after at most 4 frames.
//! [`FilterConfig::confirm_reacquisition`] = `false` reports the first measurement `ok` instead.
//!
//! # Multi-turn count and its speed limit
//!
//! The absolute angle needs no history; the turn count does. An accepted angle is placed at
//! `prediction + wrap(angle - prediction)`, and it is accepted only within the gate (at most
//! 0.15 rad), so the count stays exact whatever the step per frame: there is no speed limit
//! while tracking, only an acceleration limit. The prediction extrapolates the estimated speed
//! and acceleration; what it cannot know is the change of acceleration in one frame. The
//! defaults follow 3000 rad/s^2 at 5 Hz (1e5 rad/s^3) with no rejection; a sudden
//! acceleration `alpha` from a steady spin costs `alpha dt^2 / 2` of prediction error, which the
//! gate takes up to `alpha` = 2 * 0.15 / dt^2 = 12 000 rad/s^2 at 200 fps. Beyond that
//! the measurement is rejected, never mis-counted, and a new track takes over with the count
//! continued from the prediction, exact while the prediction error stays below pi (a quarter of
//! a turn of margin at 3000 rad/s^2 over 8 frames, 40 ms).
//!
//! A speed limit applies only where there is no prediction to unwrap against: a candidate's
//! two-point start measures the angle step between two frames, which must stay below pi, so
//! `|omega| < pi / dt` = 628 rad/s = 6000 rpm at 200 fps (3000 rpm across one dropped frame,
//! 2000 rpm across two), capped by [`FilterConfig::max_angular_velocity_rad_s`]. After `lost`
//! the turn count continues from the last known unwrapped angle assuming the rod turned less than
//! half a turn while unseen: it cannot be known.
//!
//! The filter allocates nothing: its whole state is a few numbers per rod.

mod axis;
mod bank;
mod config;
mod turns;

pub use crate::angle::wrap_pi;
use crate::angle::{unwrap_near, wrap_2pi};
use crate::measurement::{Measurement, Status};
use crate::time::Timestamp;
use axis::{Axis, Track};
pub use bank::FilterBank;
pub use config::{FilterConfig, Rejection};
use turns::TurnCount;
pub use turns::TurnStats;

/// A track not yet confirmed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Candidate {
    track: Track,
    /// Measurements taken (1 after a start, 2 after a two-point start).
    points: u32,
    /// Its rate comes from a two-point start over a step the speed bound does not
    /// disambiguate.
    ambiguous: bool,
}

/// The measurement as the filter uses it.
#[derive(Debug, Clone, Copy)]
struct Obs {
    t: Timestamp,
    position_mm: f64,
    angle_rad: f64,
    r_pos: f64,
    r_ang: f64,
    quality: f64,
}

/// A measurement checked against a track's prediction.
#[derive(Debug, Clone, Copy)]
struct Gated {
    pred: Track,
    nu_pos: f64,
    nu_ang: f64,
    result: Result<(), Rejection>,
}

/// The per-rod state filter. See the [module documentation](self) for the model.
///
/// Feed it one row per frame in time order (a camera's row or a fused one); it returns the
/// filtered row for the same frame, with no delay.
#[derive(Debug, Clone)]
pub struct RodFilter {
    cfg: FilterConfig,
    main: Option<Track>,
    candidate: Option<Candidate>,
    /// The last known unwrapped angle, kept through `lost` to continue the turn count.
    turn_ref: Option<f64>,
    last_t: Option<Timestamp>,
    rejection: Option<Rejection>,
    /// Whether the turn count is known, and its counters.
    turns: TurnCount,
    /// The confirmed track rests on one measurement only (the run's first frame, confirmed at
    /// once by its quality or by agreeing cameras): the next measurement that fails its gate
    /// drops it.
    provisional: bool,
    /// The run's first frame was confirmed at once already (it happens once per run).
    first_confirmed: bool,
    /// A measurement contradicted the confirmed track's prediction since its last update: the
    /// prediction's turn count is in doubt until the track takes a measurement again.
    contradicted: bool,
}

impl RodFilter {
    /// A filter with no track yet.
    pub fn new(cfg: FilterConfig) -> RodFilter {
        RodFilter {
            cfg,
            main: None,
            candidate: None,
            turn_ref: None,
            last_t: None,
            rejection: None,
            turns: TurnCount::default(),
            provisional: false,
            first_confirmed: false,
            contradicted: false,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &FilterConfig {
        &self.cfg
    }

    /// Why the last row given to [`RodFilter::update`] was not accepted; `None` when it was.
    pub fn last_rejection(&self) -> Option<Rejection> {
        self.rejection
    }

    /// Whether a confirmed track exists (the rod is neither lost nor unseen).
    pub fn is_tracking(&self) -> bool {
        self.main.is_some()
    }

    /// Forgets everything.
    pub fn reset(&mut self) {
        *self = RodFilter::new(self.cfg);
    }

    fn obs(&self, m: &Measurement) -> Obs {
        let q = m.quality.clamp(self.cfg.min_quality.max(1e-3), 1.0);
        let sp = self.cfg.position_noise_mm / q;
        let sa = self.cfg.angle_noise_rad / q;
        Obs {
            t: m.timestamp_ns,
            position_mm: m.position_mm,
            angle_rad: m.angle_rad,
            r_pos: sp * sp,
            r_ang: sa * sa,
            quality: m.quality,
        }
    }

    fn predict(&self, tr: &Track, t: Timestamp) -> Track {
        let c = &self.cfg;
        self.predict_with(
            tr,
            t,
            c.jerk_std_mm_s3.powi(2),
            c.angular_jerk_std_rad_s3.powi(2),
        )
    }

    /// [`RodFilter::predict`] with the given process noise variances (0: the state's own
    /// uncertainty only).
    fn predict_with(&self, tr: &Track, t: Timestamp, q_pos: f64, q_ang: f64) -> Track {
        let dt = t.seconds_since(tr.t).max(0.0);
        let h = self.cfg.accel_horizon_s;
        Track {
            pos: tr.pos.predict(dt, q_pos, h),
            ang: tr.ang.predict(dt, q_ang, h),
            t,
            quality: tr.quality,
        }
    }

    /// Predicts `tr` to the observation's time and checks both gates.
    fn gate(&self, tr: &Track, o: &Obs) -> Gated {
        let pred = self.predict(tr, o.t);
        let tau = o.t.seconds_since(tr.t);
        let half_tau2 = 0.5 * tau * tau;
        let c = &self.cfg;
        let nu_pos = o.position_mm - pred.pos.x();
        let nu_ang = wrap_pi(o.angle_rad - pred.ang.x());
        let gate_pos = (c.gate_sigma * (pred.pos.var() + o.r_pos).sqrt()
            + c.max_accel_mm_s2 * half_tau2)
            .min(c.max_position_gate_mm);
        let gate_ang = (c.gate_sigma * (pred.ang.var() + o.r_ang).sqrt()
            + c.max_angular_accel_rad_s2 * half_tau2)
            .min(c.max_angle_gate_rad);
        let result = if nu_pos.abs() > gate_pos {
            Err(Rejection::PositionGate {
                innovation_mm: nu_pos,
                gate_mm: gate_pos,
            })
        } else if nu_ang.abs() > gate_ang {
            Err(Rejection::AngleGate {
                innovation_rad: nu_ang,
                gate_rad: gate_ang,
            })
        } else {
            Ok(())
        };
        Gated {
            pred,
            nu_pos,
            nu_ang,
            result,
        }
    }

    fn apply(g: &Gated, o: &Obs) -> Track {
        let mut tr = g.pred;
        tr.pos.update(g.nu_pos, o.r_pos);
        tr.ang.update(g.nu_ang, o.r_ang);
        tr.quality = o.quality;
        tr
    }

    /// Checks a row against the current track without changing anything: `Ok` when
    /// [`RodFilter::update`] would accept it into the confirmed track. Used by the fusion to
    /// decide between disagreeing cameras.
    pub fn check(&self, m: &Measurement) -> Result<(), Rejection> {
        let m = m.sanitized();
        if m.status != Status::Ok {
            return Err(Rejection::NotMeasured(m.status));
        }
        if m.quality < self.cfg.min_quality {
            return Err(Rejection::LowQuality(m.quality));
        }
        let tr = match (&self.main, self.last_t) {
            (Some(tr), Some(last)) if m.timestamp_ns >= last => tr,
            (Some(_), Some(last)) => {
                return Err(Rejection::Timestamp {
                    previous_s: last.as_secs_f64(),
                    got_s: m.timestamp_s(),
                })
            }
            _ => return Err(Rejection::Unconfirmed),
        };
        let o = self.obs(&m);
        if o.t.seconds_since(tr.t) > self.cfg.max_coast_s {
            return Err(Rejection::Unconfirmed);
        }
        self.gate(tr, &o).result
    }

    /// The filtered row for `m`'s frame. `m` is one camera's raw row or a fused row for the
    /// rod; the returned row keeps its frame, timestamp, camera and rod. Only the input's
    /// `position_mm`, `angle_rad`, `quality` and `status` are read: the turn count is the
    /// filter's own.
    pub fn update(&mut self, m: &Measurement) -> Measurement {
        self.update_corroborated(m, false)
    }

    /// [`RodFilter::update`] for a row that another measurement of the same frame corroborates
    /// (a fused row of cameras that agree): on the run's first frame such a row is confirmed
    /// at once (see [`FilterConfig::confirm_quality`]).
    pub fn update_corroborated(&mut self, m: &Measurement, corroborated: bool) -> Measurement {
        let m = m.sanitized();
        self.rejection = None;
        let t = m.timestamp_ns;
        if let Some(last) = self.last_t {
            if t <= last {
                // Out of order or repeated: change nothing, report the state at the last time.
                self.rejection = Some(Rejection::Timestamp {
                    previous_s: last.as_secs_f64(),
                    got_s: t.as_secs_f64(),
                });
                return self.coast_row(&m, last);
            }
        }
        self.last_t = Some(t);

        // Too long without an accepted measurement: lost.
        if let Some(tr) = self.main {
            if t.seconds_since(tr.t) > self.cfg.max_coast_s {
                self.turn_ref = Some(tr.ang.x());
                self.main = None;
                self.provisional = false;
                self.turns_lost();
            }
        }
        if let Some(c) = self.candidate {
            if t.seconds_since(c.track.t) > self.cfg.max_coast_s {
                self.candidate = None;
            }
        }

        if m.status != Status::Ok {
            self.rejection = Some(Rejection::NotMeasured(m.status));
            return self.coast_row(&m, t);
        }
        if m.quality < self.cfg.min_quality {
            self.rejection = Some(Rejection::LowQuality(m.quality));
            return self.coast_row(&m, t);
        }
        let o = self.obs(&m);

        if let Some(tr) = self.main {
            let g = self.gate(&tr, &o);
            match g.result {
                Ok(()) => {
                    self.turns_on_update(&tr, o.t);
                    let tr = Self::apply(&g, &o);
                    self.main = Some(tr);
                    self.candidate = None;
                    self.provisional = false;
                    self.contradicted = false;
                    return self.row(&m, &tr, Status::Ok, o.quality, self.turns.known);
                }
                Err(e) => {
                    self.rejection = Some(e);
                    self.contradicted = true;
                    if self.provisional {
                        // A first frame confirmed on its own is contradicted: start again.
                        self.main = None;
                        self.provisional = false;
                        self.turns.anchored = false;
                        self.turns.known = false;
                    }
                }
            }
        }

        // The main track could not take it: it goes to the candidate.
        let reference = match (&self.main, &self.candidate) {
            (Some(tr), _) => Some(self.predict(tr, t).ang.x()),
            (None, Some(c)) => Some(self.predict(&c.track, t).ang.x()),
            (None, None) => self.turn_ref,
        };
        let at_once = !self.first_confirmed
            && self.main.is_none()
            && self.candidate.is_none()
            && self.turn_ref.is_none()
            && (corroborated || self.cfg.confirm_quality.is_some_and(|q| o.quality >= q));
        if self.feed_candidate(&o, reference, at_once) {
            if let Some(c) = self.candidate {
                let replaces = self.may_replace_main(&c.track);
                if c.points >= self.cfg.override_points || replaces {
                    self.turns_on_promote(&c, !replaces);
                    self.candidate = None;
                    self.main = Some(c.track);
                    self.contradicted = false;
                    self.provisional = at_once && self.cfg.confirm_reacquisition;
                    self.first_confirmed |= at_once;
                    self.turns_apply_pending();
                    self.rejection = None;
                    let tr = self.main.unwrap_or(c.track);
                    return self.row(&m, &tr, Status::Ok, o.quality, self.turns.known);
                }
            }
        }
        if self.rejection.is_none() {
            self.rejection = Some(Rejection::Unconfirmed);
        }
        self.coast_row(&m, t)
    }

    /// Whether a confirmed candidate may take over. Always after loss; while the main track
    /// still coasts, only when the candidate lies within the main prediction's uncapped gate
    /// (its uncertainty plus the physical acceleration bound): a decoder that stays wrong by a
    /// stripe period for a few frames must not overrule a confident prediction.
    fn may_replace_main(&self, cand: &Track) -> bool {
        let Some(tr) = &self.main else {
            return true;
        };
        // The main track's own uncertainty plus the physical bound: the process noise is what
        // the bound replaces, with a hard limit.
        let p = self.predict_with(tr, cand.t, 0.0, 0.0);
        let tau = cand.t.seconds_since(tr.t);
        let half_tau2 = 0.5 * tau * tau;
        let c = &self.cfg;
        let d_pos = (cand.pos.x() - p.pos.x()).abs();
        let d_ang = wrap_pi(cand.ang.x() - p.ang.x()).abs();
        d_pos
            <= c.gate_sigma * (p.pos.var() + cand.pos.var()).sqrt() + c.max_accel_mm_s2 * half_tau2
            && d_ang
                <= c.gate_sigma * (p.ang.var() + cand.ang.var()).sqrt()
                    + c.max_angular_accel_rad_s2 * half_tau2
    }

    /// Gives a measurement to the candidate track; true when the candidate is confirmed
    /// (`at_once`: a new candidate is confirmed by its first measurement).
    fn feed_candidate(&mut self, o: &Obs, reference: Option<f64>, at_once: bool) -> bool {
        let c = &self.cfg;
        // A new track's acceleration prior: small, because the gate adds the physical bound
        // `max_accel tau^2 / 2` anyway; a wide prior would open the gate past a Gray step.
        let acc_var_pos = (0.1 * c.max_accel_mm_s2).powi(2);
        let acc_var_ang = (0.1 * c.max_angular_accel_rad_s2).powi(2);
        let start = |angle: f64| -> Candidate {
            let unwrapped = match reference {
                Some(r) => unwrap_near(angle, r),
                None => angle,
            };
            Candidate {
                track: Track {
                    pos: Axis::new(
                        [o.position_mm, 0.0, 0.0],
                        [o.r_pos, c.reacquire_velocity_std_mm_s.powi(2), acc_var_pos],
                    ),
                    ang: Axis::new(
                        [unwrapped, 0.0, 0.0],
                        [
                            o.r_ang,
                            c.reacquire_angular_velocity_std_rad_s.powi(2),
                            acc_var_ang,
                        ],
                    ),
                    t: o.t,
                    quality: o.quality,
                },
                points: 1,
                ambiguous: false,
            }
        };
        let Some(cand) = self.candidate else {
            self.candidate = Some(start(o.angle_rad));
            return !c.confirm_reacquisition || at_once;
        };
        let g = self.gate(&cand.track, o);
        if g.result.is_ok() {
            self.candidate = Some(Candidate {
                track: Self::apply(&g, o),
                points: cand.points + 1,
                ambiguous: cand.ambiguous,
            });
            return true;
        }
        if cand.points == 1 {
            // Two-point start: the rod moves; the velocity is the step over the frame gap.
            let dt = if o.t > cand.track.t {
                o.t.seconds_since(cand.track.t)
            } else {
                c.nominal_dt_s
            };
            let step_ang = wrap_pi(o.angle_rad - cand.track.ang.x());
            let v_pos = (o.position_mm - cand.track.pos.x()) / dt;
            let v_ang = step_ang / dt;
            if v_pos.abs() <= c.max_velocity_mm_s && v_ang.abs() <= c.max_angular_velocity_rad_s {
                // Value from the new point, rate from the difference (its covariance follows).
                let axis = |x: f64, v: f64, r: f64, prev_r: f64, acc_var: f64| Axis {
                    s: [x, v, 0.0],
                    p: [
                        [r, r / dt, 0.0],
                        [r / dt, (r + prev_r) / (dt * dt), 0.0],
                        [0.0, 0.0, acc_var],
                    ],
                };
                self.candidate = Some(Candidate {
                    track: Track {
                        pos: axis(
                            o.position_mm,
                            v_pos,
                            o.r_pos,
                            cand.track.pos.var(),
                            acc_var_pos,
                        ),
                        ang: axis(
                            cand.track.ang.x() + step_ang,
                            v_ang,
                            o.r_ang,
                            cand.track.ang.var(),
                            acc_var_ang,
                        ),
                        t: o.t,
                        quality: o.quality,
                    },
                    points: 2,
                    ambiguous: !self.step_unambiguous(dt),
                });
                return false;
            }
        }
        // Inconsistent with the candidate too: start again from this measurement.
        self.candidate = Some(start(o.angle_rad));
        !c.confirm_reacquisition
    }

    fn row(
        &self,
        m: &Measurement,
        tr: &Track,
        status: Status,
        quality: f64,
        turns_known: bool,
    ) -> Measurement {
        Measurement {
            frame: m.frame,
            timestamp_ns: m.timestamp_ns,
            camera: m.camera,
            rod: m.rod,
            position_mm: tr.pos.x(),
            angle_rad: wrap_2pi(tr.ang.x()),
            angle_unwrapped_rad: tr.ang.x(),
            velocity_mm_s: tr.pos.v(),
            angular_velocity_rad_s: tr.ang.v(),
            quality: quality.clamp(0.0, 1.0),
            status,
            turns_known,
        }
        .sanitized()
    }

    /// The row when no measurement was accepted at time `t`: the prediction, the candidate's
    /// estimate, or `lost`.
    fn coast_row(&self, m: &Measurement, t: Timestamp) -> Measurement {
        if let Some(tr) = &self.main {
            let p = self.predict(tr, t.max(tr.t));
            let fade = (1.0 - t.seconds_since(tr.t) / self.cfg.max_coast_s).clamp(0.0, 1.0);
            let known = self.turns.known && !self.contradicted && self.carried_exactly(tr, t);
            return self.row(m, &p, Status::Predicted, tr.quality * fade, known);
        }
        if let Some(c) = &self.candidate {
            let p = self.predict(&c.track, t.max(c.track.t));
            // Only the run's first track counts from its own first measurement.
            let known = !self.turns.anchored && !c.ambiguous && self.turns.pending_turns.is_none();
            return self.row(m, &p, Status::Predicted, 0.25 * c.track.quality, known);
        }
        Measurement::empty(m.frame, m.timestamp_ns, m.camera, m.rod, Status::Lost)
    }
}
