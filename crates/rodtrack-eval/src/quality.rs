//! What a row's `quality` says about its error: many random tables as built, each through a
//! mix of scenes (still rods, a lamp's glare on a Gray code, gameplay with hands, a spin,
//! a hand resting over part of a marker), every camera calibrated as an operator would, the
//! raw tracker rows (no filter, no fusion) held against the truth and grouped by quality.
//!
//! [`run_table`] gives the rows of one table; [`bands`] the error percentiles per quality
//! band; [`format_bands`] the table `docs/quality.md` quotes. The `quality_bands` example runs
//! it.

use crate::Result;
use rodtrack_core::angle::wrap_pi;
use rodtrack_core::calib::CameraCalibration;
use rodtrack_core::pipeline::CameraPipeline;
use rodtrack_core::track::Mode;
use rodtrack_core::{FrameView, RodResult, Status};
use rodtrack_sim::rng::Rng;
use rodtrack_sim::scene::Glare;
use rodtrack_sim::{
    apply_variation, calibrate_sim_camera, default_cameras, HandPass, Lighting, RenderMode,
    Scenario, SceneConfig, SimCamera, Simulation, TrackBuilder,
};
use std::f64::consts::TAU;

/// An `ok` row this far off is a gross error (angle, rad).
pub const GROSS_ANGLE_RAD: f64 = 0.2;
/// An `ok` row this far off is a gross error (position, mm).
pub const GROSS_POSITION_MM: f64 = 5.0;

/// The quality bands' lower edges; the last band runs to 1 inclusive.
pub const BAND_EDGES: [f64; 6] = [0.0, 0.3, 0.6, 0.8, 0.9, 0.95];

/// The scenes each table goes through.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scene {
    /// Still rods at random poses.
    Static,
    /// Still rods, a lamp's glare on one rod's Gray code in one camera.
    Glare,
    /// Gameplay: fast slides and kicks, hands passing over the markers, the ball, a spin to
    /// up to 3000 rpm.
    Gameplay,
    /// Still rods, a hand resting over part of one rod's marker (across or along it),
    /// moving slowly over it.
    PartCover,
    /// Slow turns and slides (a few rad/s, tens of mm/s).
    Slow,
}

impl Scene {
    /// Every scene.
    pub const ALL: [Scene; 5] = [
        Scene::Static,
        Scene::Glare,
        Scene::Gameplay,
        Scene::PartCover,
        Scene::Slow,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Scene::Static => "static",
            Scene::Glare => "glare",
            Scene::Gameplay => "gameplay",
            Scene::PartCover => "part_cover",
            Scene::Slow => "slow",
        }
    }
}

/// One raw row held against the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScoredRow {
    /// The table: `asbuilt:SEED`.
    pub seed: u64,
    /// The scene it came from.
    pub scene: Scene,
    /// Camera index.
    pub camera: u32,
    /// Rod.
    pub rod: u32,
    /// Frame.
    pub frame: u64,
    /// The row's quality.
    pub quality: f64,
    /// Whether the row is `ok`.
    pub ok: bool,
    /// Whether the marker is wholly visible (the truth's `visible`).
    pub visible: bool,
    /// Angle error, rad (wrapped to `[0, pi]`).
    pub angle_error_rad: f64,
    /// Position error, mm.
    pub position_error_mm: f64,
    /// What the tracker found (its diagnostics: the reason when not ok, the stripes, the
    /// code's agreement).
    pub result: RodResult,
}

impl ScoredRow {
    /// An `ok` row with a gross error.
    pub fn gross(&self) -> bool {
        self.ok
            && (self.angle_error_rad > GROSS_ANGLE_RAD
                || self.position_error_mm > GROSS_POSITION_MM)
    }
}

/// A table's scene: its scenario and its name.
fn scenario_for(
    scene_kind: Scene,
    scene: &SceneConfig,
    n_cameras: usize,
    seed: u64,
    frames: usize,
) -> Result<Scenario> {
    let mut rng = Rng::new(seed ^ 0x0A11_7700 ^ (scene_kind as u64) << 40);
    let n_rods = scene.rods.len() as u64;
    let sc = match scene_kind {
        Scene::Static => Scenario::by_name("static", scene, seed)?.with_frames(frames),
        Scene::Glare => {
            let mut sc = Scenario::by_name("static", scene, seed)?.with_frames(frames);
            let rod = rng.below(n_rods) as usize;
            let cam = rng.below(n_cameras as u64) as usize;
            let g = &scene.marker.gray_code;
            let g0 = g.start_mm;
            let g1 = g0 + g.bits as f64 * g.bit_space_mm;
            let u = rng.range(g0 + 0.1 * (g1 - g0), g1);
            let r = &scene.rods[rod];
            let pos = sc.rods[rod].position.value(0.0);
            let glare = Glare {
                at_mm: [r.x_mm, r.marker_y(u, pos), r.z_mm + r.radius_mm()],
                sigma_px: rng.range(4.0, 20.0),
                peak_dn: rng.range(120.0, 260.0),
                camera: Some(cam),
            };
            sc.lighting = Some(Lighting {
                glare: Some(glare),
                ..scene.lighting
            });
            let mut gl = TrackBuilder::new(0.0);
            gl.hold(0.2 * sc.duration_s).move_to(1.0, 50.0, 1e4);
            sc.glare = gl.build();
            sc
        }
        Scene::Gameplay => {
            let mut sc = Scenario::by_name("gameplay", scene, seed)?.with_frames(frames);
            let dur = sc.duration_s;
            // The scripted hands start after a second or two: bring them into the window.
            let span = sc.hands.first().map_or(1.0, |h| h.t0_s);
            for h in sc.hands.iter_mut() {
                let d = h.t1_s - h.t0_s;
                h.t0_s = (h.t0_s - span).max(0.0) * 0.3 + 0.1 * dur;
                h.t1_s = h.t0_s + d.min(0.4 * dur);
            }
            let spin_rod = rng.below(n_rods) as usize;
            let rate = rng.range(600.0, 3000.0) / 60.0 * TAU;
            let mut a = TrackBuilder::new(0.0);
            a.hold(0.2 * dur)
                .spin(rate, rng.range(0.02, 0.1))
                .hold(0.3 * dur)
                .spin(-rate, 0.05);
            sc.rods[spin_rod].angle = a.build();
            sc
        }
        Scene::PartCover => {
            let mut sc = Scenario::by_name("static", scene, seed)?.with_frames(frames);
            let rod = rng.below(n_rods) as usize;
            sc.hands = vec![part_cover(
                scene,
                rod,
                sc.rods[rod].position.value(0.0),
                &mut rng,
                sc.duration_s,
            )];
            sc
        }
        Scene::Slow => {
            let mut sc = Scenario::by_name("static", scene, seed)?.with_frames(frames);
            let dur = sc.duration_s;
            for (i, r) in scene.rods.iter().enumerate() {
                let h = r.half_travel_mm();
                let p0 = sc.rods[i].position.value(0.0);
                let a0 = sc.rods[i].angle.value(0.0);
                let mut p = TrackBuilder::new(p0);
                p.hold(0.1 * dur).move_to(
                    rng.range(-0.8 * h, 0.8 * h),
                    rng.range(10.0, 60.0),
                    500.0,
                );
                sc.rods[i].position = p.build();
                let mut a = TrackBuilder::new(a0);
                a.hold(0.1 * dur)
                    .move_to(a0 + rng.range(-3.0, 3.0), rng.range(0.5, 3.0), 50.0);
                sc.rods[i].angle = a.build();
            }
            sc
        }
    };
    Ok(sc)
}

/// A hand whose palm's edge lies over rod `rod`'s marker: across the rod (covering one side of
/// it, all along the marker) or along it (covering one end of the marker), drifting slowly
/// so that the covered share changes over the scene.
pub fn part_cover(
    scene: &SceneConfig,
    rod: usize,
    position_mm: f64,
    rng: &mut Rng,
    duration_s: f64,
) -> HandPass {
    let r = &scene.rods[rod];
    let palm = scene.hand.palm_mm;
    let len = scene.marker_len_mm();
    // Just above the rod's top: the palm's edge projects onto the rod where it is.
    let z = r.z_mm + r.radius_mm() + 0.5 * palm[2] + rng.range(3.0, 15.0);
    let (from, to) = if rng.below(2) == 0 {
        // Across: the palm's x edge from well beside the rod to a third of its width over it.
        let s = if rng.below(2) == 0 { 1.0 } else { -1.0 };
        let y = r.marker_y(0.5 * len, position_mm);
        let e0 = r.radius_mm() * rng.range(1.2, 2.0);
        let e1 = r.radius_mm() * rng.range(-0.2, 0.4);
        (
            [r.x_mm + s * (0.5 * palm[0] + e0), y, z],
            [r.x_mm + s * (0.5 * palm[0] + e1), y, z],
        )
    } else {
        // Along: the palm's y edge from beyond the marker's end to a fifth of the marker.
        let end = if rng.below(2) == 0 { 0.0 } else { len };
        let inward = if end == 0.0 { 1.0 } else { -1.0 };
        let y_end = r.marker_y(end, position_mm);
        let dir = r.marker_dir * inward;
        let c0 = y_end - dir * (0.5 * palm[1] + rng.range(3.0, 10.0));
        let c1 = y_end - dir * (0.5 * palm[1] - rng.range(0.05, 0.25) * len);
        ([r.x_mm, c0, z], [r.x_mm, c1, z])
    };
    let side = if from[1] > 0.5 * scene.field_width_mm {
        1.0
    } else {
        -1.0
    };
    HandPass {
        t0_s: 0.0,
        t1_s: duration_s,
        from_mm: from,
        to_mm: to,
        side,
    }
}

/// The scene and cameras of a setup (`default`, a named variation or `asbuilt:SEED`).
pub fn table(setup: &str) -> Result<(SceneConfig, Vec<SimCamera>)> {
    let mut scene = SceneConfig::default();
    let mut cameras = default_cameras();
    apply_variation(setup, &mut scene, &mut cameras)?;
    Ok((scene, cameras))
}

/// Every camera of `asbuilt:SEED` calibrated on its reference frame, as an operator does
/// once for a table (clicks drawn from `SEED`).
pub fn calibrate_table(seed: u64) -> Result<Vec<CameraCalibration>> {
    let (scene, cameras) = table(&format!("asbuilt:{seed}"))?;
    let sc = Scenario::still(&scene, 0.1);
    let mut sim = Simulation::new(scene, cameras, sc, RenderMode::Fast)?.with_seed(seed);
    (0..sim.cameras().len())
        .map(|c| Ok(calibrate_sim_camera(&mut sim, c, seed)?.calibration))
        .collect()
}

/// Every frame of scene `kind` on `asbuilt:SEED` tracked by every camera calibrated in
/// `calibrations` (raw rows, enhanced mode) and held against the truth.
pub fn run_scene(
    seed: u64,
    calibrations: &[CameraCalibration],
    kind: Scene,
    frames: usize,
) -> Result<Vec<ScoredRow>> {
    let (scene, cameras) = table(&format!("asbuilt:{seed}"))?;
    let sc = scenario_for(kind, &scene, cameras.len(), seed, frames)?;
    let mut sim = Simulation::new(scene, cameras, sc, RenderMode::Fast)?.with_seed(seed);
    let mut out = Vec::new();
    for (c, cal) in calibrations.iter().enumerate() {
        let mut pipe = CameraPipeline::new(cal, Mode::Enhanced)?;
        let mut buf = vec![0u8; sim.frame_bytes(c)?];
        let mut raw = Vec::new();
        for f in 0..sim.frame_count() {
            let meta = sim.render(f, c, &mut buf)?;
            let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format)?;
            raw.clear();
            pipe.process(&view, meta.frame_id, meta.timestamp_ns, &mut raw)?;
            let truth = sim.truth(f, c)?;
            for (i, m) in raw.iter().enumerate() {
                let Some(t) = truth.iter().find(|t| t.m.rod == m.rod) else {
                    continue;
                };
                out.push(ScoredRow {
                    seed,
                    scene: kind,
                    camera: c as u32,
                    rod: m.rod,
                    frame: m.frame,
                    quality: m.quality,
                    ok: m.status == Status::Ok,
                    visible: t.visible,
                    angle_error_rad: wrap_pi(m.angle_rad - t.m.angle_rad).abs(),
                    position_error_mm: (m.position_mm - t.m.position_mm).abs(),
                    result: pipe.last_results().get(i).copied().unwrap_or_default(),
                });
            }
        }
    }
    Ok(out)
}

/// Every scene of `asbuilt:SEED`, the cameras calibrated once.
pub fn run_table(seed: u64, frames: usize) -> Result<Vec<ScoredRow>> {
    let cal = calibrate_table(seed)?;
    let mut rows = Vec::new();
    for kind in Scene::ALL {
        rows.extend(run_scene(seed, &cal, kind, frames)?);
    }
    Ok(rows)
}

/// The error statistics of the `ok` rows of one quality band.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Band {
    /// Lower edge (inclusive).
    pub lo: f64,
    /// Upper edge (exclusive but for the last band, which includes 1).
    pub hi: f64,
    /// `ok` rows in the band.
    pub rows: usize,
    /// Angle error p50, p90, p99, max, rad.
    pub angle_rad: [f64; 4],
    /// Position error p50, p90, p99, max, mm.
    pub position_mm: [f64; 4],
    /// Rows with a gross error.
    pub gross: usize,
}

/// The `p`-quantile (nearest rank) of sorted `v`; 0 when empty.
fn quantile(v: &[f64], p: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let i = ((p * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
    v[i]
}

/// The `ok` rows of `rows` grouped by the quality bands of [`BAND_EDGES`].
pub fn bands(rows: &[ScoredRow]) -> Vec<Band> {
    (0..BAND_EDGES.len())
        .map(|b| {
            let lo = BAND_EDGES[b];
            let hi = BAND_EDGES.get(b + 1).copied().unwrap_or(1.0);
            let last = b + 1 == BAND_EDGES.len();
            let inside = |q: f64| q >= lo && (q < hi || (last && q <= hi));
            let mut a: Vec<f64> = Vec::new();
            let mut p: Vec<f64> = Vec::new();
            let mut gross = 0;
            for r in rows.iter().filter(|r| r.ok && inside(r.quality)) {
                a.push(r.angle_error_rad);
                p.push(r.position_error_mm);
                gross += r.gross() as usize;
            }
            a.sort_by(f64::total_cmp);
            p.sort_by(f64::total_cmp);
            let q = |v: &[f64]| {
                [
                    quantile(v, 0.5),
                    quantile(v, 0.9),
                    quantile(v, 0.99),
                    v.last().copied().unwrap_or(0.0),
                ]
            };
            Band {
                lo,
                hi,
                rows: a.len(),
                angle_rad: q(&a),
                position_mm: q(&p),
                gross,
            }
        })
        .collect()
}

/// The bands as a Markdown table.
pub fn format_bands(bands: &[Band]) -> String {
    let mut s = String::from(
        "| quality | ok rows | angle error p50 / p90 / p99 / max (rad) | position error p50 / p90 / p99 / max (mm) | gross |\n|---|---|---|---|---|\n",
    );
    for (i, b) in bands.iter().enumerate() {
        let close = if i + 1 == bands.len() { ']' } else { ')' };
        s += &format!(
            "| [{:.2}, {:.2}{close} | {} | {:.4} / {:.4} / {:.4} / {:.4} | {:.3} / {:.3} / {:.3} / {:.3} | {} |\n",
            b.lo,
            b.hi,
            b.rows,
            b.angle_rad[0],
            b.angle_rad[1],
            b.angle_rad[2],
            b.angle_rad[3],
            b.position_mm[0],
            b.position_mm[1],
            b.position_mm[2],
            b.position_mm[3],
            b.gross
        );
    }
    s
}

/// Coverage of visible rows: visible rows reported `ok` over visible rows (1 when none).
pub fn coverage(rows: &[ScoredRow]) -> f64 {
    let vis = rows.iter().filter(|r| r.visible).count();
    let ok = rows.iter().filter(|r| r.visible && r.ok).count();
    if vis == 0 {
        1.0
    } else {
        ok as f64 / vis as f64
    }
}
