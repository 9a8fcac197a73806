//! The turn count's honesty: when the count of whole turns is known, when it stops being
//! known, and how it is re-anchored (see the module documentation of [`super`], "Whether the
//! turn count is known").

use super::axis::Track;
use super::{Candidate, RodFilter};
use crate::angle::wrap_2pi;
use crate::time::Timestamp;
use std::f64::consts::{PI, TAU};

/// The turn count's state of one rod's filter.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct TurnCount {
    /// The confirmed track's count is exact since its anchor.
    pub(super) known: bool,
    /// The run's first track was confirmed (its first measurement is the count's origin).
    pub(super) anchored: bool,
    /// Consecutive unambiguous updates while the count is unknown.
    pub(super) steady: u32,
    /// A count given by the user for the next confirmed track (no track when it was given).
    pub(super) pending_turns: Option<i64>,
    /// The counters.
    pub(super) stats: TurnStats,
}

/// How often a rod's turn count became unknown and was re-anchored.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TurnStats {
    /// Times the count became unknown (a stretch in which it could have slipped).
    pub unknown_stretches: u64,
    /// Times the filter re-anchored an unknown count by itself (steady tracking).
    pub auto_reanchors: u64,
    /// Times the count was set by [`RodFilter::reanchor_turns`].
    pub user_reanchors: u64,
}

impl TurnStats {
    /// Adds another rod's counters.
    pub fn add(&mut self, o: &TurnStats) {
        self.unknown_stretches += o.unknown_stretches;
        self.auto_reanchors += o.auto_reanchors;
        self.user_reanchors += o.user_reanchors;
    }
}

impl RodFilter {
    /// The half-width of the angles the rod may have reached at time `t` since `tr` (its
    /// state's uncertainty plus the physical acceleration bound), rad: the count carried
    /// across the gap is exact only while this stays below half a turn.
    fn angle_spread(&self, tr: &Track, t: Timestamp) -> f64 {
        let p = self.predict_with(tr, t, 0.0, 0.0);
        let tau = t.seconds_since(tr.t).max(0.0);
        self.cfg.gate_sigma * p.ang.var().max(0.0).sqrt()
            + 0.5 * self.cfg.max_angular_accel_rad_s2 * tau * tau
    }

    /// Whether the count carried from `tr` to time `t` is exact.
    pub(super) fn carried_exactly(&self, tr: &Track, t: Timestamp) -> bool {
        self.angle_spread(tr, t) < PI
    }

    /// Whether a step of `dt_s` between two measurements is unambiguous at the physical speed
    /// bound: `max_angular_velocity * dt < pi`.
    pub(super) fn step_unambiguous(&self, dt_s: f64) -> bool {
        self.cfg.max_angular_velocity_rad_s * dt_s < PI
    }

    /// The count may have slipped from here on.
    pub(super) fn turns_lost(&mut self) {
        if self.turns.known {
            self.turns.stats.unknown_stretches += 1;
        }
        self.turns.known = false;
        self.turns.steady = 0;
    }

    /// The confirmed track `prev` took a measurement at time `t`.
    pub(super) fn turns_on_update(&mut self, prev: &Track, t: Timestamp) {
        if self.turns.known {
            if !self.carried_exactly(prev, t) {
                self.turns_lost();
            }
            return;
        }
        if self.step_unambiguous(t.seconds_since(prev.t)) {
            self.turns.steady += 1;
            if self.turns.steady >= self.cfg.reanchor_frames {
                self.turns.known = true;
                self.turns.steady = 0;
                self.turns.stats.auto_reanchors += 1;
            }
        } else {
            self.turns.steady = 0;
        }
    }

    /// The candidate `cand` becomes the confirmed track (`self.main` is still the old one);
    /// `overrode`: it took over against the old track's prediction.
    pub(super) fn turns_on_promote(&mut self, cand: &Candidate, overrode: bool) {
        if !self.turns.anchored {
            // The run's first track: its first measurement is the origin of the count.
            self.turns.anchored = true;
            self.turns.known = true;
            self.turns.steady = 0;
            if cand.ambiguous {
                self.turns_lost();
            }
            return;
        }
        let exact = match &self.main {
            Some(old) => {
                self.turns.known
                    && !overrode
                    && !cand.ambiguous
                    && self.carried_exactly(old, cand.track.t)
                    && self.velocity_continues(old, &cand.track)
            }
            // After `lost`: the count was continued from the last value, not measured.
            None => false,
        };
        if !exact {
            self.turns_lost();
        }
    }

    /// Whether the new track's angular velocity is one the old track could have reached
    /// within the physical acceleration bound.
    fn velocity_continues(&self, old: &Track, new: &Track) -> bool {
        let p = self.predict_with(old, new.t, 0.0, 0.0);
        let tau = new.t.seconds_since(old.t).max(0.0);
        let dv = (new.ang.v() - p.ang.v()).abs();
        dv <= self.cfg.gate_sigma * (p.ang.p[1][1] + new.ang.p[1][1]).max(0.0).sqrt()
            + self.cfg.max_angular_accel_rad_s2 * tau
    }

    /// Applies a count given by the user while no track existed, once a track is confirmed.
    pub(super) fn turns_apply_pending(&mut self) {
        if let Some(turns) = self.turns.pending_turns.take() {
            if let Some(tr) = self.main.as_mut() {
                set_turns(tr, turns);
                self.turns.known = true;
                self.turns.steady = 0;
                self.turns.stats.user_reanchors += 1;
            } else {
                self.turns.pending_turns = Some(turns);
            }
        }
    }

    /// Re-anchors the turn count by hand: from now on the rod is at whole turn `turns`, that is
    /// `angle_unwrapped_rad = 2 pi turns + angle_rad`, and the count is known. Use it after the
    /// count became unknown (a gap, a spin faster than the frame rate follows) when the rod's
    /// true turn is known, for example at a mechanical reference. Without a track (the rod is
    /// lost or not seen yet) the count applies to the next confirmed track.
    pub fn reanchor_turns(&mut self, turns: i64) {
        self.turns.pending_turns = Some(turns);
        if self.main.is_some() {
            self.turns_apply_pending();
            if let Some(c) = self.candidate.as_mut() {
                set_turns(&mut c.track, turns);
            }
        } else {
            self.turn_ref = Some(TAU * turns as f64 + PI);
        }
    }

    /// Whether the confirmed track's turn count is known (see [`Measurement::turns_known`]).
    ///
    /// [`Measurement::turns_known`]: crate::Measurement::turns_known
    pub fn turns_known(&self) -> bool {
        self.main.is_some() && self.turns.known
    }

    /// How often the count became unknown and was re-anchored.
    pub fn turn_stats(&self) -> TurnStats {
        self.turns.stats
    }
}

/// Moves a track by whole turns so that its angle lies in turn `turns`.
fn set_turns(tr: &mut Track, turns: i64) {
    let x = tr.ang.x();
    tr.ang.s[0] = TAU * turns as f64 + wrap_2pi(x);
}
