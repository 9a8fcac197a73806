//! The memory a track run holds at most (see `docs/robustness.md`).

use crate::source::max_image_file_bytes;

/// What a run holds besides its frames: the binary, the trackers' tables, rows, threads'
/// stacks (32 MiB; a two-camera 1440x1080 run peaks near 19 MiB in all).
pub const BASE_BYTES: usize = 32 << 20;

/// The most a track run over image files holds, bytes, for cameras of `(width, height,
/// bytes per pixel)` and `queue_depth` frames queued per camera:
///
/// `BASE_BYTES + sum over cameras of ((queue_depth + 3) * F + (8 * P + 1 MiB) + 8 * P)`
///
/// with `F = width * height * bytes per pixel` (one frame buffer: the pool keeps at most
/// `queue_depth + 3`), `P = width * height` pixels, `8 * P + 1 MiB` the longest frame file read
/// ([`max_image_file_bytes`]) and `8 * P` the decoder's conversion buffer (RGBA 16-bit, the
/// widest layout accepted). A file claiming another size is refused from its header, so no
/// file makes a run hold more.
pub fn track_memory_budget(cameras: &[(usize, usize, usize)], queue_depth: usize) -> usize {
    cameras
        .iter()
        .map(|&(w, h, bpp)| {
            let px = w.saturating_mul(h);
            let frame = px.saturating_mul(bpp);
            let file = usize::try_from(max_image_file_bytes(px)).unwrap_or(usize::MAX);
            (queue_depth + 3)
                .saturating_mul(frame)
                .saturating_add(file)
                .saturating_add(px.saturating_mul(8))
        })
        .fold(BASE_BYTES, usize::saturating_add)
}
