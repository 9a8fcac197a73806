//! The static table: field with lines, walls, floor.

use super::ray::{inv_dir, ray_box, V3};
use super::world::WBox;
use crate::scene::SceneConfig;

/// Static table geometry: field with lines, walls, floor.
#[derive(Debug, Clone)]
pub(crate) struct Table {
    l: f32,
    w: f32,
    floor_z: f32,
    walls: Vec<WBox>,
    field: V3,
    lines: V3,
    wall: V3,
    floor: V3,
    ambient: f32,
}

impl Table {
    pub fn new(scene: &SceneConfig) -> Table {
        let l = scene.field_length_mm as f32;
        let w = scene.field_width_mm as f32;
        let t = scene.wall_thickness_mm as f32;
        let h = scene.wall_height_mm as f32;
        let walls = vec![
            WBox {
                lo: [-t, -t, -40.0],
                hi: [l + t, 0.0, h],
            },
            WBox {
                lo: [-t, w, -40.0],
                hi: [l + t, w + t, h],
            },
            WBox {
                lo: [-t, 0.0, -40.0],
                hi: [0.0, w, h],
            },
            WBox {
                lo: [l, 0.0, -40.0],
                hi: [l + t, w, h],
            },
        ];
        let f = |v: [f64; 3]| v.map(|x| x as f32);
        let c = &scene.colours;
        Table {
            l,
            w,
            floor_z: scene.floor_z_mm as f32,
            walls,
            field: f(c.field),
            lines: f(c.lines),
            wall: f(c.wall),
            floor: f(c.floor),
            ambient: scene.lighting.ambient as f32,
        }
    }

    /// Distance to the nearest wall along a ray (infinite if none).
    pub fn trace_walls(&self, o: V3, d: V3) -> f32 {
        let inv = inv_dir(d);
        self.walls
            .iter()
            .filter_map(|b| ray_box(o, inv, b.lo, b.hi).map(|h| h.0))
            .fold(f32::INFINITY, f32::min)
    }

    /// (distance, colour) of the static background along a ray.
    pub fn trace(&self, o: V3, d: V3) -> (f32, V3) {
        let inv = inv_dir(d);
        let mut best = (f32::INFINITY, [0.0; 3]);
        for b in &self.walls {
            if let Some((t, axis, sign)) = ray_box(o, inv, b.lo, b.hi) {
                if t < best.0 {
                    let sh = if axis == 2 && sign > 0.0 {
                        1.0
                    } else {
                        self.ambient + 0.15
                    };
                    best = (t, self.wall.map(|v| v * sh));
                }
            }
        }
        if d[2] < 0.0 {
            let t = -o[2] / d[2];
            if t < best.0 {
                let x = o[0] + t * d[0];
                let y = o[1] + t * d[1];
                if x >= 0.0 && x <= self.l && y >= 0.0 && y <= self.w {
                    let cx = x - 0.5 * self.l;
                    let cy = y - 0.5 * self.w;
                    let rr = (cx * cx + cy * cy).sqrt();
                    let line = cx.abs() < 2.5 || (rr - 100.0).abs() < 2.5;
                    best = (t, if line { self.lines } else { self.field });
                }
            }
            let t = (self.floor_z - o[2]) / d[2];
            if t < best.0 {
                best = (t, self.floor);
            }
        }
        best
    }
}
