//! One constant-acceleration Kalman axis (value, rate, acceleration) and a track of two.

use crate::time::Timestamp;

/// One constant-acceleration Kalman axis: value, rate, acceleration and their covariance.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Axis {
    pub(super) s: [f64; 3],
    pub(super) p: [[f64; 3]; 3],
}

// 3x3 matrix algebra reads best with explicit indices.
#[allow(clippy::needless_range_loop)]
impl Axis {
    /// A state with independent variances.
    pub(super) fn new(s: [f64; 3], var: [f64; 3]) -> Axis {
        Axis {
            s,
            p: [[var[0], 0.0, 0.0], [0.0, var[1], 0.0], [0.0, 0.0, var[2]]],
        }
    }

    pub(super) fn x(&self) -> f64 {
        self.s[0]
    }

    pub(super) fn v(&self) -> f64 {
        self.s[1]
    }

    /// Variance of the value.
    pub(super) fn var(&self) -> f64 {
        self.p[0][0]
    }

    /// The state `dt` later, with a jerk of variance `q` held over `dt`. The acceleration acts
    /// for at most `horizon` (then the rate holds): extrapolating a noisy acceleration through a
    /// long occlusion would do more harm than good.
    pub(super) fn predict(&self, dt: f64, q: f64, horizon: f64) -> Axis {
        let h = dt.min(horizon);
        let f = [
            [1.0, dt, h * dt - 0.5 * h * h],
            [0.0, 1.0, h],
            [0.0, 0.0, 1.0],
        ];
        let half = 0.5 * dt * dt;
        let g = [half * dt / 3.0, half, dt];
        let mut out = Axis::default();
        for i in 0..3 {
            out.s[i] = (0..3).map(|k| f[i][k] * self.s[k]).sum();
        }
        // F P
        let mut fp = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                fp[i][j] = (0..3).map(|k| f[i][k] * self.p[k][j]).sum();
            }
        }
        // F P F^T + q g g^T
        for i in 0..3 {
            for j in 0..3 {
                out.p[i][j] = (0..3).map(|k| fp[i][k] * f[j][k]).sum::<f64>() + q * g[i] * g[j];
            }
        }
        out
    }

    /// Kalman update of the value with innovation `nu` and measurement variance `r`.
    pub(super) fn update(&mut self, nu: f64, r: f64) {
        let s = self.p[0][0] + r;
        let k = [self.p[0][0] / s, self.p[1][0] / s, self.p[2][0] / s];
        let row = self.p[0];
        for i in 0..3 {
            self.s[i] += k[i] * nu;
            for j in 0..3 {
                self.p[i][j] -= k[i] * row[j];
            }
        }
    }
}

/// A track: both axes at the time of their last update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Track {
    pub(super) pos: Axis,
    pub(super) ang: Axis,
    pub(super) t: Timestamp,
    pub(super) quality: f64,
}
