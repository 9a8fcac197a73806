//! The ball's truth and the table frame: the ball's centre and velocity in table millimetres
//! per frame, the fraction of the ball each camera sees, and the camera's true pose in the
//! table frame (SPEC section 9: origin at the field's centre, `x` along the table towards the
//! goal at world `x = field_length_mm`, `y` across, `z` up).

use crate::geom::{Obj, Table, WorldGeom, WorldState, V3};
use crate::sim::{frame_time, Ctx, Simulation};
use crate::SimError;
use rodtrack_core::linalg_small::{cross, normalise3};
use rodtrack_core::{Pose, Timestamp};

/// One frame of the ball's truth.
#[derive(Debug, Clone, PartialEq)]
pub struct BallTruthRow {
    /// Frame id.
    pub frame: u64,
    /// Trigger time.
    pub timestamp_ns: Timestamp,
    /// Centre at mid-exposure, table frame, mm.
    pub x_mm: f64,
    /// Centre at mid-exposure, table frame, mm.
    pub y_mm: f64,
    /// Velocity, mm/s.
    pub vx_mm_s: f64,
    /// Velocity, mm/s.
    pub vy_mm_s: f64,
    /// Fraction of the ball's image each camera sees (inside the image, not hidden by a rod,
    /// a figure or a hand), camera order.
    pub visible: Vec<f64>,
}

/// The truth CSV's header for `cameras` cameras.
pub fn ball_truth_header(cameras: usize) -> String {
    let mut h = String::from("frame,timestamp_s,x_mm,y_mm,vx_mm_s,vy_mm_s");
    for c in 0..cameras {
        h.push_str(&format!(",visible_{c}"));
    }
    h
}

impl BallTruthRow {
    /// One CSV line.
    pub fn csv_line(&self) -> String {
        let mut s = format!(
            "{},{:.6},{:.4},{:.4},{:.2},{:.2}",
            self.frame,
            self.timestamp_ns.as_secs_f64(),
            self.x_mm,
            self.y_mm,
            self.vx_mm_s,
            self.vy_mm_s
        );
        for v in &self.visible {
            s.push_str(&format!(",{v:.3}"));
        }
        s
    }
}

/// Rays per ball for the visible fraction: rings of the ball's image disc.
const RINGS: usize = 5;
const PER_RING: usize = 12;

impl Ctx {
    /// World to table: the field's centre is the origin.
    pub fn world_to_table(&self, p: [f64; 2]) -> [f64; 2] {
        [
            p[0] - 0.5 * self.scene.field_length_mm,
            p[1] - 0.5 * self.scene.field_width_mm,
        ]
    }

    /// The fraction of the ball at `c` (world) that camera `cam` sees.
    pub fn ball_visible_fraction(&self, cam: usize, g: &WorldGeom, c: [f64; 3]) -> f64 {
        let camera = &self.cameras[cam].camera;
        let r = 0.5 * self.scene.ball_diameter_mm;
        let o = camera.pose.centre_world();
        let w = [c[0] - o[0], c[1] - o[1], c[2] - o[2]];
        let dist = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
        if dist <= r {
            return 0.0;
        }
        let a = w.map(|v| v / dist);
        // A basis across the viewing direction.
        let t = if a[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let e1 = normalise3(cross(a, t));
        let e2 = cross(a, e1);
        let tan_half = r / (dist * dist - r * r).sqrt();
        let mut cands: Vec<Obj> = Vec::new();
        for (i, rod) in g.rods.iter().enumerate() {
            cands.push(Obj::Rod(i as u16));
            for k in 0..rod.figs.len() {
                cands.push(Obj::Figure(i as u16, k as u16));
            }
        }
        for k in 0..g.hand_boxes.len() {
            cands.push(Obj::Hand(k as u16));
        }
        let of: V3 = o.map(|v| v as f32);
        // The walls hide a ball that runs into one (the end walls have no goal opening), as
        // the render does.
        let table = Table::new(&self.scene);
        let (wi, hi) = (camera.width as f64, camera.height as f64);
        let (mut seen, mut total) = (0.0, 0.0);
        for ring in 0..RINGS {
            let rho = (ring as f64 + 0.5) / RINGS as f64;
            for k in 0..PER_RING {
                let phi =
                    std::f64::consts::TAU * (k as f64 + 0.5 * (ring % 2) as f64) / PER_RING as f64;
                let s = tan_half * rho;
                let d = normalise3([
                    a[0] + s * (phi.cos() * e1[0] + phi.sin() * e2[0]),
                    a[1] + s * (phi.cos() * e1[1] + phi.sin() * e2[1]),
                    a[2] + s * (phi.cos() * e1[2] + phi.sin() * e2[2]),
                ]);
                // Nearest intersection with the sphere.
                let b = d[0] * w[0] + d[1] * w[1] + d[2] * w[2];
                let disc = b * b - (dist * dist - r * r);
                if disc < 0.0 {
                    continue;
                }
                let th = b - disc.sqrt();
                let p = [o[0] + th * d[0], o[1] + th * d[1], o[2] + th * d[2]];
                total += rho;
                let inside = matches!(camera.project(p), Some((u, v)) if u >= 0.5 && v >= 0.5 && u <= wi - 1.5 && v <= hi - 1.5);
                if !inside {
                    continue;
                }
                let df: V3 = d.map(|v| v as f32);
                if table.trace_walls(of, df) >= th as f32
                    && self
                        .shader
                        .trace(g, &cands, of, df, 0.0, (th - 0.5) as f32, None)
                        .is_none()
                {
                    seen += rho;
                }
            }
        }
        if total > 0.0 {
            seen / total
        } else {
            0.0
        }
    }

    /// The ball's truth for frame `frame_index`; `None` without a ball.
    pub fn ball_truth(&self, frame_index: usize) -> Option<BallTruthRow> {
        let path = self.scenario.ball.as_ref()?;
        let t0 = frame_index as f64 / self.scenario.fps;
        let exp = self.cameras.first().map_or(0.0, |c| c.exposure_us * 1e-6);
        let tm = t0 + 0.5 * exp;
        let st = WorldState::at(&self.scene, &self.scenario, tm);
        let g = WorldGeom::build(&self.scene, &st, 0.0);
        let (x, y) = path.at(tm)?;
        let (vx, vy) = path.velocity(tm);
        let c = [x, y, 0.5 * self.scene.ball_diameter_mm];
        let visible = (0..self.cameras.len())
            .map(|cam| self.ball_visible_fraction(cam, &g, c))
            .collect();
        let p = self.world_to_table([x, y]);
        Some(BallTruthRow {
            frame: frame_index as u64,
            timestamp_ns: frame_time(frame_index as u64, self.scenario.fps),
            x_mm: p[0],
            y_mm: p[1],
            vx_mm_s: vx,
            vy_mm_s: vy,
            visible,
        })
    }

    /// Where the ball lies for the ball's calibration frame of camera `cam`: between two rods
    /// near the image's centre, wholly visible; `None` if no such place.
    pub fn ball_click_position(&self, cam: usize) -> Option<[f64; 3]> {
        let c = &self.cameras[cam].camera;
        let o = c.pose.centre_world();
        let r = 0.5 * self.scene.ball_diameter_mm;
        let st = WorldState::posed(&self.reference);
        let g = WorldGeom::build(&self.scene, &st, 0.0);
        let mut xs: Vec<f64> = self.scene.rods.iter().map(|r| r.x_mm).collect();
        xs.sort_by(|a, b| a.total_cmp(b));
        let mut mids: Vec<f64> = xs.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
        mids.sort_by(|a, b| (a - o[0]).abs().total_cmp(&(b - o[0]).abs()));
        for x in mids {
            for dy in [60.0, -60.0, 120.0, -120.0] {
                let p = [x, o[1] + dy, r];
                if p[1] < 2.0 * r || p[1] > self.scene.field_width_mm - 2.0 * r {
                    continue;
                }
                let mut gb = g.clone();
                gb.ball = Some((p.map(|v| v as f32), r as f32));
                if self.ball_visible_fraction(cam, &gb, p) >= 0.999 {
                    return Some(p);
                }
            }
        }
        None
    }
}

impl Simulation {
    /// The ball's events as scripted (scenario `goals`), each at the first frame whose
    /// mid-exposure time is at or after the event's time, within the simulation's frames:
    /// what `rodtrack simulate` writes to `events_truth.jsonl`.
    pub fn events_truth(&self) -> Vec<rodtrack_core::ball::events::BallEvent> {
        let fps = self.ctx.scenario.fps;
        let exp = self
            .ctx
            .cameras
            .first()
            .map_or(0.0, |c| c.exposure_us * 1e-6);
        let n = self.frame_count() as u64;
        self.ctx
            .scenario
            .events
            .iter()
            .filter_map(|&(t, kind)| {
                let f = ((t - 0.5 * exp) * fps - 1e-9).ceil().max(0.0) as u64;
                (f < n).then_some(rodtrack_core::ball::events::BallEvent {
                    frame: f,
                    timestamp_ns: frame_time(f, fps),
                    kind,
                })
            })
            .collect()
    }

    /// The ball's truth for frame `frame_index` (table frame); `None` without a ball.
    pub fn ball_truth(&self, frame_index: usize) -> Option<BallTruthRow> {
        self.ctx.ball_truth(frame_index)
    }

    /// Where the ball lies in camera `cam`'s ball calibration frame (world, mm); `None` if no
    /// place between the rods shows it whole.
    pub fn ball_click_position(&self, cam: usize) -> Option<[f64; 3]> {
        self.ctx.ball_click_position(cam)
    }

    /// Camera `cam`'s true pose in the table frame (table to camera).
    pub fn table_pose(&self, cam: usize) -> Result<Pose, SimError> {
        let c = self.ctx.camera(cam)?;
        let p = c.camera.pose;
        // X_c = R X_w + t with X_w = X_t + s: t' = t + R s.
        let s = [
            0.5 * self.ctx.scene.field_length_mm,
            0.5 * self.ctx.scene.field_width_mm,
            0.0,
        ];
        let rs = p.to_camera(s);
        Ok(Pose {
            rotation: p.rotation,
            translation_mm: rs,
        })
    }

    /// Calibrates camera `cam` from its simulated clicks (`seed`) as `rodtrack calibrate` does
    /// from a recording: the rods and the table frame from the reference frame, the ball's
    /// colour from the ball frame ([`Simulation::render_ball_frame`]). For tests and benches
    /// of the ball.
    pub fn calibrated_camera_with_ball(
        &mut self,
        cam: usize,
        seed: u64,
    ) -> Result<rodtrack_core::calib::CameraCalibration, SimError> {
        let inputs = self.calibration_inputs(cam, seed)?;
        let mut reference = vec![0u8; self.frame_bytes(cam)?];
        let meta = self.render_reference(cam, &mut reference)?;
        let mut frames = vec![(0, reference)];
        if let (Some(b), Some(at)) = (&inputs.ball, self.ball_click_position(cam)) {
            let mut buf = vec![0u8; frames[0].1.len()];
            self.render_ball_frame(cam, at, &mut buf)?;
            frames.push((b.frame, buf));
        }
        let (w, h, st, f) = (meta.width, meta.height, meta.stride, meta.format);
        let views = frames
            .iter()
            .map(|(i, buf)| Ok((*i, rodtrack_core::FrameView::new(buf, w, h, st, f)?)))
            .collect::<Result<Vec<_>, SimError>>()?;
        let fps = 1.0 / self.timestamp_s(1).max(1e-6);
        Ok(rodtrack_core::calib::calibrate_camera(
            &inputs, &views, cam as u32, fps,
        )?)
    }

    /// Renders camera `cam`'s ball calibration frame: every rod at its reference pose, the
    /// ball at `ball_world_mm`.
    pub fn render_ball_frame(
        &mut self,
        cam: usize,
        ball_world_mm: [f64; 3],
        out: &mut [u8],
    ) -> Result<crate::RenderInfo, SimError> {
        let mut st = WorldState::posed(&self.ctx.reference);
        st.ball = Some(ball_world_mm);
        self.render_state(cam, &st, u64::MAX - 4096, out)
            .map(|m| crate::RenderInfo {
                frame_id: 0,
                timestamp_ns: Timestamp(0),
                ..m
            })
    }
}
