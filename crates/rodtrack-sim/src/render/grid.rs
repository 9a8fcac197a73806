//! The ray grid: rays, pixel footprints and light every few pixels, interpolated.

use crate::cameras::SimCamera;
use crate::geom::V3;

pub(super) fn norm(v: [f64; 3]) -> V3 {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [(v[0] / n) as f32, (v[1] / n) as f32, (v[2] / n) as f32]
}

/// Rays (world directions), pixel angular sizes and light factors on a grid every
/// `RayGrid::STEP` pixels, interpolated bilinearly: about 0.3 MB instead of 25 MB of per-pixel
/// tables, so it stays in cache. Interpolation error is about 0.01 px at the image corners.
#[derive(Debug, Clone)]
pub(super) struct RayGrid {
    gw: usize,
    gh: usize,
    nodes: Vec<[f32; 5]>,
}

impl RayGrid {
    const STEP: usize = 8;

    pub(super) fn new(cam: &SimCamera, light_of: &dyn Fn([f64; 3]) -> f32) -> RayGrid {
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
    pub(super) fn sample(&self, x: f32, y: f32) -> (V3, f32, f32) {
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
