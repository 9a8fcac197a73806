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
    fn overlaps(&self, o: &Rect) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }
    fn is_empty(&self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }
}

/// Pixels where a rod can appear, with everything about the hit that does not depend on the
/// rod's pose (the rod only slides along and turns about its own axis).
#[derive(Debug, Clone, Default)]
struct Strip {
    idx: Vec<u32>,
    y: Vec<f32>,
    a: Vec<f32>,
    shade: Vec<f32>,
    spec: Vec<f32>,
    hu: Vec<f32>,
    hpsi: Vec<f32>,
    alpha: Vec<f32>,
    bbox: Option<Rect>,
}

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
    /// Static background radiance (DN at brightness 1), `ch` values per pixel.
    bg: Vec<f32>,
    bg_t: Vec<f32>,
    /// Light factor per pixel (gradient times DN scale).
    light: Vec<f32>,
    glare: Option<Vec<f32>>,
    strips: Vec<Strip>,
    rad: Vec<f32>,
    dirty: Vec<Rect>,
    rects: Vec<(Rect, Vec<Obj>)>,
}

fn norm(v: [f64; 3]) -> V3 {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [(v[0] / n) as f32, (v[1] / n) as f32, (v[2] / n) as f32]
}

impl CameraRenderer {
    pub fn new(cam: &SimCamera, scene: &SceneConfig, lighting: &Lighting, shader: &Shader) -> Self {
        let (w, h) = (cam.camera.width, cam.camera.height);
        let bayer = bayer_pattern(cam.pixel_format);
        let ch = if cam.pixel_format == PixelFormat::Rgb8 {
            3
        } else {
            1
        };
        let c = cam.camera.pose.centre_world();
        let origin = c.map(|v| v as f32);
        // Ray table: exact undistortion per pixel, warm-started along each row.
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
        let mut r = CameraRenderer {
            cam: cam.clone(),
            w,
            h,
            ch,
            bayer,
            origin,
            rays,
            bg: vec![0.0; w * h * ch],
            bg_t: vec![0.0; w * h],
            light,
            glare,
            strips: Vec::new(),
            rad: vec![0.0; w * h * ch],
            dirty: Vec::new(),
            rects: Vec::new(),
        };
        r.render_background(&Table::new(scene));
        r.build_strips(scene, shader);
        r.rad.copy_from_slice(&r.bg);
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

    fn render_background(&mut self, table: &Table) {
        let n = QSUB * QSUB;
        for y in 0..self.h {
            for x in 0..self.w {
                let p = y * self.w + x;
                let mut acc = [0.0f32; 3];
                for s in 0..n {
                    let fx = ((s % QSUB) as f32 + 0.5) / QSUB as f32 - 0.5;
                    let fy = ((s / QSUB) as f32 + 0.5) / QSUB as f32 - 0.5;
                    let d = self.sub_ray(x, y, fx, fy);
                    let (_, c) = table.trace(self.origin, d);
                    for k in 0..3 {
                        acc[k] += c[k];
                    }
                }
                let (t, _) = table.trace(self.origin, self.rays[p]);
                self.bg_t[p] = t;
                let rgb = acc.map(|v| v / n as f32 * self.light[p]);
                if self.ch == 3 {
                    self.bg[p * 3..p * 3 + 3].copy_from_slice(&rgb);
                } else {
                    self.bg[p] = self.pick(rgb, x, y);
                }
            }
        }
    }

    fn build_strips(&mut self, scene: &SceneConfig, shader: &Shader) {
        let amb = shader.ambient;
        for rc in &scene.rods {
            let (x, z, r) = (rc.x_mm as f32, rc.z_mm as f32, rc.radius_mm() as f32);
            let mut s = Strip::default();
            let mut bb: Option<Rect> = None;
            for py in 0..self.h {
                for px in 0..self.w {
                    let p = py * self.w + px;
                    let foot = self.foot(px, py);
                    if let Some(h) = rod_sample(x, z, r, self.origin, self.rays[p], foot, amb) {
                        if h.t >= self.bg_t[p] {
                            continue;
                        }
                        s.idx.push(p as u32);
                        s.y.push(h.y);
                        s.a.push(h.a);
                        s.shade.push(h.shade * self.light[p]);
                        s.spec.push(h.spec * self.light[p]);
                        s.hu.push(h.hu);
                        s.hpsi.push(h.hpsi);
                        s.alpha.push(h.alpha);
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
                    }
                }
            }
            s.bbox = bb;
            self.strips.push(s);
        }
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
        let m = 3.0 + 0.04 * (u1 - u0).max(v1 - v0);
        let r = Rect {
            x0: (u0 - m).floor().clamp(0.0, self.w as f64) as usize,
            y0: (v0 - m).floor().clamp(0.0, self.h as f64) as usize,
            x1: (u1 + m).ceil().clamp(0.0, self.w as f64) as usize,
            y1: (v1 + m).ceil().clamp(0.0, self.h as f64) as usize,
        };
        (!r.is_empty()).then_some(r)
    }

    /// Collects the dirty rectangles of moving things over all time samples, with the
    /// candidate objects for each.
    fn collect_rects(&mut self, geoms: &[WorldGeom], shader: &Shader) {
        self.rects.clear();
        let mut objs: Vec<(Obj, Rect)> = Vec::new();
        let (blo, bhi) = shader.figure_bounds;
        let g0 = &geoms[0];
        let pick_times: Vec<&WorldGeom> = if geoms.len() > 2 {
            vec![&geoms[0], &geoms[geoms.len() / 2], &geoms[geoms.len() - 1]]
        } else {
            geoms.iter().collect()
        };
        let mut pts: Vec<[f64; 3]> = Vec::with_capacity(24);
        for (i, rod) in g0.rods.iter().enumerate() {
            for k in 0..rod.figs.len() {
                pts.clear();
                for g in &pick_times {
                    let rg = &g.rods[i];
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
                    objs.push((Obj::Figure(i as u16, k as u16), r));
                }
            }
        }
        for h in 0..g0.hand_boxes.len() {
            pts.clear();
            for g in &pick_times {
                let b = g.hand_boxes[h];
                for c in 0..8 {
                    pts.push([
                        if c & 1 == 0 { b.lo[0] } else { b.hi[0] } as f64,
                        if c & 2 == 0 { b.lo[1] } else { b.hi[1] } as f64,
                        if c & 4 == 0 { b.lo[2] } else { b.hi[2] } as f64,
                    ]);
                }
            }
            if let Some(r) = self.project_rect(&pts) {
                objs.push((Obj::Hand(h as u16), r));
            }
        }
        if g0.ball.is_some() {
            pts.clear();
            for g in &pick_times {
                if let Some((c, r)) = g.ball {
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
                objs.push((Obj::Ball, r));
            }
        }
        for (o, r) in &objs {
            let mut cands: Vec<Obj> = Vec::new();
            for (i, s) in self.strips.iter().enumerate() {
                if s.bbox.is_some_and(|b| b.overlaps(r)) {
                    cands.push(Obj::Rod(i as u16));
                }
            }
            for (o2, r2) in &objs {
                if o2 == o || r2.overlaps(r) {
                    cands.push(*o2);
                }
            }
            self.rects.push((*r, cands));
        }
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
        // 1. Restore what moved last frame.
        for r in std::mem::take(&mut self.dirty) {
            for y in r.y0..r.y1 {
                let a = (y * self.w + r.x0) * self.ch;
                let b = (y * self.w + r.x1) * self.ch;
                self.rad[a..b].copy_from_slice(&self.bg[a..b]);
            }
        }
        // 2. Rod strips.
        for i in 0..self.strips.len() {
            match mode {
                RenderMode::Fast => self.shade_strip_fast(i, &geoms[0], shader),
                RenderMode::Quality => self.shade_strip_quality(i, geoms, shader),
            }
        }
        // 3. Figures, hands, ball.
        self.collect_rects(geoms, shader);
        let rects = std::mem::take(&mut self.rects);
        for (r, cands) in &rects {
            for y in r.y0..r.y1 {
                for x in r.x0..r.x1 {
                    self.shade_pixel(x, y, geoms, shader, cands, mode);
                }
            }
            self.dirty.push(*r);
        }
        self.rects = rects;
        // 4. Light level, glare, noise, quantisation.
        self.finish(brightness, glare, noise, noise_seed, out);
    }

    fn shade_strip_fast(&mut self, i: usize, g: &WorldGeom, shader: &Shader) {
        let rod = &g.rods[i];
        let s = &self.strips[i];
        let ch = self.ch;
        for j in 0..s.idx.len() {
            let p = s.idx[j] as usize;
            let sample = crate::geom::RodSample {
                t: 0.0,
                y: s.y[j],
                a: s.a[j],
                shade: s.shade[j],
                spec: s.spec[j],
                hu: s.hu[j],
                hpsi: s.hpsi[j],
                alpha: s.alpha[j],
            };
            let v = shader.rod_grey(rod, &sample);
            let al = s.alpha[j];
            for c in 0..ch {
                let k = p * ch + c;
                self.rad[k] = al * v + (1.0 - al) * self.bg[k];
            }
        }
    }

    fn shade_strip_quality(&mut self, i: usize, geoms: &[WorldGeom], shader: &Shader) {
        let cands = [Obj::Rod(i as u16)];
        let idx = std::mem::take(&mut self.strips[i].idx);
        for &p in &idx {
            let p = p as usize;
            self.shade_pixel(
                p % self.w,
                p / self.w,
                geoms,
                shader,
                &cands,
                RenderMode::Quality,
            );
        }
        self.strips[i].idx = idx;
    }

    /// Full trace of one pixel against `cands`, falling back to the background.
    fn shade_pixel(
        &mut self,
        x: usize,
        y: usize,
        geoms: &[WorldGeom],
        shader: &Shader,
        cands: &[Obj],
        mode: RenderMode,
    ) {
        let p = y * self.w + x;
        let ch = self.ch;
        let light = self.light[p];
        let t_max = self.bg_t[p];
        let mut acc = [0.0f32; 3];
        let foot = self.foot(x, y);
        let n = match mode {
            RenderMode::Fast => 1,
            RenderMode::Quality => QSUB * QSUB,
        };
        for s in 0..n {
            let (d, g, f) = if n == 1 {
                (self.rays[p], &geoms[0], foot)
            } else {
                let fx = ((s % QSUB) as f32 + 0.5) / QSUB as f32 - 0.5;
                let fy = ((s / QSUB) as f32 + 0.5) / QSUB as f32 - 0.5;
                let ti = QTIME[s] * geoms.len() / (QSUB * QSUB);
                (self.sub_ray(x, y, fx, fy), &geoms[ti], foot / QSUB as f32)
            };
            match shader.trace(g, cands, self.origin, d, f, t_max, None) {
                Some(hit) => {
                    for c in 0..ch {
                        let v = if ch == 3 {
                            hit.rgb[c]
                        } else {
                            self.pick(hit.rgb, x, y)
                        };
                        acc[c] += hit.alpha * v * light + (1.0 - hit.alpha) * self.bg[p * ch + c];
                    }
                }
                None => {
                    for c in 0..ch {
                        acc[c] += self.bg[p * ch + c];
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
                            *o = (v + s * n + 0.5).clamp(0.0, 255.0) as u8;
                        }
                    }
                    None => {
                        for ((o, &r), &n) in row.iter_mut().zip(rad).zip(nz) {
                            let v = r * brightness;
                            let s = (read2 + v.max(0.0) * inv_gain).sqrt();
                            *o = (v + s * n + 0.5).clamp(0.0, 255.0) as u8;
                        }
                    }
                }
            } else {
                for (i, (o, &r)) in row.iter_mut().zip(rad).enumerate() {
                    let g = glare_map.map(|m| m[y * rw + i]).unwrap_or(0.0);
                    *o = (r * brightness + g * glare + 0.5).clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
}

/// A table of standard normal values for the noise (indexed at random offsets per row).
pub(crate) fn noise_table(len: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed);
    (0..len).map(|_| rng.gaussian() as f32).collect()
}
