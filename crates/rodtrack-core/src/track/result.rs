//! What one rod's processing gives for one frame.

use crate::measurement::Status;

/// What one rod's processing found in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RodResult {
    /// Position along `u`, mm.
    pub position_mm: f64,
    /// Angle in `[0, 2 pi)`.
    pub angle_rad: f64,
    /// Confidence in `[0, 1]`.
    pub quality: f64,
    /// Trust.
    pub status: Status,
    /// Diagnostics: the decoded Gray step.
    pub gray_step: u32,
    /// Diagnostics: the angle in Gray steps before the offset, `[0, steps)`.
    pub theta_steps: f64,
    /// Diagnostics: the correlation peak.
    pub ncc: f64,
    /// Diagnostics: why the status is not `ok` (empty when it is).
    pub reason: &'static str,
    /// Diagnostics: phase amplitude over the expected one.
    pub amp_ratio: f64,
    /// Diagnostics: the share of the stripes' variation across the rod (over bit space 0)
    /// that their fundamental explains.
    pub stripe_share: f64,
    /// Diagnostics: spread of the barcode's edges around their fit, mm.
    pub edge_std_mm: f64,
    /// Diagnostics: the largest share of a bit space's samples across the rod whose colour
    /// is not the one the decoded angle expects.
    pub code_disagreement: f64,
}
