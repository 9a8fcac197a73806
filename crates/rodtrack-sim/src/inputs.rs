//! The calibration inputs the simulator writes: the rods' clicked path points, the table's
//! field points and the ball's click (SPEC sections 5 and 9).

use crate::geom::{WorldGeom, WorldState};
use crate::rng::{hash_words, Rng};
use crate::sim::{CalibOptions, Ctx};
use crate::SimError;
use rodtrack_core::calib::{
    BallInputs, CalibrationInputs, ImageSize, KnownPose, OpencvModel, ReferenceFrames,
    ReferencePose, RodInputs, TableInputs, TablePoint,
};
use rodtrack_core::Status;

impl Ctx {
    pub fn calibration_inputs(
        &self,
        cam: usize,
        seed: u64,
        opts: &CalibOptions,
    ) -> Result<CalibrationInputs, SimError> {
        let c = self.camera(cam)?;
        let st = WorldState::posed(&self.reference);
        let g = WorldGeom::build(&self.scene, &st, 0.0);
        let mut rng = Rng::new(hash_words(&[seed, cam as u64, 0x000C_A11B]));
        let len = self.scene.marker_len_mm();
        let npts = opts.points_per_rod.clamp(3, 5);
        let mut rods = Vec::new();
        for (i, rc) in self.scene.rods.iter().enumerate() {
            if self.marker_status(cam, i, &st, &g) != Status::Ok {
                continue;
            }
            let h = rc.half_travel_mm();
            let ys = [
                rc.marker_y(0.0, -h),
                rc.marker_y(len, -h),
                rc.marker_y(0.0, h),
                rc.marker_y(len, h),
            ];
            let lo = ys.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let mut pts = Vec::new();
            for k in 0..npts {
                let f = 0.05 + 0.9 * k as f64 / (npts - 1) as f64;
                let y = lo + f * (hi - lo);
                if let Some((u, v)) = c.camera.project([rc.x_mm, y, rc.z_mm]) {
                    if u >= 0.0
                        && v >= 0.0
                        && u <= c.camera.width as f64 - 1.0
                        && v <= c.camera.height as f64 - 1.0
                    {
                        pts.push([
                            u + opts.click_noise_px * rng.gaussian(),
                            v + opts.click_noise_px * rng.gaussian(),
                        ]);
                    }
                }
            }
            if pts.len() < 3 {
                continue;
            }
            let (rp, ra) = self.reference[i];
            rods.push(RodInputs {
                rod: i as u32,
                path_points_px: pts,
                travel_mm: [-h, h],
                reference: ReferencePose {
                    frame: 0,
                    position_mm: rp,
                    angle_rad: ra,
                },
                known_poses: if opts.known_poses {
                    known_pose_list(i, h)
                        .into_iter()
                        .map(|(frame, position_mm)| KnownPose {
                            frame,
                            position_mm,
                            angle_rad: opts.known_pose_angles.then_some(ra),
                        })
                        .collect()
                } else {
                    Vec::new()
                },
                travel_frames: None,
                marker: self.scene.marker_spec_for(i),
            });
        }
        let table = opts
            .table_points
            .then(|| self.table_inputs(cam, seed, opts))
            .flatten();
        let ball = (opts.ball_click && table.is_some())
            .then(|| {
                let p = self.ball_click_position(cam)?;
                let (u, v) = c.camera.project(p)?;
                let mut rng = Rng::new(hash_words(&[seed, cam as u64, 0x0000_BA11]));
                Some(BallInputs {
                    frame: opts.ball_frame(self.scene.rods.len()),
                    px: [
                        u + opts.table_click_noise_px * rng.gaussian(),
                        v + opts.table_click_noise_px * rng.gaussian(),
                    ],
                    diameter_mm: self.scene.ball_diameter_mm,
                })
            })
            .flatten();
        let k = &c.camera.intrinsics;
        Ok(CalibrationInputs {
            camera_name: c.name.clone(),
            image_size: ImageSize {
                width: c.camera.width,
                height: c.camera.height,
            },
            pixel_format: c.pixel_format.name().to_string(),
            opencv_model_optional: opts.include_opencv_model.then(|| OpencvModel {
                camera_matrix: k.camera_matrix(),
                dist_coeffs: k.dist_coeffs().to_vec(),
            }),
            reference_frames: ReferenceFrames {
                dir: format!("{}_ref", c.name),
                reference_frame: 0,
            },
            fps: Some(self.scenario.fps),
            rods,
            table,
            ball,
        })
    }

    /// The field's corners and the centre line's ends that camera `cam` sees, clicked with
    /// `opts.table_click_noise_px` of noise; `None` with fewer than 4.
    fn table_inputs(&self, cam: usize, seed: u64, opts: &CalibOptions) -> Option<TableInputs> {
        let c = self.camera(cam).ok()?;
        let (l, w) = (self.scene.field_length_mm, self.scene.field_width_mm);
        let mut rng = Rng::new(hash_words(&[seed, cam as u64, 0x7AB1_E000]));
        let mut points = Vec::new();
        for p in [
            [0.0, 0.0],
            [0.0, w],
            [0.5 * l, 0.0],
            [0.5 * l, w],
            [l, 0.0],
            [l, w],
        ] {
            let Some((u, v)) = c.camera.project([p[0], p[1], 0.0]) else {
                continue;
            };
            let m = 2.0;
            if u < m
                || v < m
                || u > c.camera.width as f64 - 1.0 - m
                || v > c.camera.height as f64 - 1.0 - m
            {
                continue;
            }
            points.push(TablePoint {
                px: [
                    u + opts.table_click_noise_px * rng.gaussian(),
                    v + opts.table_click_noise_px * rng.gaussian(),
                ],
                mm: self.world_to_table(p),
            });
        }
        (points.len() >= 4).then_some(TableInputs { points })
    }
}

/// Rod `i`'s known-pose frames and positions: `(1 + 3 i, -h)`, `(2 + 3 i, 0)`, `(3 + 3 i, h)`.
pub(crate) fn known_pose_list(i: usize, half_travel_mm: f64) -> [(usize, f64); 3] {
    [
        (1 + 3 * i, -half_travel_mm),
        (2 + 3 * i, 0.0),
        (3 + 3 * i, half_travel_mm),
    ]
}
