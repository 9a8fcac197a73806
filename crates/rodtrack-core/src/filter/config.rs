//! [`FilterConfig`]: the temporal filter's tuning, and [`Rejection`]: why a measurement was not taken.

#[cfg(doc)]
use super::RodFilter;
use crate::measurement::Status;

/// Tuning of a [`RodFilter`]. All rates come from the measurement timestamps, not from a fixed
/// frame rate; `nominal_dt_s` is only used when a frame's time step is not usable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterConfig {
    /// Measurement noise std of the position at quality 1, mm. Default 0.1: enhanced mode
    /// measures 0.02 mm on the simulator; give 0.3 for paper mode (0.28 mm).
    pub position_noise_mm: f64,
    /// Measurement noise std of the angle at quality 1, rad. Default 0.004: enhanced mode
    /// measures 0.002 rad; give 0.013 for paper mode (the paper's figure).
    pub angle_noise_rad: f64,
    /// Process noise: std of the jerk (rate of change of the acceleration) the model follows,
    /// mm/s^3. Default 2e6: a hand shot at 100 m/s^2 and 6 Hz changes its acceleration at
    /// about 4e6 mm/s^3; the model tracks such motion with almost no lag.
    pub jerk_std_mm_s3: f64,
    /// Process noise: std of the angular jerk, rad/s^3. Default 1e5 (a spin at 3000 rad/s^2
    /// and 5 Hz has 1e5 rad/s^3).
    pub angular_jerk_std_rad_s3: f64,
    /// Longest time an estimated acceleration is extrapolated, s; the rate holds after it.
    /// Default 0.005 (1 frame at 200 fps): through an occlusion the prediction continues at
    /// constant speed, since the acceleration estimate is noisy and the gate's physical bound
    /// covers what the rod may do meanwhile.
    pub accel_horizon_s: f64,
    /// Physical bound of the linear acceleration, mm/s^2: widens the gate by
    /// `max_accel tau^2 / 2`. Default 100 000 (100 m/s^2, a hard hand shot).
    pub max_accel_mm_s2: f64,
    /// Physical bound of the angular acceleration, rad/s^2. Default 3000 (a hand spin reaching
    /// 3000 rpm in 0.1 s).
    pub max_angular_accel_rad_s2: f64,
    /// Statistical part of the gate, in stds of the innovation. Default 4.
    pub gate_sigma: f64,
    /// Cap of the position gate, mm. Default 3.5: below one barcode cell (4 mm, the size of a
    /// wrong correlation peak) by 5 noise stds.
    pub max_position_gate_mm: f64,
    /// Cap of the angle gate, rad. Default 0.15: below one Gray step (2 pi / 32 = 0.196) and a
    /// stripe period (pi / 4) by more than 3 noise stds.
    pub max_angle_gate_rad: f64,
    /// Measurements with a lower quality are not used. Default 0.2.
    pub min_quality: f64,
    /// Longest coast on the prediction before the rod is `lost`, s. Default 0.1 (20 frames at
    /// 200 fps): the angle prediction is then still far inside half a turn for spins at
    /// constant speed, while a hand that covers the rod longer may have turned it freely.
    pub max_coast_s: f64,
    /// Velocity prior std of a new candidate track (first frame after loss), mm/s. Default 100:
    /// a still rod's second frame confirms at once; a faster one takes a two-point start.
    pub reacquire_velocity_std_mm_s: f64,
    /// Angular velocity prior std of a new candidate track, rad/s. Default 4.
    pub reacquire_angular_velocity_std_rad_s: f64,
    /// Largest speed a two-point start accepts, mm/s. Default 6000.
    pub max_velocity_mm_s: f64,
    /// Largest angular speed a two-point start accepts, rad/s (it is also limited by
    /// `pi / dt`). Default 600 (5730 rpm).
    pub max_angular_velocity_rad_s: f64,
    /// Measurements that agree among themselves but not with a coasting track replace it after
    /// this many frames, even when the track's prediction is confident. Default 4 (20 ms at
    /// 200 fps): a decoder that stays wrong by the same amount for 4 frames wins, a track that
    /// diverged is replaced after 4 frames.
    pub override_points: u32,
    /// Require one confirming measurement before a new track reports `ok`. Default true.
    pub confirm_reacquisition: bool,
    /// The run's first measurement of a rod is confirmed at once (`ok` on the first frame)
    /// when another camera agrees with it (a fused row of cameras that agree, see
    /// [`RodFilter::update_corroborated`]) or, when this is set, when its quality is at least
    /// this. The track then rests on that one frame: the next measurement that disagrees drops
    /// it and a new track is confirmed as after a loss. Default `None`: quality alone does not
    /// confirm (a single frame wrong by a stripe or a Gray step can carry a high quality).
    pub confirm_quality: Option<f64>,
    /// An unknown turn count is re-anchored after this many consecutive accepted frames, each
    /// within `pi / max_angular_velocity_rad_s` of the previous one (so that no step can be
    /// a whole turn off at the speed bound). Default 4 (20 ms at 200 fps).
    pub reanchor_frames: u32,
    /// Time step used when a frame's timestamp does not advance, s. Default 0.005 (200 fps).
    pub nominal_dt_s: f64,
}

impl Default for FilterConfig {
    fn default() -> Self {
        FilterConfig {
            position_noise_mm: 0.1,
            angle_noise_rad: 0.004,
            jerk_std_mm_s3: 2e6,
            angular_jerk_std_rad_s3: 1e5,
            accel_horizon_s: 0.005,
            max_accel_mm_s2: 100_000.0,
            max_angular_accel_rad_s2: 3000.0,
            gate_sigma: 4.0,
            max_position_gate_mm: 3.5,
            max_angle_gate_rad: 0.15,
            min_quality: 0.2,
            max_coast_s: 0.1,
            reacquire_velocity_std_mm_s: 100.0,
            reacquire_angular_velocity_std_rad_s: 4.0,
            max_velocity_mm_s: 6000.0,
            max_angular_velocity_rad_s: 600.0,
            override_points: 4,
            confirm_reacquisition: true,
            confirm_quality: None,
            reanchor_frames: 4,
            nominal_dt_s: 0.005,
        }
    }
}

/// Why the last measurement given to [`RodFilter::update`] was not accepted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rejection {
    /// The row's own status was not `ok`.
    NotMeasured(Status),
    /// The row's quality was below [`FilterConfig::min_quality`].
    LowQuality(f64),
    /// The timestamp did not advance past the previous row's.
    Timestamp {
        /// The previous row's timestamp, s.
        previous_s: f64,
        /// This row's, s.
        got_s: f64,
    },
    /// The position is too far from the prediction.
    PositionGate {
        /// Measurement minus prediction, mm.
        innovation_mm: f64,
        /// The gate it failed, mm.
        gate_mm: f64,
    },
    /// The angle (wrapped) is too far from the prediction.
    AngleGate {
        /// Measurement minus prediction, wrapped to `(-pi, pi]`, rad.
        innovation_rad: f64,
        /// The gate it failed, rad.
        gate_rad: f64,
    },
    /// Accepted only into a new candidate track that still waits for a confirming measurement.
    Unconfirmed,
}

impl std::fmt::Display for Rejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Rejection::NotMeasured(s) => write!(f, "no measurement ({s})"),
            Rejection::LowQuality(q) => write!(f, "quality {q:.2} too low"),
            Rejection::Timestamp { previous_s, got_s } => {
                write!(f, "timestamp {got_s} s does not follow {previous_s} s")
            }
            Rejection::PositionGate {
                innovation_mm,
                gate_mm,
            } => write!(
                f,
                "position {innovation_mm:+.2} mm from the prediction (gate {gate_mm:.2} mm)"
            ),
            Rejection::AngleGate {
                innovation_rad,
                gate_rad,
            } => write!(
                f,
                "angle {innovation_rad:+.3} rad from the prediction (gate {gate_rad:.3} rad)"
            ),
            Rejection::Unconfirmed => f.write_str("new track not yet confirmed"),
        }
    }
}
