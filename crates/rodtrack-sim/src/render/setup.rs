//! Building a camera's renderer: the ray grid, light and glare maps, the supersampled table,
//! the rod strips and the bare steel rods.

use super::grid::{norm, RayGrid};
use super::renderer::{CameraRenderer, Rect, RenderMode, RenderStats, Strip, StripPx, QSUB, TILE};
use crate::cameras::SimCamera;
use crate::geom::{rod_sample, Shader, Table};
use crate::scene::{Lighting, SceneConfig};
use rodtrack_core::PixelFormat;

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
            point_rays: None,
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
}
