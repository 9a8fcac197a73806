//! Per-camera renderer: precomputed ray table, cached static background, fixed rod strips,
//! dirty rectangles for what moves, then one pass of light, noise and quantisation.
//!
//! Fast mode: one ray per pixel; the marker is box-filtered analytically over the pixel
//! footprint (and over the motion during the exposure), rod silhouettes are antialiased by
//! coverage. Quality mode: 4 x 4 sub-samples per pixel, each at its own time in the exposure.

mod finish;
mod frame;
mod grid;
mod paint;
mod renderer;
mod setup;

pub(crate) use finish::noise_table;
pub(crate) use renderer::{CameraRenderer, QSUB};
pub use renderer::{RenderMode, RenderStats};
