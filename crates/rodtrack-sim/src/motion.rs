//! One axis of motion over time: a base value plus trapezoidal moves plus spins, evaluated
//! analytically (value and derivative) at any time.

use serde::{Deserialize, Serialize};

/// A point-to-point move with a trapezoidal velocity profile (constant acceleration, cruise,
/// constant deceleration), as a motion controller plans it. It adds `delta` to the track,
/// starting at `t0_s`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Move {
    /// Start time, s.
    pub t0_s: f64,
    /// Signed distance, units of the track (mm or rad).
    pub delta: f64,
    /// Cruise speed, units/s (> 0).
    pub v_max: f64,
    /// Acceleration and deceleration, units/s^2 (> 0).
    pub a_max: f64,
}

impl Move {
    /// (acceleration time, cruise time, peak speed).
    fn phases(&self) -> (f64, f64, f64) {
        let d = self.delta.abs();
        let v = self.v_max.max(1e-9);
        let a = self.a_max.max(1e-9);
        if d * a >= v * v {
            let ta = v / a;
            (ta, (d - v * ta) / v, v)
        } else {
            let ta = (d / a).sqrt();
            (ta, 0.0, a * ta)
        }
    }

    /// How long the move takes, s.
    pub fn duration_s(&self) -> f64 {
        let (ta, tc, _) = self.phases();
        2.0 * ta + tc
    }

    /// (distance covered, speed) at time `t_s` (both with the move's sign).
    pub fn eval(&self, t_s: f64) -> (f64, f64) {
        let tau = t_s - self.t0_s;
        if tau <= 0.0 || self.delta == 0.0 {
            return (0.0, 0.0);
        }
        let (ta, tc, vp) = self.phases();
        let a = vp / ta.max(1e-12);
        let sign = self.delta.signum();
        let (s, v) = if tau < ta {
            (0.5 * a * tau * tau, a * tau)
        } else if tau < ta + tc {
            (0.5 * a * ta * ta + vp * (tau - ta), vp)
        } else if tau < 2.0 * ta + tc {
            let r = 2.0 * ta + tc - tau;
            (self.delta.abs() - 0.5 * a * r * r, a * r)
        } else {
            (self.delta.abs(), 0.0)
        };
        (sign * s, sign * v)
    }
}

/// A constant-rate rotation (or slide) that ramps up linearly from rest.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spin {
    /// Start time, s.
    pub t0_s: f64,
    /// Final rate, units/s.
    pub rate: f64,
    /// Time to reach the rate from 0, s.
    pub ramp_s: f64,
}

impl Spin {
    /// (distance, speed) at time `t_s`.
    pub fn eval(&self, t_s: f64) -> (f64, f64) {
        let tau = t_s - self.t0_s;
        if tau <= 0.0 {
            return (0.0, 0.0);
        }
        if self.ramp_s > 0.0 && tau < self.ramp_s {
            let v = self.rate * tau / self.ramp_s;
            (0.5 * v * tau, v)
        } else {
            (self.rate * (tau - 0.5 * self.ramp_s.max(0.0)), self.rate)
        }
    }
}

/// One axis over time: `base + sum(moves) + sum(spins)`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Track {
    /// Value before anything moves.
    pub base: f64,
    /// Trapezoidal moves (may overlap: they add).
    pub moves: Vec<Move>,
    /// Constant-rate components.
    pub spins: Vec<Spin>,
}

impl Track {
    /// A constant track.
    pub fn constant(v: f64) -> Track {
        Track {
            base: v,
            ..Track::default()
        }
    }

    /// Value at `t_s`.
    pub fn value(&self, t_s: f64) -> f64 {
        self.eval(t_s).0
    }

    /// Derivative at `t_s`.
    pub fn rate(&self, t_s: f64) -> f64 {
        self.eval(t_s).1
    }

    /// (value, derivative) at `t_s`.
    pub fn eval(&self, t_s: f64) -> (f64, f64) {
        let mut v = self.base;
        let mut d = 0.0;
        for m in &self.moves {
            if t_s > m.t0_s {
                let (a, b) = m.eval(t_s);
                v += a;
                d += b;
            }
        }
        for s in &self.spins {
            let (a, b) = s.eval(t_s);
            v += a;
            d += b;
        }
        (v, d)
    }

    /// Largest absolute rate over `[t0, t1]`, sampled (for motion-blur bounds).
    pub fn max_rate(&self, t0_s: f64, t1_s: f64) -> f64 {
        (0..=4)
            .map(|i| self.rate(t0_s + (t1_s - t0_s) * i as f64 / 4.0).abs())
            .fold(0.0, f64::max)
    }
}

/// Builds a [`Track`] as a sequence of moves and holds, keeping the current time and target.
#[derive(Debug, Clone)]
pub struct TrackBuilder {
    track: Track,
    /// Current time, s (end of the last move or hold).
    pub t_s: f64,
    /// Current target value (the value once all moves so far have finished).
    pub value: f64,
}

impl TrackBuilder {
    /// Starts at `value` at time 0.
    pub fn new(value: f64) -> Self {
        TrackBuilder {
            track: Track::constant(value),
            t_s: 0.0,
            value,
        }
    }
    /// Waits `dt_s`.
    pub fn hold(&mut self, dt_s: f64) -> &mut Self {
        self.t_s += dt_s.max(0.0);
        self
    }
    /// Moves to `target` now; time advances by the move's duration.
    pub fn move_to(&mut self, target: f64, v_max: f64, a_max: f64) -> &mut Self {
        let m = Move {
            t0_s: self.t_s,
            delta: target - self.value,
            v_max,
            a_max,
        };
        if m.delta != 0.0 {
            self.t_s += m.duration_s();
            self.track.moves.push(m);
        }
        self.value = target;
        self
    }
    /// Adds a spin starting now (does not advance time; `value` no longer tracks the end).
    pub fn spin(&mut self, rate: f64, ramp_s: f64) -> &mut Self {
        self.track.spins.push(Spin {
            t0_s: self.t_s,
            rate,
            ramp_s,
        });
        self
    }
    /// The finished track.
    pub fn build(&self) -> Track {
        self.track.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_reaches_target_with_continuous_speed() {
        for (d, v, a) in [
            (100.0, 300.0, 3000.0),
            (5.0, 300.0, 3000.0),
            (-40.0, 100.0, 500.0),
        ] {
            let m = Move {
                t0_s: 1.0,
                delta: d,
                v_max: v,
                a_max: a,
            };
            let end = 1.0 + m.duration_s();
            assert!((m.eval(end + 0.1).0 - d).abs() < 1e-9);
            assert_eq!(m.eval(0.5), (0.0, 0.0));
            // Numerical derivative matches the analytic one.
            for i in 1..20 {
                let t = 1.0 + m.duration_s() * i as f64 / 20.0;
                let h = 1e-6;
                let num = (m.eval(t + h).0 - m.eval(t - h).0) / (2.0 * h);
                assert!(
                    (num - m.eval(t).1).abs() < 1e-3 * v,
                    "{num} {:?}",
                    m.eval(t)
                );
                assert!(m.eval(t).1.abs() <= v + 1e-9);
            }
        }
    }

    #[test]
    fn spin_ramps_then_runs() {
        let s = Spin {
            t0_s: 0.0,
            rate: 10.0,
            ramp_s: 1.0,
        };
        assert!((s.eval(0.5).1 - 5.0).abs() < 1e-12);
        assert!((s.eval(3.0).0 - 25.0).abs() < 1e-12);
    }
}
