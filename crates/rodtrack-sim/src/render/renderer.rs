//! The renderer's state (one camera's precomputed tables and scratch buffers), its public
//! types and the small per-pixel helpers shared by the other parts.

use super::grid::RayGrid;
use crate::cameras::SimCamera;
use crate::geom::{Obj, Table, WorldGeom, V3};
use crate::raster::Quad;

/// How carefully to render.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RenderMode {
    /// One sample per pixel, analytic marker antialiasing and blur.
    #[default]
    Fast,
    /// 4 x 4 sub-samples per pixel spread over the exposure.
    Quality,
}

/// Sub-samples per axis in quality mode.
pub(crate) const QSUB: usize = 4;

/// A pixel rectangle, `[x0, x1) x [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Rect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

impl Rect {
    pub(super) fn is_empty(&self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }
}

/// A pixel where a rod can appear, with everything about the hit that does not depend on the
/// rod's pose (the rod only slides along and turns about its own axis).
#[derive(Debug, Clone, Copy)]
pub(super) struct StripPx {
    pub(super) idx: u32,
    /// The table behind this pixel (per channel; only the first is used for mono/Bayer).
    pub(super) bg0: [f32; 3],
    pub(super) y: f32,
    pub(super) a: f32,
    pub(super) shade: f32,
    pub(super) spec: f32,
    pub(super) hu: f32,
    pub(super) hpsi: f32,
    pub(super) alpha: f32,
}

/// One rod's pixels, sorted by the world `y` they see (so the marker's pixels are one range).
#[derive(Debug, Clone, Default)]
pub(super) struct Strip {
    pub(super) px: Vec<StripPx>,
    pub(super) bbox: Option<Rect>,
}

/// Tile size for the dirty regions of moving objects, px.
pub(super) const TILE: usize = 16;

/// One camera's renderer with all its precomputed tables and scratch buffers.
#[derive(Debug, Clone)]
pub(crate) struct CameraRenderer {
    pub cam: SimCamera,
    /// The markers rendered with `n x n` point rays per pixel instead of the pixel's area
    /// (see [`crate::Simulation::with_point_rays`]); `None`: the area.
    pub point_rays: Option<usize>,
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) ch: usize,
    pub(super) bayer: Option<[u8; 4]>,
    pub(super) origin: V3,
    /// Rays, pixel footprints and light on a coarse grid (fits in cache), interpolated.
    pub(super) grid: RayGrid,
    /// The static table, for the walls that may hide moving things.
    pub(super) table: Table,
    /// True for tiles where a wall is seen (elsewhere nothing static is in front of anything).
    pub(super) tile_wall: Vec<bool>,
    /// Table only (DN at brightness 1), `ch` values per pixel: what a rod is blended over.
    pub(super) bg0: Vec<f32>,
    /// Table plus bare steel rods: the image with nothing moving and no marker.
    pub(super) bg: Vec<f32>,
    pub(super) glare: Option<Vec<f32>>,
    pub(super) strips: Vec<Strip>,
    /// Bit `i` set when rod `i`'s strip touches the tile.
    pub(super) tile_rods: Vec<u64>,
    pub(super) tiles_x: usize,
    /// Working image.
    pub(super) rad: Vec<f32>,
    /// Tiles and marker ranges drawn last frame (to restore).
    pub(super) prev_tiles: Vec<u32>,
    pub(super) prev_ranges: Vec<(usize, usize, usize)>,
    /// Scratch: objects per tile, touched tiles.
    pub(super) tile_objs: Vec<Vec<Obj>>,
    pub(super) touched: Vec<u32>,
    /// Rod index + 1 per pixel where a rod is seen (0: none).
    pub(super) rod_mask: Vec<u8>,
    /// Noisy, quantised copies of the still image (brightness 1, no glare).
    pub(super) noisy_bg: Vec<Vec<u8>>,
    /// Scratch for the rasteriser.
    pub(super) quads: Vec<Quad>,
    pub(super) spans: Vec<(u32, u32, u32)>,
    pub(super) tile_dirty: Vec<bool>,
    /// Scratch for the world at this frame's time samples.
    pub scratch_state: crate::geom::WorldState,
    pub scratch_geoms: Vec<WorldGeom>,
    /// Quality mode: pixels to trace for moving objects this frame.
    pub(super) obj_mask: Vec<bool>,
    pub(super) mask_list: Vec<u32>,
    pub stats: RenderStats,
}

/// Where the time of the last rendered frame went.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct RenderStats {
    /// Restoring last frame's changes, ms.
    pub restore_ms: f64,
    /// Shading the markers, ms.
    pub markers_ms: f64,
    /// Tracing figures, hands and ball, ms.
    pub objects_ms: f64,
    /// Light, noise and quantisation over the whole frame, ms.
    pub finish_ms: f64,
    /// Marker pixels shaded.
    pub marker_px: usize,
    /// 16 x 16 tiles traced for moving objects.
    pub object_tiles: usize,
    /// Sum over those tiles of the number of objects tested.
    pub object_cands: usize,
}

impl CameraRenderer {
    /// The ray through sub-pixel position `(x + fx, y + fy)`, its angular size and light.
    #[inline]
    pub(super) fn sub_ray(&self, x: usize, y: usize, fx: f32, fy: f32) -> (V3, f32, f32) {
        self.grid.sample(x as f32 + fx, y as f32 + fy)
    }

    /// Nearest wall along a ray from pixel tile `t` (infinite where no wall is seen).
    #[inline]
    pub(super) fn t_max(&self, x: usize, y: usize, d: V3) -> f32 {
        if self.tile_wall[(y / TILE) * self.tiles_x + x / TILE] {
            self.table.trace_walls(self.origin, d)
        } else {
            f32::INFINITY
        }
    }

    #[inline]
    pub(super) fn pick(&self, rgb: V3, x: usize, y: usize) -> f32 {
        match self.bayer {
            Some(p) => rgb[p[(y & 1) * 2 + (x & 1)] as usize],
            None => 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2],
        }
    }

    /// Writes colour `rgb` (already lit) for pixel `p` into `buf`.
    #[inline]
    pub(super) fn put(&self, buf: &mut [f32], p: usize, rgb: V3) {
        if self.ch == 3 {
            buf[p * 3..p * 3 + 3].copy_from_slice(&rgb);
        } else {
            buf[p] = self.pick(rgb, p % self.w, p / self.w);
        }
    }

    pub(super) fn tile_rect(&self, t: usize) -> Rect {
        let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
        Rect {
            x0: tx * TILE,
            y0: ty * TILE,
            x1: ((tx + 1) * TILE).min(self.w),
            y1: ((ty + 1) * TILE).min(self.h),
        }
    }
}
