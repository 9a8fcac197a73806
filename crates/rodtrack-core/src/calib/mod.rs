//! Calibration (paper 2.7): inputs, the calibration file, and the measurements that make it.

pub mod inputs;

pub use inputs::{CalibrationInputs, ImageSize, OpencvModel, ReferenceFrames, ReferencePose, RodInputs};
