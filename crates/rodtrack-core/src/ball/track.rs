//! Following the ball over frames: a window around the prediction, the coarse scan when that
//! finds nothing, and a constant-velocity Kalman filter per axis for the velocity and for
//! short occlusions.

use super::detect::{BallDetector, Detection, Reach, ScanArea};
use super::tuning::{
    ACCEL_MM_S2, GATE_SIGMAS, MAX_SPEED_MM_S, MEAS_SIGMA_MIN_MM, PREDICTED_SCAN_BANDS, PREDICT_S,
};
use super::{BallRow, BallStatus};
use crate::calib::CameraCalibration;
use crate::{CameraId, CoreError, FrameView, Timestamp};

/// One axis of the constant-velocity filter.
#[derive(Debug, Clone, Copy, Default)]
struct Axis {
    p: f64,
    v: f64,
    cov: [[f64; 2]; 2],
}

impl Axis {
    fn start(p: f64, v: f64, var_p: f64, var_v: f64) -> Axis {
        Axis {
            p,
            v,
            cov: [[var_p, 0.0], [0.0, var_v]],
        }
    }

    fn predict(&mut self, dt: f64) {
        self.p += self.v * dt;
        let c = self.cov;
        let q = ACCEL_MM_S2 * ACCEL_MM_S2;
        let p00 = c[0][0] + dt * (c[0][1] + c[1][0]) + dt * dt * c[1][1] + q * dt.powi(4) / 4.0;
        let p01 = c[0][1] + dt * c[1][1] + q * dt.powi(3) / 2.0;
        let p11 = c[1][1] + q * dt * dt;
        self.cov = [[p00, p01], [p01, p11]];
    }

    /// Normalised squared innovation of `z` with measurement variance `r`.
    fn nis(&self, z: f64, r: f64) -> f64 {
        (z - self.p).powi(2) / (self.cov[0][0] + r)
    }

    fn update(&mut self, z: f64, r: f64) {
        let s = self.cov[0][0] + r;
        let k0 = self.cov[0][0] / s;
        let k1 = self.cov[1][0] / s;
        let e = z - self.p;
        self.p += k0 * e;
        self.v += k1 * e;
        let c = self.cov;
        self.cov = [
            [(1.0 - k0) * c[0][0], (1.0 - k0) * c[0][1]],
            [c[1][0] - k1 * c[0][0], c[1][1] - k1 * c[0][1]],
        ];
    }
}

/// A camera's ball tracker: one [`BallRow`] per frame.
///
/// ```no_run
/// # fn demo(cal: &rodtrack_core::calib::CameraCalibration, view: rodtrack_core::FrameView<'_>)
/// # -> Result<(), rodtrack_core::CoreError> {
/// if let Some(mut ball) = rodtrack_core::ball::BallTracker::new(cal)? {
///     let row = ball.process(&view, 0, rodtrack_core::Timestamp(0));
///     println!("{} {:.1} {:.1} {}", row.frame, row.x_mm, row.y_mm, row.status);
/// }
/// # Ok(()) }
/// ```
#[derive(Debug, Clone)]
pub struct BallTracker {
    det: BallDetector,
    camera: CameraId,
    axes: [Axis; 2],
    /// Time of the filter's state.
    state_ns: Option<Timestamp>,
    /// Time and position of the last detection.
    last: Option<(Timestamp, [f64; 2])>,
    /// The camera's systematic error in the table frame, mm (its table pose's fit).
    systematic_mm: f64,
    /// The measurement's standard deviation of the last detection, mm.
    meas_sigma_mm: f64,
    /// The standard deviation of the last row's position, mm (see [`BallTracker::row_sigma_mm`]).
    row_sigma_mm: f64,
    /// The last frame's ball was not seen.
    unseen: bool,
    /// The band of the coarse scan the next predicted frame searches.
    scan_band: usize,
}

impl BallTracker {
    /// The tracker of a camera's calibration; `None` when it has no `[cameras.ball]`.
    pub fn new(cal: &CameraCalibration) -> Result<Option<BallTracker>, CoreError> {
        Ok(BallDetector::new(cal)?.map(|det| {
            let systematic_mm = cal
                .table
                .as_ref()
                .zip(det.mm_per_px_at_centre())
                .map(|(t, mm_per_px)| systematic_sigma_mm(t.residual_rms_px, t.points, mm_per_px))
                .unwrap_or(0.0);
            BallTracker {
                det,
                camera: CameraId::Camera(cal.index),
                axes: [Axis::default(); 2],
                state_ns: None,
                last: None,
                systematic_mm,
                meas_sigma_mm: 0.0,
                row_sigma_mm: f64::INFINITY,
                unseen: false,
                scan_band: 0,
            }
        }))
    }

    /// The standard deviation of the position of the row the last [`BallTracker::process`] or
    /// [`BallTracker::missed`] returned, per axis, mm: the detection's (its edge rays'
    /// residual over the root of their count) or the prediction's (the filter's variance),
    /// with the camera's systematic error in the table frame added in quadrature; infinite
    /// for a `lost` row. What fusing several cameras weighs them by.
    pub fn row_sigma_mm(&self) -> f64 {
        self.row_sigma_mm
    }

    /// The camera's systematic error in the table frame, mm (see [`systematic_sigma_mm`]).
    pub fn systematic_sigma_mm(&self) -> f64 {
        self.systematic_mm
    }

    /// The detector (its camera in the table frame, its coarse step).
    pub fn detector(&self) -> &BallDetector {
        &self.det
    }

    /// Tracks the ball in one frame.
    pub fn process(&mut self, view: &FrameView, frame: u64, timestamp_ns: Timestamp) -> BallRow {
        self.advance(timestamp_ns);
        let around = self.state_ns.and_then(|_| {
            self.det
                .camera()
                .project([self.axes[0].p, self.axes[1].p, self.det.radius_mm()])
        });
        // A ball the window misses is searched where it can have gone since it was last seen,
        // at the fastest shot's speed (a kick may have sent it beyond the window); while it
        // stays unseen and predicted, there or band by band, whichever is smaller.
        let area = match around {
            Some(_) => ScanArea {
                band: self.unseen.then(|| {
                    let k = self.scan_band;
                    self.scan_band = (k + 1) % PREDICTED_SCAN_BANDS;
                    (k, PREDICTED_SCAN_BANDS)
                }),
                reach: self.last.map(|(t0, p0)| Reach {
                    centre_mm: p0,
                    radius_mm: MAX_SPEED_MM_S * timestamp_ns.seconds_since(t0).max(0.0)
                        + self.det.radius_mm(),
                }),
            },
            None => ScanArea::default(),
        };
        let det = self.det.detect_in_area(view, around, area);
        self.unseen = det.is_none();
        if let Some(d) = &det {
            self.update(d, timestamp_ns);
        }
        self.row(det.as_ref(), frame, timestamp_ns)
    }

    /// The row of a frame that could not be read or used (a bad frame): the prediction while
    /// it is trusted, else `lost`. Every frame of the camera gets a row.
    pub fn missed(&mut self, frame: u64, timestamp_ns: Timestamp) -> BallRow {
        self.advance(timestamp_ns);
        self.row(None, frame, timestamp_ns)
    }

    /// Drops a track not seen for longer than the prediction is trusted, and predicts the
    /// state to `timestamp_ns`.
    fn advance(&mut self, timestamp_ns: Timestamp) {
        let live = self
            .last
            .is_some_and(|(t, _)| timestamp_ns.seconds_since(t) <= PREDICT_S);
        if !live {
            self.state_ns = None;
            self.last = None;
        }
        if let Some(t) = self.state_ns {
            let dt = timestamp_ns.seconds_since(t).max(0.0);
            for a in &mut self.axes {
                a.predict(dt);
            }
            self.state_ns = Some(timestamp_ns);
        }
    }

    /// The row for a frame: the detection (`ok`), else the prediction (`predicted`), else
    /// `lost`.
    fn row(&mut self, det: Option<&Detection>, frame: u64, timestamp_ns: Timestamp) -> BallRow {
        let mut row = BallRow::lost(frame, timestamp_ns, self.camera);
        if det.is_some() || self.state_ns.is_some() {
            row.vx_mm_s = self.axes[0].v;
            row.vy_mm_s = self.axes[1].v;
        }
        match det {
            Some(d) => {
                row.x_mm = d.x_mm;
                row.y_mm = d.y_mm;
                row.quality = d.seen_fraction.clamp(0.0, 1.0);
                row.status = BallStatus::Ok;
                self.row_sigma_mm = self.meas_sigma_mm.hypot(self.systematic_mm);
            }
            None if self.state_ns.is_some() => {
                row.x_mm = self.axes[0].p;
                row.y_mm = self.axes[1].p;
                row.status = BallStatus::Predicted;
                let var = 0.5 * (self.axes[0].cov[0][0] + self.axes[1].cov[0][0]);
                self.row_sigma_mm = var.max(0.0).sqrt().hypot(self.systematic_mm);
            }
            None => self.row_sigma_mm = f64::INFINITY,
        }
        let row = row.sanitized();
        if row.status == BallStatus::Lost || !self.row_sigma_mm.is_finite() {
            self.row_sigma_mm = f64::INFINITY;
        }
        row
    }

    fn update(&mut self, d: &Detection, t: Timestamp) {
        let sigma = (d.residual_mm / (d.edge_points as f64).sqrt()).max(MEAS_SIGMA_MIN_MM);
        self.meas_sigma_mm = sigma;
        let r = sigma * sigma;
        let z = [d.x_mm, d.y_mm];
        let gated = self.state_ns.is_some()
            && self
                .axes
                .iter()
                .zip(z)
                .all(|(a, z)| a.nis(z, r) <= GATE_SIGMAS * GATE_SIGMAS);
        if gated {
            for (a, z) in self.axes.iter_mut().zip(z) {
                a.update(z, r);
            }
        } else {
            // First sight, or a kick / bounce: restart with the velocity between the last
            // detection and this one (the difference of two positions of variance `r` each,
            // over `dt`), or, at first sight, unknown up to the fastest shot.
            let (v, var_v) = match self.last {
                Some((t0, p0)) if t.seconds_since(t0) > 0.0 => {
                    let dt = t.seconds_since(t0);
                    (
                        [(z[0] - p0[0]) / dt, (z[1] - p0[1]) / dt],
                        2.0 * r / (dt * dt),
                    )
                }
                _ => ([0.0, 0.0], MAX_SPEED_MM_S * MAX_SPEED_MM_S),
            };
            for k in 0..2 {
                self.axes[k] = Axis::start(z[k], v[k], r, var_v);
            }
        }
        self.state_ns = Some(t);
        self.last = Some((t, z));
    }
}

/// A camera's systematic error in the table frame, mm: the RMS reprojection error of its
/// table points, corrected for the degrees of freedom the pose took (`2n` coordinates, 6
/// pose parameters: the residual underestimates the error by `sqrt(2n / (2n - 6))`), at the
/// image's scale `mm_per_px`. With 3 points or fewer it is unknown: one pixel's worth.
///
/// ```
/// use rodtrack_core::ball::track::systematic_sigma_mm;
/// assert!((systematic_sigma_mm(0.5, 4, 0.8) - 0.8).abs() < 1e-12);
/// assert!((systematic_sigma_mm(0.0, 3, 0.8) - 0.8).abs() < 1e-12);
/// ```
pub fn systematic_sigma_mm(residual_rms_px: f64, points: usize, mm_per_px: f64) -> f64 {
    let n2 = 2.0 * points as f64;
    let px = if points > 3 && residual_rms_px.is_finite() {
        residual_rms_px * (n2 / (n2 - 6.0)).sqrt()
    } else {
        1.0
    };
    (px * mm_per_px).max(0.0)
}
