//! Angle diagnostics on the simulator: per-row errors of the enhanced mode against truth, as CSV.
//!
//! `cargo run --release --example angle_diag -- scenario NAME FRAMES VARIATION OUT.csv`
//! (`SEED=N` picks the scenario, noise and click seed, 3 by default; `STRIDE=K` processes
//! every K-th frame, as `rodtrack evaluate` does for slow scenarios; `CALIB=FILE.toml` tracks
//! with that calibration file, e.g. from `rodtrack calibrate --auto`, instead of calibrating
//! from the simulator's clicks; `ONLY=CAM:ROD` measures one rod; `RINGS=1` also prints each
//! ring's samples and own slope.) It ends with each rod's learnt centre-line slope against the
//! true axis' across the calibrated line.
//! `cargo run --release --example angle_diag -- grid VARIATION NOISE(0|1) OUT.csv`
//! `cargo run --release --example angle_diag -- profile NAME FRAMES CAM ROD FRAME`
//! `cargo run --release --example angle_diag -- rings NAME FRAMES VARIATION CAM ROD FRAME`
//! `cargo run --release --example angle_diag -- rings-travel NAME FRAMES VARIATION CAM RODS`
//!
//! `scenario` also prints a summary: the errors of the rows reported ok on visible markers,
//! and the rows reported ok on hidden ones. `profile` prints the luma along one rod's marker
//! and across it at each bit space; `rings` the rings' silhouettes against the true axis.
//! `rings-travel` follows every ring row over a scenario (`RODS` comma-separated; `STRIDE`
//! as for `scenario`, 2 by default): per ring the tracker learns from (white and black, read
//! with the tracker's scans), the silhouette's centre minus the true axis (mean, std), its half width over
//! the calibrated radius, and how that offset runs along the travel (slope, px per 100 mm),
//! which is what the learnt centre line cannot tell from the axis.
//! `grid` renders still states (every rod at a grid of positions and angles) and measures each
//! with a fresh tracker (what the first frame after calibration gives).
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use rodtrack_core::calib::calibrate_rod;
use rodtrack_core::{CameraIntrinsics, FrameView, Marker, Mode, RodTracker, Status};
use rodtrack_sim::{
    apply_variation, default_cameras, NoiseModel, RenderMode, RodPose, Scenario, SceneConfig,
    Simulation, WorldState,
};
use std::f64::consts::TAU;
use std::io::Write;

fn wrap(d: f64) -> f64 {
    let d = d.rem_euclid(TAU);
    if d > TAU / 2.0 {
        d - TAU
    } else {
        d
    }
}

fn setup(
    scenario: &str,
    frames: usize,
    variation: &str,
    noise: bool,
) -> (
    Simulation,
    Vec<Vec<RodTracker>>,
    Vec<Vec<rodtrack_core::calib::RodCalibration>>,
) {
    let mut scene = SceneConfig::default();
    let mut cams = default_cameras();
    apply_variation(variation, &mut scene, &mut cams).unwrap();
    if !noise {
        for c in &mut cams {
            c.noise = NoiseModel::none();
        }
    }
    let seed: u64 = std::env::var("SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let sc = Scenario::by_name(scenario, &scene, seed)
        .unwrap()
        .with_frames(frames);
    let mut sim = Simulation::new(scene, cams, sc, RenderMode::Fast)
        .unwrap()
        .with_seed(seed);
    let mut all = Vec::new();
    let mut cals = Vec::new();
    // A calibration file (e.g. from `rodtrack calibrate --auto`) instead of calibrating here.
    if let Ok(path) = std::env::var("CALIB") {
        let text = std::fs::read_to_string(&path).unwrap();
        let file: rodtrack_core::calib::CalibrationFile = toml::from_str(&text).unwrap();
        for c in &file.cameras {
            let trs = c
                .rods
                .iter()
                .map(|r| RodTracker::new(r, c.image_width, c.image_height, Mode::Enhanced).unwrap())
                .collect();
            all.push(trs);
            cals.push(c.rods.clone());
        }
        return (sim, all, cals);
    }
    for cam in 0..sim.cameras().len() {
        let inputs = sim.calibration_inputs(cam, seed).unwrap();
        let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
        let meta = sim.render_reference(cam, &mut buf).unwrap();
        let m = inputs.opencv_model_optional.as_ref().unwrap();
        let intr = CameraIntrinsics::from_opencv(m.camera_matrix, &m.dist_coeffs).unwrap();
        let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
        let mut trs = Vec::new();
        let mut cs = Vec::new();
        for r in &inputs.rods {
            match calibrate_rod(r, &view, Some(&intr)) {
                Ok(c) => {
                    eprintln!(
                        "cam {cam} rod {} code_phase {:.3} radius_ratio {:.4} warnings {:?}",
                        r.rod,
                        c.residuals.reference_code_phase_steps,
                        c.residuals.radius_ratio,
                        c.residuals.warnings
                    );
                    // The true axis across the knots at the marker's middle, at the reference
                    // and at the travel's ends.
                    let rc = sim.scene().rods[r.rod as usize].clone();
                    let h = rc.half_travel_mm();
                    let mut offs = Vec::new();
                    for pos in [-0.9 * h, 0.0, 0.9 * h] {
                        let u = 85.0;
                        let lp = c.knots.at(pos + u);
                        let y = rc.marker_y(u, pos);
                        if let Ok(Some((x, yy))) = sim.project_rod_axis(cam, r.rod as usize, y) {
                            offs.push((x - lp.x) * -lp.ty + (yy - lp.y) * lp.tx);
                        }
                    }
                    eprintln!(
                        "   axis offset from knots at -0.9h, 0, +0.9h (px): {:?}, radius_px {:.2}",
                        offs.iter().map(|o| format!("{o:+.3}")).collect::<Vec<_>>(),
                        c.knots.at(85.0).radius_px
                    );
                    trs.push(RodTracker::new(&c, meta.width, meta.height, Mode::Enhanced).unwrap());
                    cs.push(c);
                }
                Err(e) => eprintln!("cam {cam} rod {}: {e}", r.rod),
            }
        }
        all.push(trs);
        cals.push(cs);
    }
    (sim, all, cals)
}

/// One rendered frame of one camera, with one rod's truth and calibration.
struct OneFrame {
    sim: Simulation,
    buf: Vec<u8>,
    meta: rodtrack_sim::RenderInfo,
    truth: rodtrack_core::Measurement,
    calib: rodtrack_core::calib::RodCalibration,
}

impl OneFrame {
    fn new(name: &str, frames: usize, variation: &str, cam: usize, rod: u32, f: usize) -> Self {
        let (mut sim, _, cals) = setup(name, frames, variation, true);
        let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
        let meta = sim.render(f, cam, &mut buf).unwrap();
        let truth = sim.truth(f, cam).unwrap();
        let truth = truth.iter().find(|t| t.m.rod == rod).unwrap().m;
        let calib = cals[cam].iter().find(|c| c.rod == rod).unwrap().clone();
        println!(
            "truth pos {:.3} ang {:.4}",
            truth.position_mm, truth.angle_rad
        );
        OneFrame {
            sim,
            buf,
            meta,
            truth,
            calib,
        }
    }

    fn view(&self) -> FrameView<'_> {
        let m = &self.meta;
        FrameView::new(&self.buf, m.width, m.height, m.stride, m.format).unwrap()
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    match args[1].as_str() {
        "scenario" => {
            let (name, frames, variation, out) =
                (&args[2], args[3].parse().unwrap(), &args[4], &args[5]);
            let (mut sim, mut trackers, _) = setup(name, frames, variation, true);
            let mut f_out = std::fs::File::create(out).unwrap();
            writeln!(
                f_out,
                "cam,rod,frame,visible,status,tpos,tang,pos,ang,err,theta,gray,amp,reason,centre_px,ratio,eps,share"
            )
            .unwrap();
            // Visible and ok: angle and position errors; not visible but ok: angle errors.
            let (mut ang, mut pos, mut not_ok, mut false_ok) = (vec![], vec![], 0, vec![]);
            for (cam, trs) in trackers.iter_mut().enumerate() {
                let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
                let stride: usize = std::env::var("STRIDE")
                    .ok()
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(1);
                for f in (0..sim.frame_count()).step_by(stride.max(1)) {
                    let meta = sim.render(f, cam, &mut buf).unwrap();
                    let view =
                        FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format)
                            .unwrap();
                    let truth = sim.truth(f, cam).unwrap();
                    for tr in trs.iter_mut() {
                        if let Ok(o) = std::env::var("ONLY") {
                            if o != format!("{cam}:{}", tr.rod()) {
                                continue;
                            }
                        }
                        let r = tr.process(&view).unwrap();
                        let t = truth.iter().find(|t| t.m.rod == tr.rod()).unwrap();
                        let (centre_px, ratio, eps) = tr.learnt(r.position_mm + 75.0);
                        let err = wrap(r.angle_rad - t.m.angle_rad);
                        match (t.visible, r.status == Status::Ok) {
                            (true, true) => {
                                ang.push(err);
                                pos.push(r.position_mm - t.m.position_mm);
                            }
                            (true, false) => not_ok += 1,
                            (false, true) => false_ok.push(err),
                            (false, false) => {}
                        }
                        writeln!(
                            f_out,
                            "{cam},{},{f},{},{},{:.5},{:.6},{:.5},{:.6},{:.6},{:.5},{},{:.4},{},{centre_px:.4},{ratio:.4},{eps:.2},{:.4}",
                            tr.rod(),
                            t.visible as u8,
                            r.status,
                            t.m.position_mm,
                            t.m.angle_rad,
                            r.position_mm,
                            r.angle_rad,
                            if r.status == Status::Ok {
                                wrap(r.angle_rad - t.m.angle_rad)
                            } else {
                                f64::NAN
                            },
                            r.theta_steps,
                            r.gray_step,
                            r.amp_ratio,
                            r.reason,
                            r.stripe_share
                        )
                        .unwrap();
                    }
                }
            }
            // Per rod: the learnt centre line's slope against the true axis' across the
            // calibrated line, over the travel at bit space 0.
            for (cam, trs) in trackers.iter().enumerate() {
                for tr in trs {
                    if std::env::var("ONLY").is_ok_and(|o| o != format!("{cam}:{}", tr.rod())) {
                        continue;
                    }
                    let rc = sim.scene().rods[tr.rod() as usize].clone();
                    let h = rc.half_travel_mm();
                    let u = Marker::v1().bit_space_centre_mm(0);
                    let mut learnt = [0.0; 2];
                    let mut truth = [0.0; 2];
                    for (k, pos) in [-0.9 * h, 0.9 * h].into_iter().enumerate() {
                        learnt[k] = tr.learnt(pos + u).0;
                        let lp = tr.knots().at(pos + u);
                        if let Ok(Some((x, y))) =
                            sim.project_rod_axis(cam, tr.rod() as usize, rc.marker_y(u, pos))
                        {
                            truth[k] = (x - lp.x) * -lp.ty + (y - lp.y) * lp.tx;
                        }
                    }
                    let per100 = 100.0 / (1.8 * h);
                    println!(
                        "camera {cam} rod {}: centre slope learnt {:+.3}, true {:+.3} px per 100 mm",
                        tr.rod(),
                        (learnt[1] - learnt[0]) * per100,
                        (truth[1] - truth[0]) * per100
                    );
                    if std::env::var_os("RINGS").is_some() {
                        let rings: Vec<String> = tr
                            .centre_fit()
                            .rings()
                            .filter(|r| r.1 > 0.0)
                            .map(|(white, n, b)| {
                                let b = b.map_or("-".to_string(), |b| format!("{:+.3}", b * 100.0));
                                format!("{}{n:.0}:{b}", if white { "w" } else { "b" })
                            })
                            .collect();
                        println!(
                            "  rings (samples: slope px per 100 mm): {}",
                            rings.join(" ")
                        );
                    }
                }
            }
            let stats = |v: &[f64]| {
                let n = v.len().max(1) as f64;
                let m = v.iter().sum::<f64>() / n;
                let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt();
                (sd, v.iter().fold(0.0f64, |a, b| a.max(b.abs())))
            };
            let gross = ang.iter().filter(|a| a.abs() >= TAU / 32.0).count();
            let (a_sd, a_max) = stats(&ang);
            let (p_sd, p_max) = stats(&pos);
            let wrong_ok = false_ok.iter().filter(|a| a.abs() > 0.2).count();
            println!(
                "{name} {variation}, each camera: {} rows ok on visible markers, {not_ok} not ok, \
                 {gross} gross; angle std {a_sd:.4} max {a_max:.4} rad; position std {p_sd:.4} \
                 max {p_max:.4} mm; {} ok on hidden markers, {wrong_ok} off by > 0.2 rad",
                ang.len(),
                false_ok.len()
            );
        }
        "grid" => {
            let (variation, noise, out) = (&args[2], args[3] == "1", &args[4]);
            let n_pos: usize = args.get(5).map(|s| s.parse().unwrap()).unwrap_or(5);
            let n_ang: usize = args.get(6).map(|s| s.parse().unwrap()).unwrap_or(32);
            let (mut sim, trackers, _) = setup("static", 1, variation, noise);
            let halves: Vec<f64> = sim
                .scene()
                .rods
                .iter()
                .map(|r| r.half_travel_mm())
                .collect();
            let mut f_out = std::fs::File::create(out).unwrap();
            writeln!(
                f_out,
                "cam,rod,ip,ia,visible,status,tpos,tang,pos,ang,err,theta,gray,amp"
            )
            .unwrap();
            let mut k = 0u64;
            for ip in 0..n_pos {
                for ia in 0..n_ang {
                    k += 1;
                    let state = WorldState {
                        rods: halves
                            .iter()
                            .enumerate()
                            .map(|(i, &h)| {
                                let fp = if n_pos > 1 {
                                    ip as f64 / (n_pos - 1) as f64
                                } else {
                                    0.5
                                };
                                RodPose {
                                    position_mm: -0.9 * h + 1.8 * h * fp,
                                    // offset per rod so the rods do not all share an angle
                                    angle_rad: (ia as f64 + 0.137 * i as f64) * TAU / n_ang as f64,
                                    velocity_mm_s: 0.0,
                                    angular_velocity_rad_s: 0.0,
                                }
                            })
                            .collect(),
                        hands: vec![],
                        ball: None,
                    };
                    for (cam, trs) in trackers.iter().enumerate() {
                        let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
                        let meta = sim.render_state(cam, &state, k, &mut buf).unwrap();
                        let view =
                            FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format)
                                .unwrap();
                        for tr0 in trs {
                            let mut tr = tr0.clone();
                            let r = tr.process(&view).unwrap();
                            let i = tr.rod() as usize;
                            let pose = state.rods[i];
                            let vis = sim.marker_status(cam, i, &state).unwrap() == Status::Ok;
                            writeln!(
                                f_out,
                                "{cam},{i},{ip},{ia},{},{},{:.5},{:.6},{:.5},{:.6},{:.6},{:.5},{},{:.4}",
                                vis as u8,
                                r.status,
                                pose.position_mm,
                                pose.angle_rad.rem_euclid(TAU),
                                r.position_mm,
                                r.angle_rad,
                                if r.status == Status::Ok {
                                    wrap(r.angle_rad - pose.angle_rad)
                                } else {
                                    f64::NAN
                                },
                                r.theta_steps,
                                r.gray_step,
                                r.amp_ratio
                            )
                            .unwrap();
                        }
                    }
                }
            }
        }
        "profile" => {
            // Luma along the rod's line and across the face at each bit space, one frame.
            let (name, frames, cam, rod, f) = (
                &args[2],
                args[3].parse().unwrap(),
                args[4].parse::<usize>().unwrap(),
                args[5].parse::<u32>().unwrap(),
                args[6].parse::<usize>().unwrap(),
            );
            let one = OneFrame::new(name, frames, "default", cam, rod, f);
            let (view, c, m, pos) = (one.view(), &one.calib, Marker::v1(), one.truth.position_mm);
            let mut line = String::new();
            for u in (-4..=112).step_by(2) {
                let lp = c.knots.at(pos + u as f64);
                let v = view.luma_bilinear(lp.x as f32, lp.y as f32);
                line += &format!("{u}:{v:.0} ");
            }
            println!("along: {line}");
            for k in 0..5u32 {
                let lp = c.knots.at(pos + m.bit_space_centre_mm(k));
                let mut l = String::new();
                for j in -9..=9 {
                    let (x, y) = lp.offset(0.0, j as f64 / 10.0 * lp.radius_px);
                    l += &format!("{:.0} ", view.luma_bilinear(x as f32, y as f32));
                }
                println!("bit {k} across: {l}");
            }
        }
        "rings" => {
            // The rings' silhouettes of one rod in one frame against the true axis.
            let (name, frames, variation, cam, rod, f) = (
                &args[2],
                args[3].parse().unwrap(),
                &args[4],
                args[5].parse::<usize>().unwrap(),
                args[6].parse::<u32>().unwrap(),
                args[7].parse::<usize>().unwrap(),
            );
            let one = OneFrame::new(name, frames, variation, cam, rod, f);
            let (view, c, m, pos) = (one.view(), &one.calib, Marker::v1(), one.truth.position_mm);
            let (sim, rc) = (&one.sim, one.sim.scene().rods[rod as usize].clone());
            for u in rodtrack_core::track::ring_rows(&m) {
                let lp = c.knots.at(pos + u);
                let y = rc.marker_y(u, pos);
                let true_off = sim
                    .project_rod_axis(cam, rod as usize, y)
                    .ok()
                    .flatten()
                    .map(|(x, yy)| (x - lp.x) * -lp.ty + (yy - lp.y) * lp.tx);
                let sil = rodtrack_core::track::ring_silhouette(&view, &lp);
                println!(
                    "u {u:6.1}: silhouette {:?} radius_px {:.2} true offset {:?}",
                    sil.map(|(c, hw)| (format!("{c:+.3}"), format!("{:.4}", hw / lp.radius_px))),
                    lp.radius_px,
                    true_off.map(|o| format!("{o:+.3}"))
                );
                let mut l = String::new();
                for j in -20..=20 {
                    let (x, yy) = lp.offset(0.0, j as f64 * 0.1 * lp.radius_px);
                    l += &format!("{:.0} ", view.luma_bilinear(x as f32, yy as f32));
                }
                println!("   across (-2R..2R): {l}");
            }
        }
        "rings-travel" => rings_travel(&args),
        other => panic!("unknown mode {other}"),
    }
}

/// Running sums of one ring row's silhouette offsets from the true axis against the axis
/// coordinate `s`.
#[derive(Default, Clone, Copy)]
struct RowStats {
    n: f64,
    s: f64,
    ss: f64,
    d: f64,
    dd: f64,
    sd: f64,
    ratio: f64,
}

impl RowStats {
    fn add(&mut self, s_mm: f64, d_px: f64, ratio: f64) {
        self.n += 1.0;
        self.s += s_mm;
        self.ss += s_mm * s_mm;
        self.d += d_px;
        self.dd += d_px * d_px;
        self.sd += s_mm * d_px;
        self.ratio += ratio;
    }

    /// (mean, std, mean ratio, slope per 100 mm).
    fn summary(&self) -> (f64, f64, f64, f64) {
        let n = self.n.max(1.0);
        let (ms, md) = (self.s / n, self.d / n);
        let var_s = (self.ss / n - ms * ms).max(1e-9);
        let sd = (self.dd / n - md * md).max(0.0).sqrt();
        (
            md,
            sd,
            self.ratio / n,
            100.0 * (self.sd / n - ms * md) / var_s,
        )
    }
}

/// Mode `rings-travel`: see the file's top.
fn rings_travel(args: &[String]) {
    use rodtrack_core::track::{ring_silhouette_scan, BLACK_RING_SCAN, WHITE_RING_SCAN};
    let (name, frames, variation, cam) = (
        &args[2],
        args[3].parse().unwrap(),
        &args[4],
        args[5].parse::<usize>().unwrap(),
    );
    let rods: Vec<u32> = args[6].split(',').map(|s| s.parse().unwrap()).collect();
    let stride: usize = std::env::var("STRIDE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2);
    let (mut sim, _, cals) = setup(name, frames, variation, true);
    let m = Marker::v1();
    let rows: Vec<(f64, bool)> = rodtrack_core::track::silhouette_rings(&m);
    // Per rod: per row, and the true axis against the calibrated line.
    let mut stats = vec![vec![RowStats::default(); rows.len()]; rods.len()];
    let mut axis = vec![RowStats::default(); rods.len()];
    let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
    for f in (0..sim.frame_count()).step_by(stride.max(1)) {
        let meta = sim.render(f, cam, &mut buf).unwrap();
        let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
        let truth = sim.truth(f, cam).unwrap();
        for (ir, &rod) in rods.iter().enumerate() {
            let Some(t) = truth.iter().find(|t| t.m.rod == rod && t.visible) else {
                continue;
            };
            let Some(c) = cals[cam].iter().find(|c| c.rod == rod) else {
                continue;
            };
            let rc = sim.scene().rods[rod as usize].clone();
            let pos = t.m.position_mm;
            for (k, &(u, white)) in rows.iter().enumerate() {
                let lp = c.knots.at(pos + u);
                let Some(true_off) = sim
                    .project_rod_axis(cam, rod as usize, rc.marker_y(u, pos))
                    .unwrap()
                    .map(|(x, y)| (x - lp.x) * -lp.ty + (y - lp.y) * lp.tx)
                else {
                    continue;
                };
                if white {
                    axis[ir].add(pos + u, true_off, 1.0);
                }
                let scan = if white {
                    &WHITE_RING_SCAN
                } else {
                    &BLACK_RING_SCAN
                };
                let sil = ring_silhouette_scan(&view, &lp, scan);
                // Far off: a hand or a figure, which the tracker's gates refuse.
                if let Some((centre, hw)) = sil.filter(|s| (s.0 - true_off).abs() < 3.0) {
                    stats[ir][k].add(pos + u, centre - true_off, hw / lp.radius_px);
                }
            }
        }
    }
    for (ir, &rod) in rods.iter().enumerate() {
        println!(
            "camera {cam} rod {rod}: true axis off the calibrated line by {:+.3} px per 100 mm",
            axis[ir].summary().3
        );
        for (k, &(u, white)) in rows.iter().enumerate() {
            let (mean, sd, ratio, slope) = stats[ir][k].summary();
            println!(
                "  {} ring u {u:5.1} mm: {:4} frames, silhouette - axis {mean:+.3} px (std {sd:.3}), \
                 half width / radius {ratio:.3}, along the travel {slope:+.3} px per 100 mm",
                if white { "white" } else { "black" },
                stats[ir][k].n
            );
        }
    }
}
