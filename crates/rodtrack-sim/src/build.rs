//! A simulation of the reference table, or of a table set up otherwise, from a scenario name.

use crate::{
    apply_variation, default_cameras, RenderMode, Scenario, SceneConfig, SimError, Simulation,
};

/// Builds the simulation of scenario `scenario` (one of [`crate::SCENARIO_NAMES`]) on the
/// table set up as `setup` says (`default`, a named variation or `asbuilt:SEED`; see
/// [`apply_variation`]): `frames` frames (default: the scenario's length), scene noise and
/// clicks drawn from `seed`, quality rendering when `quality`.
///
/// `rodtrack simulate`, the `sim://` source and the demo all build their simulations here,
/// so that the same arguments give the same frames byte for byte.
///
/// ```
/// let sim = rodtrack_sim::build_simulation("exp3", Some(2), 1, false, "default").unwrap();
/// assert_eq!(sim.frame_count(), 2);
/// assert_eq!(sim.cameras().len(), 2);
/// ```
pub fn build_simulation(
    scenario: &str,
    frames: Option<usize>,
    seed: u64,
    quality: bool,
    setup: &str,
) -> Result<Simulation, SimError> {
    let mut scene = SceneConfig::default();
    let mut cameras = default_cameras();
    apply_variation(setup, &mut scene, &mut cameras)?;
    let mut sc = Scenario::by_name(scenario, &scene, seed)?;
    if let Some(n) = frames {
        sc = sc.with_frames(n);
    }
    let mode = if quality {
        RenderMode::Quality
    } else {
        RenderMode::Fast
    };
    Ok(Simulation::new(scene, cameras, sc, mode)?.with_seed(seed))
}

/// Camera `c` of a simulation calibrated as an operator would calibrate it: from its simulated
/// clicks (about 1 px of error, drawn from `seed`) and its rendered reference frame.
#[derive(Debug, Clone)]
pub struct SimCalibration {
    /// The calibration inputs (the clicks).
    pub inputs: rodtrack_core::calib::CalibrationInputs,
    /// The reference frame's pixels.
    pub reference: Vec<u8>,
    /// The reference frame's layout.
    pub meta: crate::RenderInfo,
    /// The camera's calibration.
    pub calibration: rodtrack_core::calib::CameraCalibration,
}

/// Calibrates camera `c` of `sim` as an operator would; see [`SimCalibration`].
///
/// ```
/// let mut sim = rodtrack_sim::build_simulation("exp3", Some(2), 1, false, "default").unwrap();
/// let cal = rodtrack_sim::calibrate_sim_camera(&mut sim, 0, 1).unwrap();
/// assert!(!cal.calibration.rods.is_empty());
/// ```
pub fn calibrate_sim_camera(
    sim: &mut Simulation,
    c: usize,
    seed: u64,
) -> Result<SimCalibration, SimError> {
    let inputs = sim.calibration_inputs(c, seed)?;
    let mut reference = vec![0u8; sim.frame_bytes(c)?];
    let meta = sim.render_reference(c, &mut reference)?;
    let view = rodtrack_core::FrameView::new(
        &reference,
        meta.width,
        meta.height,
        meta.stride,
        meta.format,
    )?;
    let fps = 1.0 / sim.timestamp_s(1).max(1e-6);
    let calibration =
        rodtrack_core::calib::calibrate_camera_from_view(&inputs, &view, c as u32, fps)?;
    Ok(SimCalibration {
        inputs,
        reference,
        meta,
        calibration,
    })
}
