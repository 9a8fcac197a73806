//! The table as the events see it: the field's edges in the table frame and each rod's axis
//! along `x`, from the calibration.

use super::EventConfig;
use crate::calib::CalibrationFile;
use crate::{CameraIntrinsics, CoreError};

/// The field's edges (table frame, mm: origin at the field's centre) and the rods' axes.
#[derive(Debug, Clone, PartialEq)]
pub struct TableGeometry {
    /// Goal A's line, mm.
    pub x_min_mm: f64,
    /// Goal B's line, mm.
    pub x_max_mm: f64,
    /// A side wall, mm.
    pub y_min_mm: f64,
    /// The other side wall, mm.
    pub y_max_mm: f64,
    /// Each rod's axis: `(rod index of the calibration, x_mm)`, in rod order.
    pub rods: Vec<(u32, f64)>,
}

/// How far the clicked field points may lie outside the configured field, mm, before the
/// configuration is taken to be wrong.
const FIELD_POINT_SLACK_MM: f64 = 25.0;

impl TableGeometry {
    /// The field of `cfg` centred on the origin, with `rods` as given.
    pub fn new(cfg: &EventConfig, rods: Vec<(u32, f64)>) -> TableGeometry {
        let (hl, hw) = (0.5 * cfg.field_length_mm, 0.5 * cfg.field_width_mm);
        TableGeometry {
            x_min_mm: -hl,
            x_max_mm: hl,
            y_min_mm: -hw,
            y_max_mm: hw,
            rods,
        }
    }

    /// The reference table (SPEC section 1): 1200 x 680 mm, 8 rods 150 mm apart, the first
    /// 75 mm from goal A's line.
    pub fn reference() -> TableGeometry {
        let cfg = EventConfig::default();
        let rods = (0..8u32)
            .map(|i| (i, -0.5 * cfg.field_length_mm + 75.0 + 150.0 * f64::from(i)))
            .collect();
        TableGeometry::new(&cfg, rods)
    }

    /// The field of `cfg`, and each rod's axis from its calibrated image path: the path
    /// points' rays met with the plane at the axis' height (`cfg.rod_axis_height_mm`), their
    /// mean `x`, averaged over the cameras that see the rod. Cameras need `[cameras.table]`
    /// and `opencv_model`; fails when none has them, or when a clicked field point lies
    /// outside the configured field (a wrong field size).
    pub fn from_calibration(
        cal: &CalibrationFile,
        cfg: &EventConfig,
    ) -> Result<TableGeometry, CoreError> {
        cfg.validate()?;
        let mut geom = TableGeometry::new(cfg, Vec::new());
        let mut sums: Vec<(u32, f64, usize)> = Vec::new();
        let mut tables = 0;
        for c in &cal.cameras {
            let (Some(table), Some(model)) = (&c.table, &c.opencv_model) else {
                continue;
            };
            tables += 1;
            let [[x0, y0], [x1, y1]] = table.field_mm;
            let s = FIELD_POINT_SLACK_MM;
            if x0 < geom.x_min_mm - s
                || x1 > geom.x_max_mm + s
                || y0 < geom.y_min_mm - s
                || y1 > geom.y_max_mm + s
            {
                return Err(CoreError::Events {
                    field: "field_length_mm",
                    reason: format!(
                        "camera {} ({}): the clicked field points span [{x0:.0}, {x1:.0}] x \
                         [{y0:.0}, {y1:.0}] mm, beyond a field of {} x {} mm: give the \
                         table's field size",
                        c.index, c.name, cfg.field_length_mm, cfg.field_width_mm
                    ),
                });
            }
            let k = CameraIntrinsics::from_opencv(model.camera_matrix, &model.dist_coeffs)?;
            let cam = table.camera(k, c.image_width, c.image_height);
            for rod in &c.rods {
                let (mut sx, mut n) = (0.0, 0usize);
                for p in &rod.path_points_px {
                    let (o, d) = cam.ray(p[0], p[1]);
                    if d[2].abs() < 1e-9 {
                        continue;
                    }
                    let t = (cfg.rod_axis_height_mm - o[2]) / d[2];
                    let x = o[0] + t * d[0];
                    if t > 0.0 && x.is_finite() {
                        sx += x;
                        n += 1;
                    }
                }
                if n == 0 {
                    continue;
                }
                match sums.iter_mut().find(|s| s.0 == rod.rod) {
                    Some(s) => {
                        s.1 += sx / n as f64;
                        s.2 += 1;
                    }
                    None => sums.push((rod.rod, sx / n as f64, 1)),
                }
            }
        }
        if tables == 0 {
            return Err(CoreError::Events {
                field: "table",
                reason: "no camera of the calibration has `[cameras.table]` and \
                         `opencv_model`: the events need the table frame"
                    .into(),
            });
        }
        sums.sort_by_key(|s| s.0);
        geom.rods = sums.iter().map(|s| (s.0, s.1 / s.2 as f64)).collect();
        Ok(geom)
    }

    /// Checks that the field has a positive size and every number is finite.
    pub fn validate(&self) -> Result<(), CoreError> {
        let ok = [self.x_min_mm, self.x_max_mm, self.y_min_mm, self.y_max_mm]
            .iter()
            .chain(self.rods.iter().map(|r| &r.1))
            .all(|v| v.is_finite());
        if !ok || self.x_max_mm <= self.x_min_mm || self.y_max_mm <= self.y_min_mm {
            return Err(CoreError::Events {
                field: "table",
                reason: format!(
                    "the field [{}, {}] x [{}, {}] mm (or a rod's axis) is not a finite, \
                     non-empty rectangle",
                    self.x_min_mm, self.x_max_mm, self.y_min_mm, self.y_max_mm
                ),
            });
        }
        Ok(())
    }

    /// The goal mouths' centre across the table, mm.
    pub fn y_centre_mm(&self) -> f64 {
        0.5 * (self.y_min_mm + self.y_max_mm)
    }

    /// How far `(x, y)` lies beyond the field's edge, mm: positive outside, negative inside
    /// (minus the distance to the nearest edge).
    pub fn distance_beyond_edge_mm(&self, x_mm: f64, y_mm: f64) -> f64 {
        let dx = (self.x_min_mm - x_mm).max(x_mm - self.x_max_mm);
        let dy = (self.y_min_mm - y_mm).max(y_mm - self.y_max_mm);
        if dx > 0.0 || dy > 0.0 {
            dx.max(0.0).hypot(dy.max(0.0))
        } else {
            dx.max(dy)
        }
    }

    /// The rod whose axis is nearest `x_mm`, when within `reach_mm`.
    pub fn nearest_rod(&self, x_mm: f64, reach_mm: f64) -> Option<u32> {
        self.rods
            .iter()
            .map(|&(r, x)| (r, (x - x_mm).abs()))
            .filter(|&(_, d)| d <= reach_mm)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(r, _)| r)
    }
}
