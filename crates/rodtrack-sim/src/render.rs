//! Per-camera renderer: precomputed ray table, cached static background, fixed rod strips,
//! dirty rectangles for what moves, then one pass of light, noise and quantisation.
//!
//! Fast mode: one ray per pixel; the marker is box-filtered analytically over the pixel
//! footprint (and over the motion during the exposure), rod silhouettes are antialiased by
//! coverage. Quality mode: 4 x 4 sub-samples per pixel, each at its own time in the exposure.

use crate::cameras::SimCamera;
use crate::geom::{rod_hit, rod_sample, Obj, Shader, Table, WorldGeom, V3};
use crate::raster::{box_faces, scan, Quad};
use crate::rng::{hash_words, Rng};
use crate::scene::Team;
use crate::scene::{Lighting, SceneConfig};
use rodtrack_core::PixelFormat;

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
/// Time slot of each quality sub-sample (a 4x4 ordered-dither matrix: neighbours differ).
const QTIME: [usize; 16] = [0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5];

/// Which channel a pixel's colour filter passes (0 R, 1 G, 2 B), or `None` for mono/RGB.
fn bayer_pattern(f: PixelFormat) -> Option<[u8; 4]> {
    match f {
        PixelFormat::BayerRggb8 | PixelFormat::BayerRggb16 => Some([0, 1, 1, 2]),
        PixelFormat::BayerBggr8 | PixelFormat::BayerBggr16 => Some([2, 1, 1, 0]),
        PixelFormat::BayerGrbg8 | PixelFormat::BayerGrbg16 => Some([1, 0, 2, 1]),
        PixelFormat::BayerGbrg8 | PixelFormat::BayerGbrg16 => Some([1, 2, 0, 1]),
        _ => None,
    }
}

/// A pixel rectangle, `[x0, x1) x [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Rect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

impl Rect {
    fn is_empty(&self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }
}

/// A pixel where a rod can appear, with everything about the hit that does not depend on the
/// rod's pose (the rod only slides along and turns about its own axis).
#[derive(Debug, Clone, Copy)]
struct StripPx {
    idx: u32,
    /// The table behind this pixel (per channel; only the first is used for mono/Bayer).
    bg0: [f32; 3],
    y: f32,
    a: f32,
    shade: f32,
    spec: f32,
    hu: f32,
    hpsi: f32,
    alpha: f32,
}

/// One rod's pixels, sorted by the world `y` they see (so the marker's pixels are one range).
#[derive(Debug, Clone, Default)]
struct Strip {
    px: Vec<StripPx>,
    bbox: Option<Rect>,
}

/// Tile size for the dirty regions of moving objects, px.
const TILE: usize = 16;

/// One camera's renderer with all its precomputed tables and scratch buffers.
#[derive(Debug, Clone)]
pub(crate) struct CameraRenderer {
    pub cam: SimCamera,
    w: usize,
    h: usize,
    ch: usize,
    bayer: Option<[u8; 4]>,
    origin: V3,
    /// Rays, pixel footprints and light on a coarse grid (fits in cache), interpolated.
    grid: RayGrid,
    /// The static table, for the walls that may hide moving things.
    table: Table,
    /// True for tiles where a wall is seen (elsewhere nothing static is in front of anything).
    tile_wall: Vec<bool>,
    /// Table only (DN at brightness 1), `ch` values per pixel: what a rod is blended over.
    bg0: Vec<f32>,
    /// Table plus bare steel rods: the image with nothing moving and no marker.
    bg: Vec<f32>,
    glare: Option<Vec<f32>>,
    strips: Vec<Strip>,
    /// Bit `i` set when rod `i`'s strip touches the tile.
    tile_rods: Vec<u64>,
    tiles_x: usize,
    /// Working image.
    rad: Vec<f32>,
    /// Tiles and marker ranges drawn last frame (to restore).
    prev_tiles: Vec<u32>,
    prev_ranges: Vec<(usize, usize, usize)>,
    /// Scratch: objects per tile, touched tiles.
    tile_objs: Vec<Vec<Obj>>,
    touched: Vec<u32>,
    /// Rod index + 1 per pixel where a rod is seen (0: none).
    rod_mask: Vec<u8>,
    /// Noisy, quantised copies of the still image (brightness 1, no glare).
    noisy_bg: Vec<Vec<u8>>,
    /// Scratch for the rasteriser.
    quads: Vec<Quad>,
    spans: Vec<(u32, u32, u32)>,
    tile_dirty: Vec<bool>,
    /// Scratch for the world at this frame's time samples.
    pub scratch_state: crate::geom::WorldState,
    pub scratch_geoms: Vec<WorldGeom>,
    /// Quality mode: pixels to trace for moving objects this frame.
    obj_mask: Vec<bool>,
    mask_list: Vec<u32>,
    pub stats: RenderStats,
}

/// Number of noisy copies of the still image kept for the fast path.
const NOISY_COPIES: usize = 8;

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

fn norm(v: [f64; 3]) -> V3 {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [(v[0] / n) as f32, (v[1] / n) as f32, (v[2] / n) as f32]
}

impl CameraRenderer {
    pub fn new(
        cam: &SimCamera,
        scene: &SceneConfig,
        lighting: &Lighting,
        shader: &Shader,
        mode: RenderMode,
        noise: &[f32],
    ) -> Self {
        let (w, h) = (cam.camera.width, cam.camera.height);
        let bayer = bayer_pattern(cam.pixel_format);
        let ch = if cam.pixel_format == PixelFormat::Rgb8 {
            3
        } else {
            1
        };
        let c = cam.camera.pose.centre_world();
        let origin = c.map(|v| v as f32);
        let dn_scale = 235.0 * cam.brightness * cam.exposure_us / 500.0;
        // Light: a gradient in the rods' plane.
        let (sg, cg) = lighting.gradient_dir_rad.sin_cos();
        let hl = 0.5 * scene.field_length_mm;
        let hw = 0.5 * scene.field_width_mm;
        let extent = hl * cg.abs() + hw * sg.abs();
        let lnr = lighting.gradient_ratio.max(1e-6).ln();
        let plane_z = scene.rods.first().map(|r| r.z_mm).unwrap_or(80.0);
        let light_of = |d: [f64; 3]| {
            let t = (plane_z - c[2]) / d[2];
            let x = c[0] + t * d[0] - hl;
            let y = c[1] + t * d[1] - hw;
            let s = ((x * cg + y * sg) / extent).clamp(-1.5, 1.5);
            (dn_scale * (0.5 * lnr * s).exp()) as f32
        };
        let grid = RayGrid::new(cam, &light_of);
        let glare = lighting.glare.and_then(|g| {
            let (u, v) = cam.camera.project(g.at_mm)?;
            let inv = 1.0 / (2.0 * g.sigma_px * g.sigma_px);
            let mut m = vec![0.0f32; w * h * ch];
            for y in 0..h {
                for x in 0..w {
                    let r2 = (x as f64 - u).powi(2) + (y as f64 - v).powi(2);
                    let val = (g.peak_dn * (-r2 * inv).exp()) as f32;
                    for c in 0..ch {
                        m[(y * w + x) * ch + c] = val;
                    }
                }
            }
            Some(m)
        });
        let tiles_x = w.div_ceil(TILE);
        let tiles_y = h.div_ceil(TILE);
        let mut r = CameraRenderer {
            cam: cam.clone(),
            w,
            h,
            ch,
            bayer,
            origin,
            grid,
            table: Table::new(scene),
            tile_wall: vec![false; tiles_x * tiles_y],
            bg0: vec![0.0; w * h * ch],
            bg: Vec::new(),
            glare,
            strips: Vec::new(),
            tile_rods: vec![0; tiles_x * tiles_y],
            tiles_x,
            rad: Vec::new(),
            prev_tiles: Vec::new(),
            prev_ranges: Vec::new(),
            tile_objs: vec![Vec::new(); tiles_x * tiles_y],
            touched: Vec::new(),
            rod_mask: vec![0; w * h],
            noisy_bg: Vec::new(),
            quads: Vec::new(),
            spans: Vec::new(),
            tile_dirty: vec![false; tiles_x * tiles_y],
            scratch_state: Default::default(),
            scratch_geoms: Vec::new(),
            obj_mask: vec![false; w * h],
            mask_list: Vec::new(),
            stats: RenderStats::default(),
        };
        let sub = match mode {
            RenderMode::Fast => 2,
            RenderMode::Quality => QSUB,
        };
        r.build_static(scene, shader, sub, &light_of);
        r.rad = r.bg.clone();
        r.build_noisy_copies(noise, 0x005E_EDB6);
        r
    }

    /// The ray through sub-pixel position `(x + fx, y + fy)`, its angular size and light.
    #[inline]
    fn sub_ray(&self, x: usize, y: usize, fx: f32, fy: f32) -> (V3, f32, f32) {
        self.grid.sample(x as f32 + fx, y as f32 + fy)
    }

    /// Nearest wall along a ray from pixel tile `t` (infinite where no wall is seen).
    #[inline]
    fn t_max(&self, x: usize, y: usize, d: V3) -> f32 {
        if self.tile_wall[(y / TILE) * self.tiles_x + x / TILE] {
            self.table.trace_walls(self.origin, d)
        } else {
            f32::INFINITY
        }
    }

    #[inline]
    fn pick(&self, rgb: V3, x: usize, y: usize) -> f32 {
        match self.bayer {
            Some(p) => rgb[p[(y & 1) * 2 + (x & 1)] as usize],
            None => 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2],
        }
    }

    /// Writes colour `rgb` (already lit) for pixel `p` into `buf`.
    #[inline]
    fn put(&self, buf: &mut [f32], p: usize, rgb: V3) {
        if self.ch == 3 {
            buf[p * 3..p * 3 + 3].copy_from_slice(&rgb);
        } else {
            buf[p] = self.pick(rgb, p % self.w, p / self.w);
        }
    }

    /// Renders the table (supersampled), finds every rod's pixels (exact rays) and bakes the
    /// bare steel rods into `bg`.
    fn build_static(
        &mut self,
        scene: &SceneConfig,
        shader: &Shader,
        sub: usize,
        light_of: &dyn Fn([f64; 3]) -> f32,
    ) {
        let n = sub * sub;
        let amb = shader.ambient;
        let steel = shader.steel;
        let ss = shader.steel_spec;
        let ch = self.ch;
        let mut bg0 = std::mem::take(&mut self.bg0);
        let mut bg = bg0.clone();
        let mut strips: Vec<Strip> = vec![Strip::default(); scene.rods.len()];
        let rods: Vec<(f32, f32, f32)> = scene
            .rods
            .iter()
            .map(|rc| (rc.x_mm as f32, rc.z_mm as f32, rc.radius_mm() as f32))
            .collect();
        let k = self.cam.camera.intrinsics;
        let pose = self.cam.camera.pose;
        for y in 0..self.h {
            for x in 0..self.w {
                let p = y * self.w + x;
                // Table, supersampled.
                let mut acc = [0.0f32; 3];
                for s in 0..n {
                    let fx = ((s % sub) as f32 + 0.5) / sub as f32 - 0.5;
                    let fy = ((s / sub) as f32 + 0.5) / sub as f32 - 0.5;
                    let (d, _, _) = self.sub_ray(x, y, fx, fy);
                    let (_, c) = self.table.trace(self.origin, d);
                    for k in 0..3 {
                        acc[k] += c[k];
                    }
                }
                // Exact ray of the pixel centre.
                let (nx, ny) = k.pixel_to_normalized(x as f64, y as f64);
                let dw = pose.dir_to_world([nx, ny, 1.0]);
                let light = light_of(dw);
                let d = norm(dw);
                let (t_bg, _) = self.table.trace(self.origin, d);
                if t_bg < f32::INFINITY && self.table.trace_walls(self.origin, d) <= t_bg {
                    self.tile_wall[(y / TILE) * self.tiles_x + x / TILE] = true;
                }
                let rgb = acc.map(|v| v / n as f32 * light);
                self.put(&mut bg0, p, rgb);
                let (_, foot, _) = self.sub_ray(x, y, 0.0, 0.0);
                for (ri, &(rx, rz, rr)) in rods.iter().enumerate() {
                    let Some(h) = rod_sample(rx, rz, rr, self.origin, d, foot, amb) else {
                        continue;
                    };
                    if h.t >= t_bg {
                        continue;
                    }
                    let mut b0 = [0.0f32; 3];
                    b0[..ch].copy_from_slice(&bg0[p * ch..p * ch + ch]);
                    let sp = StripPx {
                        idx: p as u32,
                        bg0: b0,
                        y: h.y,
                        a: h.a,
                        shade: h.shade * light,
                        spec: h.spec * light,
                        hu: h.hu,
                        hpsi: h.hpsi,
                        alpha: h.alpha,
                    };
                    let v = sp.shade * steel + sp.spec * ss;
                    for c in 0..ch {
                        bg[p * ch + c] = sp.alpha * v + (1.0 - sp.alpha) * b0[c];
                    }
                    strips[ri].px.push(sp);
                    self.rod_mask[p] = (ri + 1).min(255) as u8;
                    let b = strips[ri].bbox.get_or_insert(Rect {
                        x0: x,
                        y0: y,
                        x1: x + 1,
                        y1: y + 1,
                    });
                    b.x0 = b.x0.min(x);
                    b.x1 = b.x1.max(x + 1);
                    b.y0 = b.y0.min(y);
                    b.y1 = b.y1.max(y + 1);
                    if ri < 64 {
                        self.tile_rods[(y / TILE) * self.tiles_x + x / TILE] |= 1u64 << ri;
                    }
                }
                if !strips
                    .iter()
                    .any(|s| s.px.last().is_some_and(|q| q.idx == p as u32))
                {
                    for c in 0..ch {
                        bg[p * ch + c] = bg0[p * ch + c];
                    }
                }
            }
        }
        for s in &mut strips {
            s.px.sort_by(|a, b| a.y.total_cmp(&b.y));
        }
        self.strips = strips;
        self.bg0 = bg0;
        self.bg = bg;
    }

    /// Projected bounding rectangle of world points, with a margin; `None` if off-image.
    fn project_rect(&self, pts: &[[f64; 3]]) -> Option<Rect> {
        let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for p in pts {
            let (u, v) = self.cam.camera.project(*p)?;
            u0 = u0.min(u);
            u1 = u1.max(u);
            v0 = v0.min(v);
            v1 = v1.max(v);
        }
        let m = 2.0 + 0.03 * (u1 - u0).max(v1 - v0);
        let r = Rect {
            x0: (u0 - m).floor().clamp(0.0, self.w as f64) as usize,
            y0: (v0 - m).floor().clamp(0.0, self.h as f64) as usize,
            x1: (u1 + m).ceil().clamp(0.0, self.w as f64) as usize,
            y1: (v1 + m).ceil().clamp(0.0, self.h as f64) as usize,
        };
        (!r.is_empty()).then_some(r)
    }

    fn mark(&mut self, r: Rect, o: Obj) {
        for ty in r.y0 / TILE..r.y1.div_ceil(TILE) {
            for tx in r.x0 / TILE..r.x1.div_ceil(TILE) {
                let t = ty * self.tiles_x + tx;
                if self.tile_objs[t].is_empty() {
                    self.touched.push(t as u32);
                }
                self.tile_objs[t].push(o);
            }
        }
    }

    /// Marks the tiles covered by moving things (over all time samples), with the objects
    /// that may be seen in each.
    fn collect_tiles(&mut self, geoms: &[WorldGeom], shader: &Shader) {
        for &t in &self.touched {
            self.tile_objs[t as usize].clear();
        }
        self.touched.clear();
        let (blo, bhi) = shader.figure_bounds;
        let last = geoms.len() - 1;
        let picks = if last >= 2 {
            [0, last / 2, last]
        } else {
            [0, last, last]
        };
        let g0 = &geoms[0];
        let mut pts: Vec<[f64; 3]> = Vec::with_capacity(24);
        for i in 0..g0.rods.len() {
            for k in 0..g0.rods[i].figs.len() {
                pts.clear();
                for &gi in &picks {
                    let rg = &geoms[gi].rods[i];
                    for c in 0..8 {
                        let lx = if c & 1 == 0 { blo[0] } else { bhi[0] };
                        let ly = if c & 2 == 0 { blo[1] } else { bhi[1] };
                        let lz = if c & 4 == 0 { blo[2] } else { bhi[2] };
                        // Local to world: rotation by +phi about y.
                        let wx = rg.x + lx * rg.cphi + lz * rg.sphi;
                        let wz = rg.z - lx * rg.sphi + lz * rg.cphi;
                        pts.push([wx as f64, (rg.figs[k] + ly) as f64, wz as f64]);
                    }
                }
                if let Some(r) = self.project_rect(&pts) {
                    self.mark(r, Obj::Figure(i as u16, k as u16));
                }
            }
        }
        for h in 0..g0.hand_boxes.len() {
            pts.clear();
            for &gi in &picks {
                let Some(b) = geoms[gi].hand_boxes.get(h) else {
                    continue;
                };
                for c in 0..8 {
                    pts.push([
                        if c & 1 == 0 { b.lo[0] } else { b.hi[0] } as f64,
                        if c & 2 == 0 { b.lo[1] } else { b.hi[1] } as f64,
                        if c & 4 == 0 { b.lo[2] } else { b.hi[2] } as f64,
                    ]);
                }
            }
            if let Some(r) = self.project_rect(&pts) {
                self.mark(r, Obj::Hand(h as u16));
            }
        }
        if g0.ball.is_some() {
            pts.clear();
            for &gi in &picks {
                if let Some((c, r)) = geoms[gi].ball {
                    for k in 0..8 {
                        pts.push([
                            (c[0] + if k & 1 == 0 { -r } else { r }) as f64,
                            (c[1] + if k & 2 == 0 { -r } else { r }) as f64,
                            (c[2] + if k & 4 == 0 { -r } else { r }) as f64,
                        ]);
                    }
                }
            }
            if let Some(r) = self.project_rect(&pts) {
                self.mark(r, Obj::Ball);
            }
        }
    }

    fn tile_rect(&self, t: usize) -> Rect {
        let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
        Rect {
            x0: tx * TILE,
            y0: ty * TILE,
            x1: ((tx + 1) * TILE).min(self.w),
            y1: ((ty + 1) * TILE).min(self.h),
        }
    }

    /// The range of rod `i`'s strip pixels that may show the marker in `geoms`.
    fn marker_range(&self, i: usize, geoms: &[WorldGeom], len: f32) -> (usize, usize) {
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        for g in [&geoms[0], &geoms[geoms.len() - 1]] {
            let r = &g.rods[i];
            let a = r.marker_start;
            let b = r.marker_start + r.dir * len;
            let m = 3.0 + r.hu_blur;
            lo = lo.min(a.min(b) - m);
            hi = hi.max(a.max(b) + m);
        }
        let px = &self.strips[i].px;
        (
            px.partition_point(|p| p.y < lo),
            px.partition_point(|p| p.y <= hi),
        )
    }

    /// Renders one frame into `out` (tightly packed, `width * bytes_per_pixel` per row).
    ///
    /// `geoms` are the world at the time samples (1 in fast mode, 16 in quality mode);
    /// `brightness` and `glare` are the scenario's levels; `noise_seed` seeds the noise.
    #[allow(clippy::too_many_arguments)]
    pub fn render(
        &mut self,
        geoms: &[WorldGeom],
        shader: &Shader,
        mode: RenderMode,
        brightness: f32,
        glare: f32,
        noise: &[f32],
        noise_seed: u64,
        out: &mut [u8],
    ) {
        let ch = self.ch;
        let t_start = std::time::Instant::now();
        // 1. Restore what changed last frame.
        let prev_tiles = std::mem::take(&mut self.prev_tiles);
        for &t in &prev_tiles {
            let r = self.tile_rect(t as usize);
            for y in r.y0..r.y1 {
                let a = (y * self.w + r.x0) * ch;
                let b = (y * self.w + r.x1) * ch;
                self.rad[a..b].copy_from_slice(&self.bg[a..b]);
            }
        }
        self.prev_tiles = prev_tiles;
        self.prev_tiles.clear();
        for &(i, a, b) in &self.prev_ranges {
            for sp in &self.strips[i].px[a..b] {
                let p = sp.idx as usize * ch;
                self.rad[p..p + ch].copy_from_slice(&self.bg[p..p + ch]);
            }
        }
        self.prev_ranges.clear();
        let t_restore = t_start.elapsed();
        // 2. Markers.
        let len = shader.tex.len;
        let mut marker_px = 0;
        for i in 0..self.strips.len() {
            let (a, b) = self.marker_range(i, geoms, len);
            match mode {
                RenderMode::Fast => self.shade_marker_fast(i, a, b, &geoms[0], shader),
                RenderMode::Quality => {
                    let cands = [Obj::Rod(i as u16)];
                    for j in a..b {
                        let p = self.strips[i].px[j].idx as usize;
                        self.shade_pixel_quality(
                            p % self.w,
                            p / self.w,
                            geoms,
                            shader,
                            &cands,
                            QSUB,
                        );
                    }
                }
            }
            self.prev_ranges.push((i, a, b));
            marker_px += b - a;
        }
        let t_markers = t_start.elapsed();
        // 3. Figures, hands, ball.
        if mode == RenderMode::Fast {
            self.paint_objects(&geoms[0], shader);
            let t_objects = t_start.elapsed();
            self.finish(brightness, glare, noise, noise_seed, out);
            let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
            self.stats = RenderStats {
                restore_ms: ms(t_restore),
                markers_ms: ms(t_markers - t_restore),
                objects_ms: ms(t_objects - t_markers),
                finish_ms: ms(t_start.elapsed() - t_objects),
                marker_px,
                object_tiles: self.prev_tiles.len(),
                object_cands: self.quads.len(),
            };
            return;
        }
        self.collect_tiles(geoms, shader);
        // Quality: only pixels near what the moving objects cover during the exposure.
        let last = geoms.len() - 1;
        let mut quads = std::mem::take(&mut self.quads);
        let mut spans = std::mem::take(&mut self.spans);
        for gi in [0, last / 2, last] {
            quads.clear();
            spans.clear();
            self.build_quads(&geoms[gi], shader, &mut quads);
            for q in &quads {
                scan(q, self.w, self.h, &mut spans);
            }
            for &(y, x0, x1) in &spans {
                let y = y as usize;
                for yy in y.saturating_sub(1)..(y + 2).min(self.h) {
                    for x in (x0 as usize).saturating_sub(1)..(x1 as usize + 2).min(self.w) {
                        let p = yy * self.w + x;
                        if !self.obj_mask[p] {
                            self.obj_mask[p] = true;
                            self.mask_list.push(p as u32);
                        }
                    }
                }
            }
        }
        self.quads = quads;
        self.spans = spans;
        let touched = std::mem::take(&mut self.touched);
        let mut cands: Vec<Obj> = Vec::new();
        for &t in &touched {
            let r = self.tile_rect(t as usize);
            cands.clear();
            cands.extend_from_slice(&self.tile_objs[t as usize]);
            let rods = self.tile_rods[t as usize];
            match mode {
                RenderMode::Fast => {
                    for y in r.y0..r.y1 {
                        for x in r.x0..r.x1 {
                            self.shade_object_fast(x, y, &geoms[0], shader, &cands, rods);
                        }
                    }
                }
                RenderMode::Quality => {
                    for i in 0..64 {
                        if rods & (1u64 << i) != 0 {
                            cands.push(Obj::Rod(i as u16));
                        }
                    }
                    for y in r.y0..r.y1 {
                        for x in r.x0..r.x1 {
                            if self.obj_mask[y * self.w + x] {
                                self.shade_pixel_quality(x, y, geoms, shader, &cands, 2);
                            }
                        }
                    }
                }
            }
        }
        for &p in &self.mask_list {
            self.obj_mask[p as usize] = false;
        }
        self.mask_list.clear();
        self.prev_tiles.clear();
        self.prev_tiles.extend_from_slice(&touched);
        let object_tiles = touched.len();
        self.touched = touched;
        let t_objects = t_start.elapsed();
        // 4. Light level, glare, noise, quantisation.
        self.finish(brightness, glare, noise, noise_seed, out);
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
        self.stats = RenderStats {
            restore_ms: ms(t_restore),
            markers_ms: ms(t_markers - t_restore),
            objects_ms: ms(t_objects - t_markers),
            finish_ms: ms(t_start.elapsed() - t_objects),
            marker_px,
            object_tiles,
            object_cands: self
                .touched
                .iter()
                .map(|&t| self.tile_objs[t as usize].len())
                .sum(),
        };
    }

    /// Fast mode: rasterises figures, hands and the ball over the image; marks their tiles.
    fn paint_objects(&mut self, g: &WorldGeom, shader: &Shader) {
        let mut quads = std::mem::take(&mut self.quads);
        quads.clear();
        self.build_quads(g, shader, &mut quads);
        self.paint_quads(g, shader, &quads);
        self.quads = quads;
    }

    /// The camera-facing faces of every figure, hand and the ball, far to near.
    fn build_quads(&self, g: &WorldGeom, shader: &Shader, quads: &mut Vec<Quad>) {
        let cam = self.cam.camera;
        let o = self.origin.map(|v| v as f64);
        let amb = shader.ambient;
        for rod in &g.rods {
            let (c, s) = (rod.cphi, rod.sphi);
            let col = match rod.team {
                Team::Red => shader.red,
                Team::Blue => shader.blue,
            };
            let rot = |n: V3| [n[0] * c + n[2] * s, n[1], -n[0] * s + n[2] * c];
            for &fy in &rod.figs {
                let to_world = |l: V3| {
                    [
                        rod.x + l[0] * c + l[2] * s,
                        fy + l[1],
                        rod.z - l[0] * s + l[2] * c,
                    ]
                };
                for (lo, hi) in &shader.figure {
                    box_faces(&cam, o, *lo, *hi, &to_world, &rot, col, amb, quads);
                }
            }
        }
        let id = |v: V3| v;
        for b in &g.hand_boxes {
            box_faces(&cam, o, b.lo, b.hi, &id, &id, shader.skin, amb, quads);
        }
        if let Some((c, r)) = g.ball {
            let cd = [c[0] as f64, c[1] as f64, c[2] as f64];
            if let (Some((u, v)), Some((u2, _))) = (
                cam.project(cd),
                cam.project([cd[0] + r as f64, cd[1], cd[2]]),
            ) {
                let dv = [
                    c[0] - self.origin[0],
                    c[1] - self.origin[1],
                    c[2] - self.origin[2],
                ];
                let dist = (dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]).sqrt() - r;
                quads.push(Quad {
                    v: [
                        [u as f32, v as f32],
                        [(u2 - u).abs() as f32 + 0.5, 0.0],
                        [0.0; 2],
                        [0.0; 2],
                    ],
                    dist,
                    rgb: shader.ball,
                    n: [0.0, 0.0, 1.0],
                    c,
                    zmin: c[2] - r,
                    disc: true,
                });
            }
        }
        quads.sort_by(|a, b| b.dist.total_cmp(&a.dist));
    }

    /// Fills the quads into the image (fast mode) and marks their tiles dirty.
    fn paint_quads(&mut self, g: &WorldGeom, shader: &Shader, quads: &[Quad]) {
        let amb = shader.ambient;
        let mut spans = std::mem::take(&mut self.spans);
        let mut rad = std::mem::take(&mut self.rad);
        let (ch, w, bayer) = (self.ch, self.w, self.bayer);
        for q in quads {
            spans.clear();
            scan(q, self.w, self.h, &mut spans);
            if spans.is_empty() {
                continue;
            }
            let (u, v) = if q.disc {
                (q.v[0][0], q.v[0][1])
            } else {
                (
                    0.25 * (q.v[0][0] + q.v[1][0] + q.v[2][0] + q.v[3][0]),
                    0.25 * (q.v[0][1] + q.v[1][1] + q.v[2][1] + q.v[3][1]),
                )
            };
            let (_, _, light) = self.grid.sample(u, v);
            let val = q.rgb.map(|c| c * light);
            for &(y, x0, x1) in &spans {
                let y = y as usize;
                let ty = y / TILE;
                for t in
                    ty * self.tiles_x + x0 as usize / TILE..=ty * self.tiles_x + x1 as usize / TILE
                {
                    if !self.tile_dirty[t] {
                        self.tile_dirty[t] = true;
                        self.prev_tiles.push(t as u32);
                    }
                }
                for x in x0 as usize..=x1 as usize {
                    let p = y * self.w + x;
                    let mut rm = self.rod_mask[p];
                    if rm != 0 {
                        // A ray from above meets a face that lies above the rod's top first.
                        let rod = &g.rods[rm as usize - 1];
                        if q.zmin > rod.z + rod.r {
                            rm = 0;
                        }
                    }
                    let wall = self.tile_wall[ty * self.tiles_x + x / TILE];
                    if rm != 0 || wall {
                        let (d, _, _) = self.grid.sample(x as f32, y as f32);
                        let nd = q.n[0] * d[0] + q.n[1] * d[1] + q.n[2] * d[2];
                        let t_face = if q.disc || nd.abs() < 1e-6 {
                            q.dist
                        } else {
                            (q.n[0] * (q.c[0] - self.origin[0])
                                + q.n[1] * (q.c[1] - self.origin[1])
                                + q.n[2] * (q.c[2] - self.origin[2]))
                                / nd
                        };
                        if rm != 0 {
                            let rod = &g.rods[rm as usize - 1];
                            if let Some((t, yh)) = rod_hit(rod.x, rod.z, rod.r, self.origin, d) {
                                if t < t_face && yh >= rod.y_lo && yh <= rod.y_hi {
                                    continue;
                                }
                            }
                        }
                        if wall && self.table.trace_walls(self.origin, d) < t_face {
                            continue;
                        }
                    }
                    let rgb = if q.disc {
                        let dx = x as f32 - u;
                        let dy = y as f32 - v;
                        let r = q.v[1][0];
                        let nz = (1.0 - (dx * dx + dy * dy) / (r * r)).max(0.0).sqrt();
                        let sh = amb + (1.0 - amb) * nz;
                        val.map(|c| c * sh)
                    } else {
                        val
                    };
                    match (ch, bayer) {
                        (3, _) => rad[p * 3..p * 3 + 3].copy_from_slice(&rgb),
                        (_, Some(bp)) => rad[p] = rgb[bp[(y & 1) * 2 + (x & 1)] as usize],
                        _ => rad[p] = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2],
                    }
                }
            }
        }
        self.rad = rad;
        let _ = w;
        for &t in &self.prev_tiles {
            self.tile_dirty[t as usize] = false;
        }
        self.spans = spans;
    }

    fn shade_marker_fast(&mut self, i: usize, a: usize, b: usize, g: &WorldGeom, shader: &Shader) {
        let rod = &g.rods[i];
        let ch = self.ch;
        for sp in &self.strips[i].px[a..b] {
            let p = sp.idx as usize;
            let sample = crate::geom::RodSample {
                t: 0.0,
                y: sp.y,
                a: sp.a,
                shade: sp.shade,
                spec: sp.spec,
                hu: sp.hu,
                hpsi: sp.hpsi,
                alpha: sp.alpha,
            };
            let v = shader.rod_grey(rod, &sample);
            for c in 0..ch {
                let k = p * ch + c;
                self.rad[k] = sp.alpha * v + (1.0 - sp.alpha) * sp.bg0[c];
            }
        }
    }

    /// Fast mode: one ray against the moving objects; written only where one is hit and no rod
    /// is in front of it (elsewhere the image already holds the table, rods and markers).
    fn shade_object_fast(
        &mut self,
        x: usize,
        y: usize,
        g: &WorldGeom,
        shader: &Shader,
        cands: &[Obj],
        rods: u64,
    ) {
        let p = y * self.w + x;
        let (d, _, l) = self.sub_ray(x, y, 0.0, 0.0);
        let t_max = self.t_max(x, y, d);
        let Some(hit) = shader.trace(g, cands, self.origin, d, 0.0, t_max, None) else {
            return;
        };
        let mut m = rods;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let rod = &g.rods[i];
            if let Some((t, yh)) = rod_hit(rod.x, rod.z, rod.r, self.origin, d) {
                if t < hit.t && yh >= rod.y_lo && yh <= rod.y_hi {
                    return;
                }
            }
        }
        let mut rad = std::mem::take(&mut self.rad);
        self.put(&mut rad, p, hit.rgb.map(|v| v * l));
        self.rad = rad;
    }

    /// Quality mode: `sub x sub` sub-samples (4 or 2), each at its own time, against `cands`,
    /// over the table.
    #[allow(clippy::needless_range_loop)]
    fn shade_pixel_quality(
        &mut self,
        x: usize,
        y: usize,
        geoms: &[WorldGeom],
        shader: &Shader,
        cands: &[Obj],
        sub: usize,
    ) {
        let p = y * self.w + x;
        let ch = self.ch;
        let mut acc = [0.0f32; 3];
        let n = sub * sub;
        for s in 0..n {
            let fx = ((s % sub) as f32 + 0.5) / sub as f32 - 0.5;
            let fy = ((s / sub) as f32 + 0.5) / sub as f32 - 0.5;
            let slot = if sub == QSUB {
                QTIME[s]
            } else {
                [0, 2, 3, 1][s % 4]
            };
            let g = &geoms[slot * geoms.len() / n];
            let (d, foot, light) = self.sub_ray(x, y, fx, fy);
            let foot = foot / sub as f32;
            let t_max = self.t_max(x, y, d);
            match shader.trace(g, cands, self.origin, d, foot, t_max, None) {
                Some(hit) => {
                    for c in 0..ch {
                        let v = if ch == 3 {
                            hit.rgb[c]
                        } else {
                            self.pick(hit.rgb, x, y)
                        };
                        acc[c] += hit.alpha * v * light + (1.0 - hit.alpha) * self.bg0[p * ch + c];
                    }
                }
                None => {
                    for c in 0..ch {
                        acc[c] += self.bg0[p * ch + c];
                    }
                }
            }
        }
        for c in 0..ch {
            self.rad[p * ch + c] = acc[c] / n as f32;
        }
    }

    fn noise_params(&self) -> (f32, f32) {
        let gain = self.cam.noise.gain_e_per_dn;
        let inv_gain = if gain.is_finite() && gain > 0.0 {
            (1.0 / gain) as f32
        } else {
            0.0
        };
        let read2 = (self.cam.noise.read_noise_dn * self.cam.noise.read_noise_dn) as f32;
        (inv_gain, read2)
    }

    /// Makes the noisy copies of the still image used by the fast path of [`Self::finish`].
    fn build_noisy_copies(&mut self, noise: &[f32], seed: u64) {
        let n = if self.cam.noise.is_none() {
            1
        } else {
            NOISY_COPIES
        };
        let rad = std::mem::replace(&mut self.rad, self.bg.clone());
        let mut copies = Vec::with_capacity(n);
        // Antithetic pairs (noise n and -n): per pixel the copies' noise has exactly zero mean
        // and, on average, the model's variance (8 independent draws would show 7/8 of it).
        let half = n.div_ceil(2);
        for k in 0..n {
            let mut out = vec![0u8; self.w * self.h * self.ch];
            let sign = if k >= half { -1.0 } else { 1.0 };
            let seed = hash_words(&[seed, (k % half) as u64]);
            self.finish_full(1.0, 0.0, noise, seed, sign, &mut out);
            copies.push(out);
        }
        self.rad = rad;
        self.noisy_bg = copies;
    }

    /// Light level, glare, noise and quantisation. When the light is as in the still image,
    /// rows come from a noisy copy of it (chosen at random per row) and only the pixels drawn
    /// this frame (marker ranges and object tiles) get fresh noise.
    fn finish(&mut self, brightness: f32, glare: f32, noise: &[f32], seed: u64, out: &mut [u8]) {
        let still = brightness == 1.0 && (glare <= 0.0 || self.glare.is_none());
        if !still {
            self.finish_full(brightness, glare, noise, seed, 1.0, out);
            return;
        }
        let rw = self.w * self.ch;
        let mut rng = Rng::new(hash_words(&[seed, 0x00C0_B1E5]));
        let nc = self.noisy_bg.len() as u64;
        for (y, row) in out.chunks_exact_mut(rw).take(self.h).enumerate() {
            let v = rng.below(nc) as usize;
            row.copy_from_slice(&self.noisy_bg[v][y * rw..(y + 1) * rw]);
        }
        let (inv_gain, read2) = self.noise_params();
        let noisy = !self.cam.noise.is_none() && noise.len() > 2 * rw;
        let span = (noise.len().saturating_sub(rw)).max(1) as u64;
        let ch = self.ch;
        for &t in &self.prev_tiles {
            let r = self.tile_rect(t as usize);
            for y in r.y0..r.y1 {
                let a = (y * self.w + r.x0) * ch;
                let b = (y * self.w + r.x1) * ch;
                let off = rng.below(span) as usize;
                let nz = if noisy {
                    &noise[off..off + (b - a)]
                } else {
                    &[][..]
                };
                quantise_span(
                    &self.rad[a..b],
                    nz,
                    &mut out[a..b],
                    1.0,
                    read2,
                    inv_gain,
                    1.0,
                );
            }
        }
        for &(i, a, b) in &self.prev_ranges {
            let off = rng.below(span) as usize;
            for (j, sp) in self.strips[i].px[a..b].iter().enumerate() {
                let p = sp.idx as usize * ch;
                let nz = if noisy {
                    &noise[(off + j * ch) % span as usize..][..ch]
                } else {
                    &[][..]
                };
                quantise_span(
                    &self.rad[p..p + ch],
                    nz,
                    &mut out[p..p + ch],
                    1.0,
                    read2,
                    inv_gain,
                    1.0,
                );
            }
        }
    }

    /// Light level, glare, noise (times `sign`) and quantisation over the whole frame.
    #[allow(clippy::too_many_arguments)]
    fn finish_full(
        &self,
        brightness: f32,
        glare: f32,
        noise: &[f32],
        seed: u64,
        sign: f32,
        out: &mut [u8],
    ) {
        let rw = self.w * self.ch;
        let (inv_gain, read2) = self.noise_params();
        let noisy = !self.cam.noise.is_none() && noise.len() > rw;
        let mut rng = Rng::new(hash_words(&[seed, 0x004E_015E]));
        let span = (noise.len().saturating_sub(rw)).max(1) as u64;
        let glare_map = self.glare.as_deref().filter(|_| glare > 0.0);
        for (y, row) in out.chunks_exact_mut(rw).take(self.h).enumerate() {
            let rad = &self.rad[y * rw..(y + 1) * rw];
            if noisy {
                let off = rng.below(span) as usize;
                let nz = &noise[off..off + rw];
                match glare_map {
                    Some(gm) => {
                        let gr = &gm[y * rw..(y + 1) * rw];
                        for (((o, &r), &n), &g) in row.iter_mut().zip(rad).zip(nz).zip(gr) {
                            let v = r * brightness + g * glare;
                            let s = (read2 + v.max(0.0) * inv_gain).sqrt();
                            *o = quantise(v + sign * s * n);
                        }
                    }
                    None => quantise_span(rad, nz, row, brightness, read2, inv_gain, sign),
                }
            } else {
                for (i, (o, &r)) in row.iter_mut().zip(rad).enumerate() {
                    let g = glare_map.map(|m| m[y * rw + i]).unwrap_or(0.0);
                    *o = quantise(r * brightness + g * glare);
                }
            }
        }
    }
}

/// `out = quantise(b r + sign sigma(b r) n)`; no noise when `nz` is empty.
#[inline]
fn quantise_span(
    rad: &[f32],
    nz: &[f32],
    out: &mut [u8],
    b: f32,
    read2: f32,
    inv_gain: f32,
    sign: f32,
) {
    if nz.is_empty() {
        for (o, &r) in out.iter_mut().zip(rad) {
            *o = quantise(r * b);
        }
        return;
    }
    for ((o, &r), &n) in out.iter_mut().zip(rad).zip(nz) {
        let v = r * b;
        let s = (read2 + v.max(0.0) * inv_gain).sqrt();
        *o = quantise(v + sign * s * n);
    }
}

/// Rounds to the nearest DN and clips to 0..255 (integer clamp: vectorises).
#[inline(always)]
fn quantise(v: f32) -> u8 {
    ((v + 0.5) as i32).clamp(0, 255) as u8
}

/// Rays (world directions), pixel angular sizes and light factors on a grid every
/// `RayGrid::STEP` pixels, interpolated bilinearly: about 0.3 MB instead of 25 MB of per-pixel
/// tables, so it stays in cache. Interpolation error is about 0.01 px at the image corners.
#[derive(Debug, Clone)]
struct RayGrid {
    gw: usize,
    gh: usize,
    nodes: Vec<[f32; 5]>,
}

impl RayGrid {
    const STEP: usize = 8;

    fn new(cam: &SimCamera, light_of: &dyn Fn([f64; 3]) -> f32) -> RayGrid {
        let s = Self::STEP;
        let (w, h) = (cam.camera.width, cam.camera.height);
        let gw = (w - 1) / s + 2;
        let gh = (h - 1) / s + 2;
        let k = &cam.camera.intrinsics;
        let pose = &cam.camera.pose;
        let dir = |u: f64, v: f64| {
            let (nx, ny) = k.pixel_to_normalized(u, v);
            pose.dir_to_world([nx, ny, 1.0])
        };
        let mut nodes = Vec::with_capacity(gw * gh);
        for j in 0..gh {
            for i in 0..gw {
                let (u, v) = ((i * s) as f64, (j * s) as f64);
                let dw = dir(u, v);
                let d = norm(dw);
                let d1 = norm(dir(u + 1.0, v));
                let foot =
                    ((d1[0] - d[0]).powi(2) + (d1[1] - d[1]).powi(2) + (d1[2] - d[2]).powi(2))
                        .sqrt();
                nodes.push([d[0], d[1], d[2], foot, light_of(dw)]);
            }
        }
        RayGrid { gw, gh, nodes }
    }

    /// (unit direction, angular size, light) at pixel position `(x, y)`.
    #[inline]
    fn sample(&self, x: f32, y: f32) -> (V3, f32, f32) {
        let inv = 1.0 / Self::STEP as f32;
        let gx = (x * inv).clamp(0.0, (self.gw - 1) as f32 - 1e-3);
        let gy = (y * inv).clamp(0.0, (self.gh - 1) as f32 - 1e-3);
        let i = gx as usize;
        let j = gy as usize;
        let fx = gx - i as f32;
        let fy = gy - j as f32;
        let k = j * self.gw + i;
        let (a, b, c, d) = (
            &self.nodes[k],
            &self.nodes[k + 1],
            &self.nodes[k + self.gw],
            &self.nodes[k + self.gw + 1],
        );
        let mut o = [0.0f32; 5];
        for m in 0..5 {
            o[m] = (a[m] + (b[m] - a[m]) * fx) * (1.0 - fy) + (c[m] + (d[m] - c[m]) * fx) * fy;
        }
        let n = 1.0 / (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
        ([o[0] * n, o[1] * n, o[2] * n], o[3], o[4])
    }
}

/// A table of standard normal values for the noise (indexed at random offsets per row).
pub(crate) fn noise_table(len: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed);
    (0..len).map(|_| rng.gaussian() as f32).collect()
}
