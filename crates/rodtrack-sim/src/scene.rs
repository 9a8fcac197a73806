//! The scene: table, rods with markers and figures, ball, hands, colours and light.
//!
//! World frame: `x` along the field length (goal to goal), `y` along the rods (walls at `y = 0`
//! and `y = field_width_mm`), `z` up, field surface at `z = 0`. Every number of SPEC section 1
//! lives here as a field with its default; nothing is hard-coded in the renderer.
//!
//! ## Rod layout (the defaults, decided here)
//!
//! Figures are fixed on the rod; the marker (106 mm) sits between two figures (or beside the
//! single goalkeeper), so it never overlaps a figure's body along the rod and stays well inside
//! the camera's view over the whole travel. World `y` at position 0 (field centre 340):
//!
//! | figures | travel | figure centres (y, mm) | marker centre (y, mm) | clearance marker - body |
//! |---|---|---|---|---|
//! | 1 | 200 | 340 | 410 | 7 mm |
//! | 2 | 350 | 220, 460 | 340 | 57 mm |
//! | 3 | 190 | 140, 340, 540 | 440 | 37 mm |
//! | 5 | 115 | 70, 205, 340, 475, 610 (spacing 135) | 407.5 | 4.5 mm |
//!
//! Bodies are 20 mm wide along the rod; on the 5-figure rods the outer figures come within
//! 2.5 mm of the walls at the travel ends.

use crate::rng::Rng;
use rodtrack_core::MarkerSpec;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// Linear RGB albedo (0..1 per channel).
pub type Rgb = [f64; 3];

/// Which team a rod belongs to (figure colour).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Team {
    /// Red figures.
    Red,
    /// Blue figures.
    Blue,
}

/// One playing rod.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RodConfig {
    /// Axis `x`, mm.
    pub x_mm: f64,
    /// Axis height above the field, mm.
    pub z_mm: f64,
    /// Rod diameter, mm.
    pub diameter_mm: f64,
    /// Rod length, mm; the rod is centred on the field width at position 0.
    pub length_mm: f64,
    /// Total travel, mm; position runs over `[-travel/2, travel/2]`.
    pub travel_mm: f64,
    /// World `y` of each figure's centre at position 0, mm.
    pub figure_y_mm: Vec<f64>,
    /// Figure colour.
    pub team: Team,
    /// +1 if the marker's `u` axis points along world `+y`, -1 along `-y`.
    pub marker_dir: f64,
    /// World `y` of the marker's start (`u = 0`) at position 0, mm.
    pub marker_start_y_mm: f64,
    /// Print constant: the top line of the rod reads `psi = theta + psi0`.
    pub psi0_rad: f64,
}

impl RodConfig {
    /// World `y` offset of everything on the rod at `position_mm`.
    pub fn shift_y(&self, position_mm: f64) -> f64 {
        self.marker_dir * position_mm
    }
    /// Radius, mm.
    pub fn radius_mm(&self) -> f64 {
        0.5 * self.diameter_mm
    }
    /// Half the travel, mm.
    pub fn half_travel_mm(&self) -> f64 {
        0.5 * self.travel_mm
    }
    /// World `y` of marker coordinate `u_mm` at `position_mm`.
    pub fn marker_y(&self, u_mm: f64, position_mm: f64) -> f64 {
        self.marker_start_y_mm + self.marker_dir * (position_mm + u_mm)
    }
}

/// Shape of a figure (player), in the figure's frame at rod angle 0: `x` along the field, `y`
/// along the rod, `z` up, origin on the rod axis. Each part is an axis-aligned box there; the
/// whole figure turns with the rod.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FigureShape {
    /// Boxes `(min, max)`, mm.
    pub boxes: Vec<([f64; 3], [f64; 3])>,
}

impl Default for FigureShape {
    fn default() -> Self {
        FigureShape {
            boxes: vec![
                // Head: above the rod, top 22 mm above the axis.
                ([-8.0, -8.0, 9.0], [8.0, 8.0, 22.0]),
                // Torso around the rod, 20 mm wide along it.
                ([-9.0, -10.0, -38.0], [9.0, 10.0, 10.0]),
                // Legs.
                ([-6.0, -9.0, -68.0], [6.0, 9.0, -38.0]),
                // Foot, toe forward (+x), down to 5 mm above the field (axis at 80).
                ([-7.0, -9.0, -75.0], [13.0, 9.0, -66.0]),
            ],
        }
    }
}

impl FigureShape {
    /// The union box of all parts.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for (a, b) in &self.boxes {
            for k in 0..3 {
                lo[k] = lo[k].min(a[k]);
                hi[k] = hi[k].max(b[k]);
            }
        }
        (lo, hi)
    }
}

/// Colours (linear RGB albedo).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Colours {
    /// Marker paper.
    pub paper: Rgb,
    /// Marker ink.
    pub ink: Rgb,
    /// Bare steel rod (diffuse part).
    pub steel: Rgb,
    /// Steel specular strength (fraction of full scale at the highlight).
    pub steel_specular: f64,
    /// Playing field.
    pub field: Rgb,
    /// Field lines.
    pub lines: Rgb,
    /// Table walls.
    pub wall: Rgb,
    /// Floor outside the table.
    pub floor: Rgb,
    /// Red team.
    pub red: Rgb,
    /// Blue team.
    pub blue: Rgb,
    /// Ball.
    pub ball: Rgb,
    /// Hands and forearms.
    pub skin: Rgb,
}

impl Default for Colours {
    fn default() -> Self {
        Colours {
            paper: [0.85, 0.85, 0.85],
            ink: [0.05, 0.05, 0.05],
            steel: [0.45, 0.45, 0.47],
            steel_specular: 0.35,
            field: [0.10, 0.38, 0.12],
            lines: [0.80, 0.82, 0.80],
            wall: [0.30, 0.22, 0.15],
            floor: [0.12, 0.12, 0.12],
            red: [0.72, 0.08, 0.06],
            blue: [0.07, 0.16, 0.70],
            ball: [0.95, 0.60, 0.15],
            skin: [0.80, 0.58, 0.46],
        }
    }
}

/// A bright reflection (additive), fixed in the world, seen as a blob in each camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Glare {
    /// World point the blob is centred on (projected into each camera), mm.
    pub at_mm: [f64; 3],
    /// Blob radius (Gaussian sigma), px.
    pub sigma_px: f64,
    /// Peak added brightness at full glare level, DN.
    pub peak_dn: f64,
    /// Only this camera (an index into the simulation's cameras) sees the blob: a specular
    /// reflection seen from one viewpoint. `None`: every camera sees it.
    #[serde(default)]
    pub camera: Option<usize>,
}

/// Lighting of the table (static part; the scenario varies brightness and glare over time).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Lighting {
    /// Ratio of the brightest to the darkest end of the table (1 = uniform).
    pub gradient_ratio: f64,
    /// Direction of increasing brightness in the field plane, rad from world `+x`.
    pub gradient_dir_rad: f64,
    /// Optional glare blob.
    pub glare: Option<Glare>,
    /// Fraction of light that is ambient (the rest comes from straight above).
    pub ambient: f64,
}

impl Lighting {
    /// The light camera `camera` sees: without a glare meant for another camera only.
    pub fn for_camera(mut self, camera: usize) -> Lighting {
        if self
            .glare
            .is_some_and(|g| g.camera.is_some_and(|c| c != camera))
        {
            self.glare = None;
        }
        self
    }
}

impl Default for Lighting {
    fn default() -> Self {
        Lighting {
            gradient_ratio: 1.0,
            gradient_dir_rad: 0.0,
            glare: None,
            ambient: 0.35,
        }
    }
}

/// The hand model: a palm box and a forearm box reaching out over the table edge.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HandShape {
    /// Palm size `(x, y, z)`, mm.
    pub palm_mm: [f64; 3],
    /// Forearm width (x) and thickness (z), mm.
    pub forearm_mm: [f64; 2],
}

impl Default for HandShape {
    fn default() -> Self {
        HandShape {
            palm_mm: [95.0, 110.0, 30.0],
            forearm_mm: [70.0, 55.0],
        }
    }
}

/// The whole scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneConfig {
    /// Field length (goal to goal), mm.
    pub field_length_mm: f64,
    /// Field width (wall to wall, along the rods), mm.
    pub field_width_mm: f64,
    /// Wall height above the field, mm.
    pub wall_height_mm: f64,
    /// Wall thickness, mm.
    pub wall_thickness_mm: f64,
    /// Floor height outside the table (negative: below the field), mm.
    pub floor_z_mm: f64,
    /// The rods.
    pub rods: Vec<RodConfig>,
    /// Figure shape.
    pub figure: FigureShape,
    /// Ball diameter, mm.
    pub ball_diameter_mm: f64,
    /// Hand shape.
    pub hand: HandShape,
    /// Colours.
    pub colours: Colours,
    /// Lighting.
    pub lighting: Lighting,
    /// The marker printed on every rod (its `rod_diameter_mm` is replaced by each rod's).
    pub marker: MarkerSpec,
}

/// Defaults of SPEC section 1 used to generate the rods.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RodLayout {
    /// First rod's axis `x`, mm.
    pub first_x_mm: f64,
    /// Axis spacing, mm.
    pub pitch_mm: f64,
    /// Axis height, mm.
    pub axis_z_mm: f64,
    /// Rod diameter, mm.
    pub diameter_mm: f64,
    /// Figures per rod.
    pub figure_counts: Vec<usize>,
    /// Marker directions per rod (+1 / -1); `None`: alternate, starting with +1.
    pub marker_dirs: Option<Vec<f64>>,
    /// Seed of the per-rod print constants `psi0`.
    pub psi0_seed: u64,
}

impl Default for RodLayout {
    fn default() -> Self {
        RodLayout {
            first_x_mm: 75.0,
            pitch_mm: 150.0,
            axis_z_mm: 80.0,
            diameter_mm: 16.0,
            figure_counts: vec![1, 2, 5, 3, 3, 5, 2, 1],
            marker_dirs: None,
            psi0_seed: 0x5EED_0001,
        }
    }
}

/// Travel for a rod with `n` figures (SPEC section 1), mm.
pub fn travel_for(n: usize) -> f64 {
    match n {
        1 => 200.0,
        2 => 350.0,
        3 => 190.0,
        5 => 115.0,
        _ => 150.0,
    }
}

/// Figure centres and marker centre (world `y` at position 0) for `n` figures on a field of
/// width `w` (see the module docs).
pub fn figure_layout(n: usize, w: f64) -> (Vec<f64>, f64) {
    let c = 0.5 * w;
    match n {
        1 => (vec![c], c + 70.0),
        2 => (vec![c - 120.0, c + 120.0], c),
        3 => (vec![c - 200.0, c, c + 200.0], c + 100.0),
        5 => (
            (0..5).map(|k| c + 135.0 * (k as f64 - 2.0)).collect(),
            c + 67.5,
        ),
        _ => {
            let s = w / (n as f64 + 1.0);
            let ys: Vec<f64> = (0..n).map(|k| s * (k as f64 + 1.0)).collect();
            let m = if n >= 2 {
                0.5 * (ys[0] + ys[1])
            } else {
                c + 70.0
            };
            (ys, m)
        }
    }
}

impl SceneConfig {
    /// A scene with rods generated from `layout`.
    pub fn with_layout(layout: &RodLayout) -> SceneConfig {
        let field_width_mm = 680.0;
        let marker = MarkerSpec::default();
        let marker_len = marker.validate().map(|m| m.length_mm()).unwrap_or(106.0);
        let mut rng = Rng::new(layout.psi0_seed);
        let rods = layout
            .figure_counts
            .iter()
            .enumerate()
            .map(|(i, &n)| {
                let (figure_y_mm, marker_centre) = figure_layout(n, field_width_mm);
                let marker_dir = layout
                    .marker_dirs
                    .as_ref()
                    .and_then(|d| d.get(i).copied())
                    .map(|d| if d < 0.0 { -1.0 } else { 1.0 })
                    .unwrap_or(if i % 2 == 0 { 1.0 } else { -1.0 });
                RodConfig {
                    x_mm: layout.first_x_mm + layout.pitch_mm * i as f64,
                    z_mm: layout.axis_z_mm,
                    diameter_mm: layout.diameter_mm,
                    length_mm: 1500.0,
                    travel_mm: travel_for(n),
                    figure_y_mm,
                    team: if matches!(i, 0 | 1 | 3 | 5) {
                        Team::Red
                    } else {
                        Team::Blue
                    },
                    marker_dir,
                    marker_start_y_mm: marker_centre - marker_dir * 0.5 * marker_len,
                    psi0_rad: rng.range(0.0, TAU),
                }
            })
            .collect();
        SceneConfig {
            field_length_mm: 1200.0,
            field_width_mm,
            wall_height_mm: 120.0,
            wall_thickness_mm: 20.0,
            floor_z_mm: -700.0,
            rods,
            figure: FigureShape::default(),
            ball_diameter_mm: 35.0,
            hand: HandShape::default(),
            colours: Colours::default(),
            lighting: Lighting::default(),
            marker,
        }
    }

    /// Sets every rod's diameter (the marker wraps once around whatever diameter).
    pub fn with_rod_diameter(mut self, diameter_mm: f64) -> Self {
        for r in &mut self.rods {
            r.diameter_mm = diameter_mm;
        }
        self
    }

    /// Sets every rod's marker direction (+1 / -1), keeping each marker's centre in place.
    pub fn with_marker_dirs(mut self, dirs: &[f64]) -> Self {
        let len = self.marker_len_mm();
        for (r, &d) in self.rods.iter_mut().zip(dirs) {
            let centre = r.marker_start_y_mm + r.marker_dir * 0.5 * len;
            r.marker_dir = if d < 0.0 { -1.0 } else { 1.0 };
            r.marker_start_y_mm = centre - r.marker_dir * 0.5 * len;
        }
        self
    }

    /// The marker length, mm (106 for marker v1).
    pub fn marker_len_mm(&self) -> f64 {
        self.marker
            .validate()
            .map(|m| m.length_mm())
            .unwrap_or(106.0)
    }

    /// The marker spec for rod `i` (its diameter set to the rod's).
    pub fn marker_spec_for(&self, rod: usize) -> MarkerSpec {
        let mut m = self.marker.clone();
        if let Some(r) = self.rods.get(rod) {
            m.rod_diameter_mm = r.diameter_mm;
        }
        m
    }
}

impl Default for SceneConfig {
    fn default() -> Self {
        SceneConfig::with_layout(&RodLayout::default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The marker stays clear of every figure body along the rod (by at least 3 mm) and inside
    /// the field over the whole travel.
    #[test]
    fn marker_never_overlaps_a_figure_body() {
        let s = SceneConfig::default();
        let len = s.marker_len_mm();
        let (lo, hi) = s.figure.bounds();
        let _ = lo;
        let half_body = hi[1].max(-lo[1]);
        let dirs: Vec<f64> = s.rods.iter().map(|r| r.marker_dir).collect();
        assert!(dirs.contains(&1.0) && dirs.contains(&-1.0));
        for r in &s.rods {
            let a = r.marker_y(0.0, 0.0).min(r.marker_y(len, 0.0));
            let b = r.marker_y(0.0, 0.0).max(r.marker_y(len, 0.0));
            for &f in &r.figure_y_mm {
                let gap = (f - half_body - b).max(a - (f + half_body));
                assert!(gap >= 3.0, "rod at x={} gap {gap}", r.x_mm);
            }
            let h = r.half_travel_mm();
            assert!(a - h > 50.0 && b + h < s.field_width_mm - 50.0);
            for &f in &r.figure_y_mm {
                assert!(f - h - half_body >= 0.0 && f + h + half_body <= s.field_width_mm);
            }
        }
    }
}
