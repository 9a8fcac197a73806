//! Steps 1-2: the coarse line and the barcode's correlation, around where the marker is
//! expected and, failing that, over the whole travel.

use super::result::RodResult;
use super::state::{EnhancedState, Located};
use super::tuning::SEARCH_WINDOWS_MM;
use crate::frame::FrameView;
use crate::marker::Marker;
use crate::measurement::Status;
use crate::signal::{argmax, ncc_cells_prefix, parabolic_offset, prefix_sums};

impl EnhancedState {
    /// Steps 1-2: coarse line at 1/4 cell (nearest luma node) and the NCC with the cell kernel
    /// in O(samples x cells): first in a window around the last frame's marker, and over the
    /// whole travel when that finds no clear peak inside the window.
    pub(super) fn locate(&mut self, m: &Marker, frame: &FrameView) -> Result<Located, RodResult> {
        let st = self;
        let node_off = frame.node_offset() as f64;
        let n_cand = st.corr.len();
        let mut found = None;
        if let (Some(_), Some(p)) = (st.last_k, st.predicted_mm) {
            // Around where the last frame's motion says the marker is now.
            let k0 = ((p + m.barcode_start_mm() - st.coarse_s0) / st.coarse_step)
                .round()
                .clamp(0.0, (n_cand - 1) as f64) as usize;
            for window_mm in SEARCH_WINDOWS_MM {
                let window = (window_mm / st.coarse_step).ceil() as usize;
                let (lo, hi) = (k0.saturating_sub(window), (k0 + window).min(n_cand - 1));
                if let Some((k, c, sub)) = coarse_search(st, frame, node_off, lo, hi) {
                    let inside = (k > lo || lo == 0) && (k < hi || hi == n_cand - 1);
                    if inside && c >= 0.8 {
                        found = Some((k, c, sub));
                        break;
                    }
                }
            }
        }
        if found.is_none() {
            st.full_searches += 1;
            found = coarse_search(st, frame, node_off, 0, n_cand - 1);
        }
        st.last_k = None;
        let Some((k, _, sub)) = found else {
            return Err(RodResult {
                status: Status::OutOfView,
                ..Default::default()
            });
        };
        let ncc = st.corr[k] as f64;
        if !st.valid[k] {
            return Err(RodResult {
                status: Status::OutOfView,
                ..Default::default()
            });
        }
        if ncc < 0.5 {
            return Err(RodResult {
                status: Status::NotFound,
                quality: ncc.max(0.0) * 0.5,
                ncc,
                reason: "weak barcode correlation",
                ..Default::default()
            });
        }
        let pos0 = st.coarse_s0 + (k as f64 + sub) * st.coarse_step - m.barcode_start_mm();
        // Black and white levels from the cells' middle samples.
        let (mut w_sum, mut w_n, mut b_sum, mut b_n) = (0.0f64, 0usize, 0.0f64, 0usize);
        for (c, &cell) in st.cells.iter().enumerate() {
            let base = k + c * st.cell_len;
            let v = 0.5 * (st.coarse[base + 1] + st.coarse[base + 2]) as f64;
            if cell > 0.5 {
                w_sum += v;
                w_n += 1;
            } else {
                b_sum += v;
                b_n += 1;
            }
        }
        let white = w_sum / w_n.max(1) as f64;
        let black = b_sum / b_n.max(1) as f64;
        if white - black < 8.0 {
            return Err(RodResult {
                status: Status::NotFound,
                ncc,
                reason: "no contrast",
                ..Default::default()
            });
        }
        Ok(Located {
            k,
            ncc,
            pos0_mm: pos0,
            white,
            black,
        })
    }
}

/// Samples the coarse line over candidates `lo..=hi` (and the kernel's length beyond) and
/// correlates: the best candidate, its NCC and the sub-sample offset of the peak. Invalid
/// candidates (window not wholly in the frame) never win.
fn coarse_search(
    st: &mut EnhancedState,
    frame: &FrameView,
    node_off: f64,
    lo: usize,
    hi: usize,
) -> Option<(usize, f64, f64)> {
    let kernel_n = st.cells.len() * st.cell_len;
    let end = hi + kernel_n;
    if st.coarse_grid_offset != node_off {
        for (g, n) in st.coarse_grid.iter_mut().zip(&st.coarse_nodes) {
            *g = n.map(|(i, j)| {
                (
                    (i as f64 - node_off).round() as isize,
                    (j as f64 - node_off).round() as isize,
                )
            });
        }
        st.coarse_grid_offset = node_off;
    }
    frame.luma_nodes(&st.coarse_grid[lo..end], &mut st.coarse[lo..end]);
    let len = end - lo;
    prefix_sums(
        &st.coarse[lo..end],
        &mut st.prefix[..len + 1],
        &mut st.prefix2[..len + 1],
    );
    ncc_cells_prefix(
        &st.cells,
        st.cell_len,
        &st.prefix[..len + 1],
        &st.prefix2[..len + 1],
        &mut st.corr[lo..=hi],
    );
    for (c, ok) in st.corr[lo..=hi].iter_mut().zip(&st.valid[lo..=hi]) {
        if !ok {
            *c = -1.0;
        }
    }
    let k = lo + argmax(&st.corr[lo..=hi])?;
    if !st.valid[k] {
        return None;
    }
    let sub = parabolic_offset(&st.corr[lo..=hi], k - lo) as f64;
    Some((k, st.corr[k] as f64, sub))
}
