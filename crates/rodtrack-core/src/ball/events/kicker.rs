//! The shot's rod: the rods' measured angles give each rod's angular velocity; a rod swinging
//! when the ball was kicked, within a swinging foot's reach of the ball, kicked it.
//!
//! A figure's foot turns at `omega` about its axis, its toe about the axes' height
//! ([`EventConfig::rod_axis_height_mm`]) from it: the toe's speed is `omega * height`. A foot
//! far heavier than the ball sends it off at up to twice the foot's speed, so a kick of the
//! least shot speed needs `omega >= shot_min_speed_mm_s / (2 * rod_axis_height_mm)` (9.4
//! rad/s on the reference table). Among the rods within
//! [`EventConfig::rod_swing_reach_mm`] of the ball's last position before the jump (plus the
//! distance the shot covers between that row and the jump's: the kick happened between them)
//! whose
//! angular speed reached that in the kick's window (from [`EventConfig::shot_before_min_s`]
//! before that position to the jump's row), the fastest kicked. With none (no rod measured,
//! or none swinging: a ball struck by a still figure), the rod whose axis is nearest the ball
//! within [`EventConfig::rod_reach_mm`].

use super::{EventConfig, TableGeometry};
use crate::Timestamp;

/// Angular velocities kept per rod (0.32 s at 200 fps, more than the kick's window).
const RATES: usize = 64;

/// A pause longer than this between two angles of a rod gives no angular velocity, s.
const MAX_GAP_S: f64 = 0.05;

#[derive(Debug, Clone)]
struct RodRate {
    rod: u32,
    x_mm: f64,
    last: Option<(Timestamp, f64)>,
    /// `(mid time, angular velocity rad/s)`.
    rates: [(Timestamp, f64); RATES],
    len: usize,
    next: usize,
}

/// Each rod's recent angular velocities (no allocation after [`RodSwings::new`]).
#[derive(Debug, Clone)]
pub(super) struct RodSwings {
    rods: Vec<RodRate>,
}

impl RodSwings {
    pub(super) fn new(geom: &TableGeometry) -> RodSwings {
        RodSwings {
            rods: geom
                .rods
                .iter()
                .map(|&(rod, x_mm)| RodRate {
                    rod,
                    x_mm,
                    last: None,
                    rates: [(Timestamp(0), 0.0); RATES],
                    len: 0,
                    next: 0,
                })
                .collect(),
        }
    }

    /// Rod `rod`'s measured angle at `t` (any camera; a second angle at the same time, from
    /// another camera, and one older than the last, are ignored; rods not in the table too).
    pub(super) fn push(&mut self, rod: u32, t: Timestamp, angle_rad: f64) {
        if !angle_rad.is_finite() {
            return;
        }
        let Some(r) = self.rods.iter_mut().find(|r| r.rod == rod) else {
            return;
        };
        if let Some((t0, a0)) = r.last {
            let dt = t.seconds_since(t0);
            if dt <= 0.0 {
                return;
            }
            if dt <= MAX_GAP_S {
                // The shortest turn between the two angles.
                let d = (angle_rad - a0 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                let mid = Timestamp(t0.0 + (t.0 - t0.0) / 2);
                r.rates[r.next] = (mid, d / dt);
                r.next = (r.next + 1) % RATES;
                r.len = (r.len + 1).min(RATES);
            }
        }
        r.last = Some((t, angle_rad));
    }

    /// The kicking rod of a shot of `speed_mm_s` from `x_mm` (the ball's last position before
    /// the jump, at `start`) whose jump row is at `jump` (see the module's documentation).
    pub(super) fn kicker(
        &self,
        geom: &TableGeometry,
        cfg: &EventConfig,
        x_mm: f64,
        speed_mm_s: f64,
        (start, jump): (Timestamp, Timestamp),
    ) -> Option<u32> {
        let min_rate = cfg.shot_min_speed_mm_s / (2.0 * cfg.rod_axis_height_mm.max(1.0));
        let from_s = -cfg.shot_before_min_s;
        // The kick happened between the two rows: the ball then lay within the distance the
        // shot covers in that time of the last row before the jump (which may already be
        // kicked, its velocity not yet restarted).
        let slack_mm = speed_mm_s.max(0.0) * jump.seconds_since(start).max(0.0);
        let reach_mm = cfg.rod_swing_reach_mm + slack_mm;
        let swinging = self
            .rods
            .iter()
            .filter(|r| (r.x_mm - x_mm).abs() <= reach_mm)
            .filter_map(|r| {
                let peak = (0..r.len)
                    .map(|i| r.rates[i])
                    .filter(|(t, _)| t.seconds_since(start) >= from_s && *t <= jump)
                    .map(|(_, w)| w.abs())
                    .fold(0.0f64, f64::max);
                (peak >= min_rate).then_some((r.rod, peak))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match swinging {
            Some((rod, _)) => Some(rod),
            None => geom.nearest_rod(x_mm, cfg.rod_reach_mm),
        }
    }
}
