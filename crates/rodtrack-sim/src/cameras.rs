//! Simulated cameras: the core's OpenCV camera model plus sensor settings (pixel format,
//! exposure, frame rate, noise, brightness).

use rodtrack_core::{Camera, CameraIntrinsics, PixelFormat, Pose};
use serde::{Deserialize, Serialize};

/// Sensor noise model: shot noise from a conversion gain plus Gaussian read noise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NoiseModel {
    /// Conversion gain, electrons per DN (shot noise variance in DN^2 is `mean_dn / gain`).
    pub gain_e_per_dn: f64,
    /// Read noise, DN (standard deviation).
    pub read_noise_dn: f64,
}

impl NoiseModel {
    /// No noise at all (for geometry tests).
    pub fn none() -> Self {
        NoiseModel {
            gain_e_per_dn: f64::INFINITY,
            read_noise_dn: 0.0,
        }
    }
    /// True when the model adds nothing.
    pub fn is_none(&self) -> bool {
        self.read_noise_dn <= 0.0 && !(self.gain_e_per_dn.is_finite() && self.gain_e_per_dn > 0.0)
    }
}

impl Default for NoiseModel {
    fn default() -> Self {
        NoiseModel {
            gain_e_per_dn: 25.0,
            read_noise_dn: 2.0,
        }
    }
}

/// One simulated camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimCamera {
    /// Name (`cam0`, ...), used for folders and files.
    pub name: String,
    /// Geometry: intrinsics, distortion, pose, image size.
    pub camera: Camera,
    /// Output pixel format (8-bit Bayer, `mono8` or `rgb8`).
    pub pixel_format: PixelFormat,
    /// Exposure time, microseconds (scales brightness and motion blur).
    pub exposure_us: f64,
    /// Frame rate, frames/s (a [`crate::Simulation`] sets it to its scenario's rate: the
    /// cameras share one hardware trigger).
    pub fps: f64,
    /// Sensor noise.
    pub noise: NoiseModel,
    /// Global brightness factor (1 = white paper at about 200 DN at 500 us).
    pub brightness: f64,
}

/// Focal length for a vertical view angle over `height_px` rows.
pub fn focal_for_vertical_view(height_px: usize, view_deg: f64) -> f64 {
    0.5 * height_px as f64 / (0.5 * view_deg).to_radians().tan()
}

impl SimCamera {
    /// A camera of the reference setup centred over world `(x_mm, y_mm)` at height `z_mm`,
    /// turned by `yaw_rad` and tilted by `pitch_rad` (see [`Pose::looking_down`]).
    pub fn reference(
        name: &str,
        centre_mm: [f64; 3],
        yaw_rad: f64,
        pitch_rad: f64,
        dist: [f64; 5],
    ) -> SimCamera {
        let (w, h) = (1440usize, 1080usize);
        let f = focal_for_vertical_view(h, 53.2);
        let intrinsics = CameraIntrinsics {
            fx: f,
            fy: f,
            cx: 0.5 * (w as f64 - 1.0),
            cy: 0.5 * (h as f64 - 1.0),
            k1: dist[0],
            k2: dist[1],
            p1: dist[2],
            p2: dist[3],
            k3: dist[4],
        };
        SimCamera {
            name: name.to_string(),
            camera: Camera {
                intrinsics,
                pose: Pose::looking_down(centre_mm, yaw_rad, pitch_rad),
                width: w,
                height: h,
            },
            pixel_format: PixelFormat::BayerRggb8,
            exposure_us: 500.0,
            fps: 200.0,
            noise: NoiseModel::default(),
            brightness: 1.0,
        }
    }

    /// Replaces the pose by one looking down from `centre_mm` with the given yaw and pitch.
    pub fn with_pose(mut self, centre_mm: [f64; 3], yaw_rad: f64, pitch_rad: f64) -> Self {
        self.camera.pose = Pose::looking_down(centre_mm, yaw_rad, pitch_rad);
        self
    }

    /// Replaces the radial distortion `k1`.
    pub fn with_k1(mut self, k1: f64) -> Self {
        self.camera.intrinsics.k1 = k1;
        self
    }

    /// Bytes of one tightly packed frame.
    pub fn frame_bytes(&self) -> usize {
        self.camera.width * self.camera.height * self.pixel_format.bytes_per_pixel()
    }
}

/// The default pair: `cam0` over `x = 525` (rods 0-6), `cam1` over `x = 675` (rods 1-7), both
/// 750 mm above the rods, rows along the rods, with slightly different yaw, pitch and
/// distortion.
pub fn default_cameras() -> Vec<SimCamera> {
    vec![
        SimCamera::reference(
            "cam0",
            [525.0, 340.0, 830.0],
            0.6f64.to_radians(),
            -0.9f64.to_radians(),
            [-0.25, 0.08, 0.0004, -0.0003, 0.0],
        ),
        SimCamera::reference(
            "cam1",
            [675.0, 342.0, 828.0],
            -0.8f64.to_radians(),
            0.7f64.to_radians(),
            [-0.24, 0.075, -0.0003, 0.0002, 0.0],
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_focal_matches_view_angle() {
        let f = focal_for_vertical_view(1080, 53.2);
        assert!((f - 540.0 / 26.6f64.to_radians().tan()).abs() < 1e-9);
        let cams = default_cameras();
        assert_eq!(cams.len(), 2);
        assert_ne!(cams[0].camera.pose, cams[1].camera.pose);
    }
}
