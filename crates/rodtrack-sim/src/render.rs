//! Per-camera renderer: precomputed ray table, cached static background, fixed rod strips,
//! dirty rectangles for what moves, then one pass of light, noise and quantisation.
//!
//! Fast mode: one ray per pixel; the marker is box-filtered analytically over the pixel
//! footprint (and over the motion during the exposure), rod silhouettes are antialiased by
//! coverage. Quality mode: 4 x 4 sub-samples per pixel, each at its own time in the exposure.

use crate::cameras::SimCamera;
use crate::geom::{rod_sample, Obj, Shader, Table, WorldGeom, V3};
use crate::rng::{hash_words, Rng};
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
    rays: Vec<V3>,
    /// Table only (DN at brightness 1), `ch` values per pixel: what a rod is blended over.
    bg0: Vec<f32>,
    /// Table plus bare steel rods: the image with nothing moving and no marker.
    bg: Vec<f32>,
    bg_t: Vec<f32>,
    /// Light factor per pixel (gradient times DN scale).
    light: Vec<f32>,
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
        // Ray table: exact undistortion per pixel.
        let k = &cam.camera.intrinsics;
        let mut rays = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let (nx, ny) = k.pixel_to_normalized(x as f64, y as f64);
                rays.push(norm(cam.camera.pose.dir_to_world([nx, ny, 1.0])));
            }
        }
        let dn_scale = 235.0 * cam.brightness * cam.exposure_us / 500.0;
        // Light map from where each pixel's ray meets the rods' plane.
        let (sg, cg) = lighting.gradient_dir_rad.sin_cos();
        let hl = 0.5 * scene.field_length_mm;
        let hw = 0.5 * scene.field_width_mm;
        let extent = hl * cg.abs() + hw * sg.abs();
        let lnr = lighting.gradient_ratio.max(1e-6).ln();
        let plane_z = scene.rods.first().map(|r| r.z_mm).unwrap_or(80.0);
        let light: Vec<f32> = rays
            .iter()
            .map(|d| {
                let t = (plane_z - c[2]) / d[2] as f64;
                let x = c[0] + t * d[0] as f64 - hl;
                let y = c[1] + t * d[1] as f64 - hw;
                let s = ((x * cg + y * sg) / extent).clamp(-1.5, 1.5);
                (dn_scale * (0.5 * lnr * s).exp()) as f32
            })
            .collect();
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
            rays,
            bg0: vec![0.0; w * h * ch],
            bg: Vec::new(),
            bg_t: vec![0.0; w * h],
            light,
            glare,
            strips: Vec::new(),
            tile_rods: vec![0; tiles_x * tiles_y],
            tiles_x,
            rad: Vec::new(),
            prev_tiles: Vec::new(),
            prev_ranges: Vec::new(),
            tile_objs: vec![Vec::new(); tiles_x * tiles_y],
            touched: Vec::new(),
            stats: RenderStats::default(),
        };
        let sub = match mode {
            RenderMode::Fast => 2,
            RenderMode::Quality => QSUB,
        };
        r.render_background(&Table::new(scene), sub);
        r.build_strips(scene, shader);
        r.rad = r.bg.clone();
        r
    }

    /// Angular size of pixel `(x, y)` (from the ray table).
    #[inline]
    fn foot(&self, x: usize, y: usize) -> f32 {
        let i = y * self.w + x;
        let j = if x + 1 < self.w { i + 1 } else { i - 1 };
        let (a, b) = (self.rays[i], self.rays[j]);
        let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    }

    /// The ray through sub-pixel position `(x + fx, y + fy)` (`fx, fy` in `[-0.5, 0.5]`),
    /// bilinear in the ray table.
    #[inline]
    fn sub_ray(&self, x: usize, y: usize, fx: f32, fy: f32) -> V3 {
        let x1 = if fx >= 0.0 {
            (x + 1).min(self.w - 1)
        } else {
            x.saturating_sub(1)
        };
        let y1 = if fy >= 0.0 {
            (y + 1).min(self.h - 1)
        } else {
            y.saturating_sub(1)
        };
        let (ax, ay) = (fx.abs(), fy.abs());
        let r00 = self.rays[y * self.w + x];
        let r10 = self.rays[y * self.w + x1];
        let r01 = self.rays[y1 * self.w + x];
        let r11 = self.rays[y1 * self.w + x1];
        let mut d = [0.0f32; 3];
        for k in 0..3 {
            d[k] = (r00[k] * (1.0 - ax) + r10[k] * ax) * (1.0 - ay)
                + (r01[k] * (1.0 - ax) + r11[k] * ax) * ay;
        }
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        [d[0] / n, d[1] / n, d[2] / n]
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

    fn render_background(&mut self, table: &Table, sub: usize) {
        let n = sub * sub;
        let mut bg0 = std::mem::take(&mut self.bg0);
        for y in 0..self.h {
            for x in 0..self.w {
                let p = y * self.w + x;
                let mut acc = [0.0f32; 3];
                for s in 0..n {
                    let fx = ((s % sub) as f32 + 0.5) / sub as f32 - 0.5;
                    let fy = ((s / sub) as f32 + 0.5) / sub as f32 - 0.5;
                    let d = self.sub_ray(x, y, fx, fy);
                    let (_, c) = table.trace(self.origin, d);
                    for k in 0..3 {
                        acc[k] += c[k];
                    }
                }
                let (t, _) = table.trace(self.origin, self.rays[p]);
                self.bg_t[p] = t;
                let rgb = acc.map(|v| v / n as f32 * self.light[p]);
                self.put(&mut bg0, p, rgb);
            }
        }
        self.bg0 = bg0;
    }

    /// Finds every rod's pixels and bakes the bare steel rods into `bg`.
    fn build_strips(&mut self, scene: &SceneConfig, shader: &Shader) {
        let amb = shader.ambient;
        let mut bg = self.bg0.clone();
        let steel = shader.steel;
        let ss = shader.steel_spec;
        for (ri, rc) in scene.rods.iter().enumerate() {
            let (x, z, r) = (rc.x_mm as f32, rc.z_mm as f32, rc.radius_mm() as f32);
            let mut s = Strip::default();
            let mut bb: Option<Rect> = None;
            for py in 0..self.h {
                for px in 0..self.w {
                    let p = py * self.w + px;
                    let foot = self.foot(px, py);
                    let Some(h) = rod_sample(x, z, r, self.origin, self.rays[p], foot, amb) else {
                        continue;
                    };
                    if h.t >= self.bg_t[p] {
                        continue;
                    }
                    let sp = StripPx {
                        idx: p as u32,
                        y: h.y,
                        a: h.a,
                        shade: h.shade * self.light[p],
                        spec: h.spec * self.light[p],
                        hu: h.hu,
                        hpsi: h.hpsi,
                        alpha: h.alpha,
                    };
                    let v = sp.shade * steel + sp.spec * ss;
                    for c in 0..self.ch {
                        let k = p * self.ch + c;
                        bg[k] = sp.alpha * v + (1.0 - sp.alpha) * bg[k];
                    }
                    s.px.push(sp);
                    let b = bb.get_or_insert(Rect {
                        x0: px,
                        y0: py,
                        x1: px + 1,
                        y1: py + 1,
                    });
                    b.x0 = b.x0.min(px);
                    b.x1 = b.x1.max(px + 1);
                    b.y0 = b.y0.min(py);
                    b.y1 = b.y1.max(py + 1);
                    if ri < 64 {
                        self.tile_rods[(py / TILE) * self.tiles_x + px / TILE] |= 1u64 << ri;
                    }
                }
            }
            s.px.sort_by(|a, b| a.y.total_cmp(&b.y));
            s.bbox = bb;
            self.strips.push(s);
        }
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
                        self.shade_pixel_quality(p % self.w, p / self.w, geoms, shader, &cands);
                    }
                }
            }
            self.prev_ranges.push((i, a, b));
            marker_px += b - a;
        }
        let t_markers = t_start.elapsed();
        // 3. Figures, hands, ball.
        self.collect_tiles(geoms, shader);
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
                            self.shade_pixel_quality(x, y, geoms, shader, &cands);
                        }
                    }
                }
            }
        }
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
            object_cands: self.touched.iter().map(|&t| self.tile_objs[t as usize].len()).sum(),
        };
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
                self.rad[k] = sp.alpha * v + (1.0 - sp.alpha) * self.bg0[k];
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
        let d = self.rays[p];
        let Some(hit) = shader.trace(g, cands, self.origin, d, 0.0, self.bg_t[p], None) else {
            return;
        };
        let mut m = rods;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let rod = &g.rods[i];
            if let Some(s) = rod_sample(rod.x, rod.z, rod.r, self.origin, d, 0.0, 0.0) {
                if s.t < hit.t && s.y >= rod.y_lo && s.y <= rod.y_hi {
                    return;
                }
            }
        }
        let l = self.light[p];
        let mut rad = std::mem::take(&mut self.rad);
        self.put(&mut rad, p, hit.rgb.map(|v| v * l));
        self.rad = rad;
    }

    /// Quality mode: 4 x 4 sub-samples, each at its own time, against `cands`, over the table.
    fn shade_pixel_quality(
        &mut self,
        x: usize,
        y: usize,
        geoms: &[WorldGeom],
        shader: &Shader,
        cands: &[Obj],
    ) {
        let p = y * self.w + x;
        let ch = self.ch;
        let light = self.light[p];
        let t_max = self.bg_t[p];
        let mut acc = [0.0f32; 3];
        let foot = self.foot(x, y) / QSUB as f32;
        let n = QSUB * QSUB;
        for s in 0..n {
            let fx = ((s % QSUB) as f32 + 0.5) / QSUB as f32 - 0.5;
            let fy = ((s / QSUB) as f32 + 0.5) / QSUB as f32 - 0.5;
            let g = &geoms[QTIME[s] * geoms.len() / n];
            let d = self.sub_ray(x, y, fx, fy);
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

    fn finish(&self, brightness: f32, glare: f32, noise: &[f32], seed: u64, out: &mut [u8]) {
        let rw = self.w * self.ch;
        let gain = self.cam.noise.gain_e_per_dn;
        let inv_gain = if gain.is_finite() && gain > 0.0 {
            (1.0 / gain) as f32
        } else {
            0.0
        };
        let read2 = (self.cam.noise.read_noise_dn * self.cam.noise.read_noise_dn) as f32;
        let noisy = !self.cam.noise.is_none() && noise.len() > rw;
        let mut rng = Rng::new(hash_words(&[seed, 0x4E01_5E]));
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
                            *o = quantise(v + s * n);
                        }
                    }
                    None => {
                        for ((o, &r), &n) in row.iter_mut().zip(rad).zip(nz) {
                            let v = r * brightness;
                            let s = (read2 + v.max(0.0) * inv_gain).sqrt();
                            *o = quantise(v + s * n);
                        }
                    }
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

/// Rounds to the nearest DN and clips to 0..255 (integer clamp: vectorises).
#[inline(always)]
fn quantise(v: f32) -> u8 {
    ((v + 0.5) as i32).clamp(0, 255) as u8
}

/// A table of standard normal values for the noise (indexed at random offsets per row).
pub(crate) fn noise_table(len: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed);
    (0..len).map(|_| rng.gaussian() as f32).collect()
}
