//! The rendered image agrees with the camera model and with the marker's definition.
#![allow(clippy::unwrap_used)]

use rodtrack_core::{gray, PixelFormat};
use rodtrack_sim::{
    default_cameras, NoiseModel, RenderMode, Scenario, SceneConfig, SimCamera, Simulation,
    WorldState,
};
use std::f64::consts::{PI, TAU};

fn quiet(mut cams: Vec<SimCamera>, fmt: PixelFormat) -> Vec<SimCamera> {
    for c in &mut cams {
        c.noise = NoiseModel::none();
        c.pixel_format = fmt;
    }
    cams
}

fn sim(scene: SceneConfig, cams: Vec<SimCamera>, mode: RenderMode) -> Simulation {
    let sc = Scenario::still(&scene, 1.0);
    Simulation::new(scene, cams, sc, mode).unwrap()
}

/// Pixel `(x, y)` of a mono8 frame, bilinear.
fn bilinear(img: &[u8], w: usize, x: f64, y: f64) -> f64 {
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let p = |i: usize, j: usize| img[j * w + i] as f64;
    (p(x0, y0) * (1.0 - fx) + p(x0 + 1, y0) * fx) * (1.0 - fy)
        + (p(x0, y0 + 1) * (1.0 - fx) + p(x0 + 1, y0 + 1) * fx) * fy
}

/// The column where rod `rod`'s projected axis crosses image row `row` (bisection on world y).
fn axis_column(s: &Simulation, cam: usize, rod: usize, row: f64) -> Option<(f64, f64)> {
    let v = |y: f64| s.project_rod_axis(cam, rod, y).unwrap().map(|p| p.1);
    let (mut a, mut b) = (-200.0, 900.0);
    let (va, vb) = (v(a)?, v(b)?);
    if (va - row).signum() == (vb - row).signum() {
        return None;
    }
    for _ in 0..80 {
        let m = 0.5 * (a + b);
        if (v(m)? - row).signum() == (va - row).signum() {
            a = m;
        } else {
            b = m;
        }
    }
    let y = 0.5 * (a + b);
    Some((s.project_rod_axis(cam, rod, y).unwrap()?.0, y))
}

/// Rendered rod centre lines lie within 0.3 px of the rod axes projected by the camera model.
/// Uniform light (no directional shading, no highlight) and a white field make the rod a clean
/// dark band; its centre in a row is the coverage-weighted centroid of the darkening.
fn centre_line_matches_projection(mode: RenderMode) {
    let mut scene = SceneConfig::default();
    scene.figure.boxes.clear();
    scene.lighting.ambient = 1.0;
    scene.colours.steel_specular = 0.0;
    scene.colours.field = [0.9, 0.9, 0.9];
    scene.colours.lines = [0.9, 0.9, 0.9];
    let len = scene.marker_len_mm();
    let cams = quiet(default_cameras(), PixelFormat::Mono8);
    let (w, h) = (cams[0].camera.width, cams[0].camera.height);
    let mut s = sim(scene.clone(), cams, mode);
    let mut img = vec![0u8; s.frame_bytes(0).unwrap()];
    let rods = scene.rods.len();
    for cam in 0..2 {
        s.render_state(
            cam,
            &WorldState::posed(&vec![(0.0, 0.0); rods]),
            0,
            &mut img,
        )
        .unwrap();
        let bg = 0.9 * 235.0;
        let rod_level = 0.45 * 235.0 + 0.02 * 235.0 / 3.0;
        let mut checked = 0;
        let mut worst: f64 = 0.0;
        for (ri, rc) in scene.rods.iter().enumerate() {
            let m0 = rc.marker_y(0.0, 0.0).min(rc.marker_y(len, 0.0)) - 15.0;
            let m1 = rc.marker_y(0.0, 0.0).max(rc.marker_y(len, 0.0)) + 15.0;
            for k in 0..12 {
                let row = 60.0 + k as f64 * 85.0;
                let Some((u, y)) = axis_column(&s, cam, ri, row) else {
                    continue;
                };
                if !(110.0..=570.0).contains(&y) || (m0..=m1).contains(&y) {
                    continue;
                }
                if !(40.0..=w as f64 - 40.0).contains(&u) {
                    continue;
                }
                let (mut sw, mut sx) = (0.0, 0.0);
                let r = row as usize;
                for x in (u as usize - 25)..=(u as usize + 25) {
                    let c = ((bg - img[r * w + x] as f64) / (bg - rod_level)).clamp(0.0, 1.2);
                    sw += c;
                    sx += c * x as f64;
                }
                assert!(sw > 15.0 && sw < 35.0, "rod {ri} row {row}: width {sw} px");
                let centre = sx / sw;
                let err = centre - u;
                worst = worst.max(err.abs());
                assert!(
                    err.abs() < 0.3,
                    "{mode:?} cam {cam} rod {ri} row {row}: rendered centre {centre:.3}, projected axis {u:.3}"
                );
                checked += 1;
            }
        }
        assert!(checked >= 30, "only {checked} rows checked");
        eprintln!("{mode:?} cam {cam}: {checked} rows, worst centre error {worst:.3} px");
        let _ = h;
    }
}

#[test]
fn rod_centre_line_fast() {
    centre_line_matches_projection(RenderMode::Fast);
}

#[test]
fn rod_centre_line_quality() {
    centre_line_matches_projection(RenderMode::Quality);
}

/// Reads the Gray code of rod `rod` on the line of its surface that faces the camera.
fn read_code(s: &Simulation, img: &[u8], w: usize, cam: usize, rod: usize, pos: f64) -> u32 {
    let scene = s.scene();
    let rc = &scene.rods[rod];
    let m = scene.marker.validate().unwrap();
    let c = s.cameras()[cam].camera;
    let o = c.pose.centre_world();
    let a = (o[0] - rc.x_mm).atan2(o[2] - rc.z_mm);
    let mut code = 0;
    for k in 0..m.bits() {
        let y = rc.marker_y(m.bit_space_centre_mm(k), pos);
        let p = [
            rc.x_mm + rc.radius_mm() * a.sin(),
            y,
            rc.z_mm + rc.radius_mm() * a.cos(),
        ];
        let (u, v) = c.project(p).unwrap();
        let val = bilinear(img, w, u, v);
        if val < 100.0 {
            code |= 1 << k;
        }
    }
    code
}

/// At angle theta the marker shows gray(floor(32 (theta + psi0 + view offset) / 2 pi)) on the
/// line facing the camera; checked mid-step for all 32 steps, both marker directions, a
/// camera turned by 180 degrees, stronger distortion and a thicker rod.
#[test]
fn marker_shows_the_gray_code_of_the_angle() {
    let variants: Vec<(&str, SceneConfig, Vec<SimCamera>)> = {
        let base = SceneConfig::default();
        let flipped =
            SceneConfig::default().with_marker_dirs(&[-1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0]);
        let cam = default_cameras().remove(0);
        let yawed = cam
            .clone()
            .with_pose([525.0, 340.0, 830.0], PI, 0.01)
            .with_k1(-0.35);
        vec![
            ("default", base.clone(), vec![cam.clone()]),
            ("flipped markers", flipped, vec![cam]),
            (
                "yaw 180, k1 -0.35, rod 20 mm",
                base.with_rod_diameter(20.0),
                vec![yawed],
            ),
        ]
    };
    for (name, scene, cams) in variants {
        let cams = quiet(cams, PixelFormat::Mono8);
        let w = cams[0].camera.width;
        let rods = scene.rods.len();
        let mut s = sim(scene.clone(), cams, RenderMode::Fast);
        let mut img = vec![0u8; s.frame_bytes(0).unwrap()];
        // Rod 3 sits right below the camera (x = 525): view offset 0.
        for rod in [3usize, 2, 4] {
            let rc = &scene.rods[rod];
            let o = s.cameras()[0].camera.pose.centre_world();
            // The line facing the camera reads psi = theta + psi0 - dir * a_c.
            let a_c = (o[0] - rc.x_mm).atan2(o[2] - rc.z_mm);
            let offset = -rc.marker_dir * a_c;
            let mut ok = 0;
            for n in 0..32u32 {
                let psi = TAU * (n as f64 + 0.5) / 32.0;
                let theta = psi - rc.psi0_rad - offset;
                let pos = 17.0;
                let mut poses = vec![(0.0, 0.0); rods];
                poses[rod] = (pos, theta + TAU * 3.0);
                s.render_state(0, &WorldState::posed(&poses), 0, &mut img)
                    .unwrap();
                let code = read_code(&s, &img, w, 0, rod, pos);
                assert_eq!(
                    code,
                    gray(n),
                    "{name}: rod {rod} theta {theta:.3}: read {code:05b}, expected {:05b} (step {n})",
                    gray(n)
                );
                ok += 1;
            }
            assert_eq!(ok, 32);
            if rod == 3 {
                assert!(offset.abs() < 0.02, "{name}: rod 3 is not below the camera");
            }
        }
    }
}

/// Fast mode (analytic box filter over the pixel and the motion) agrees with quality mode
/// (4 x 4 sub-samples at 16 times in the exposure) on the markers, still and spinning.
#[test]
fn fast_mode_markers_match_quality_mode() {
    let scene = SceneConfig::default();
    for (name, frame) in [
        ("static", 10usize),
        ("spin600", 600),
        ("spin3000", 1000),
        ("gameplay", 2000),
    ] {
        let sc = Scenario::by_name(name, &scene, 1).unwrap();
        let cams = quiet(default_cameras(), PixelFormat::Mono8);
        let mut fast =
            Simulation::new(scene.clone(), cams.clone(), sc.clone(), RenderMode::Fast).unwrap();
        let mut qual = Simulation::new(scene.clone(), cams, sc, RenderMode::Quality).unwrap();
        let n = fast.frame_bytes(0).unwrap();
        let (mut a, mut b) = (vec![0u8; n], vec![0u8; n]);
        fast.render(frame, 0, &mut a).unwrap();
        qual.render(frame, 0, &mut b).unwrap();
        let truth = fast.truth(frame, 0).unwrap();
        let len = scene.marker_len_mm();
        let (mut sum, mut cnt, mut worst_rod) = (0.0, 0usize, 0.0f64);
        for (ri, rc) in scene.rods.iter().enumerate() {
            if !truth[ri].visible {
                continue;
            }
            let pos = truth[ri].m.position_mm;
            let (mut rs, mut rn) = (0.0, 0usize);
            // Pixels along the rod's top line over the whole marker.
            for k in 0..200 {
                let u = len * (k as f64 + 0.5) / 200.0;
                let y = rc.marker_y(u, pos);
                let (px, py) = fast.project_rod_axis(0, ri, y).unwrap().unwrap();
                for dx in -3i64..=3 {
                    let p = py.round() as usize * 1440 + (px.round() as i64 + dx) as usize;
                    rs += (a[p] as f64 - b[p] as f64).abs();
                    rn += 1;
                }
            }
            worst_rod = worst_rod.max(rs / rn as f64);
            sum += rs;
            cnt += rn;
        }
        let mean = sum / cnt as f64;
        eprintln!(
            "{name}: mean |fast - quality| on markers {mean:.2} DN, worst rod {worst_rod:.2} DN"
        );
        assert!(mean < 2.0 && worst_rod < 4.0, "{name}: {mean} {worst_rod}");
    }
}
