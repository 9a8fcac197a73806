//! What the ball's test suites share: the simulator's cameras calibrated from their clicks
//! (with the ball's frame), and a session's cameras over every frame of a simulation.
#![allow(dead_code, clippy::unwrap_used)]

use rodtrack_core::calib::{CalibrationFile, CALIBRATION_VERSION};
use rodtrack_core::{CameraPipeline, Mode};
use rodtrack_sdk::SessionCamera;
use rodtrack_sim::{SimSource, Simulation};

/// Calibrates every camera of `sim` from its simulated clicks, reference frame and ball frame.
pub fn calibrate(sim: &mut Simulation, seed: u64) -> CalibrationFile {
    CalibrationFile {
        version: CALIBRATION_VERSION,
        cameras: (0..sim.cameras().len())
            .map(|cam| sim.calibrated_camera_with_ball(cam, seed).unwrap())
            .collect(),
    }
}

/// Every camera of `sim` as a session's camera (enhanced mode), over every frame.
pub fn session_cameras(sim: &Simulation, cal: &CalibrationFile) -> Vec<SessionCamera> {
    let sources = SimSource::for_simulation(sim, Default::default()).unwrap();
    sources
        .into_iter()
        .zip(&cal.cameras)
        .map(|(s, c)| SessionCamera {
            label: format!("camera {}", c.index),
            source: Box::new(s),
            pipe: CameraPipeline::new(c, Mode::Enhanced).unwrap(),
        })
        .collect()
}
