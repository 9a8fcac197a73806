//! What the enhanced mode learns over frames: the rod's centre line from the rings'
//! silhouettes. Each silhouette gives two edges; a bright background beside one of them (a
//! figure, the table's wall) moves that edge alone, and such samples must not drag the line.
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_core::track::CentreFit;

/// The true centre offset across the calibrated line, px, at axis coordinate `s` mm.
fn truth(s_mm: f64) -> f64 {
    0.2 + 0.002 * s_mm
}

const RATIO: f64 = 0.91;
const RADIUS_PX: f64 = 11.5;

/// A small deterministic noise source (uniform in [-1, 1]).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// One silhouette at `s` with edge noise `noise_px` (uniform) and the left edge moved out by
/// `left_out_px`: (centre offset, half width over the radius).
fn silhouette(s_mm: f64, noise_px: f64, left_out_px: f64, rng: &mut Lcg) -> (f64, f64) {
    let c = truth(s_mm);
    let hw = RATIO * RADIUS_PX;
    let left = c - hw - left_out_px + noise_px * rng.next();
    let right = c + hw + noise_px * rng.next();
    (0.5 * (left + right), 0.5 * (right - left) / RADIUS_PX)
}

/// Learns a clean line over `[0, 100]` mm: most samples are taken.
fn learnt_clean(rng: &mut Lcg) -> CentreFit {
    let mut fit = CentreFit::default();
    let mut taken = 0;
    for i in 0..400 {
        let s = (i % 100) as f64;
        let (c, r) = silhouette(s, 0.05, 0.0, rng);
        taken += fit.add(s, c, r, RADIUS_PX) as usize;
    }
    assert!(taken >= 390, "clean samples taken: {taken} of 400");
    fit
}

#[test]
fn a_bright_background_beside_one_edge_does_not_drag_the_centre_line() {
    let mut rng = Lcg(7);
    let mut fit = learnt_clean(&mut rng);
    let at = 200.0;
    let before = fit.at(at).0 - truth(at);
    // The rod then stays where something bright is beside its left edge: each silhouette's
    // centre is 0.6 px off (inside the old 0.75 px gate), its half width 0.6 px too wide.
    let mut taken = 0;
    for i in 0..3000 {
        let s = 170.0 + (i % 70) as f64;
        let (c, r) = silhouette(s, 0.05, 1.2, &mut rng);
        taken += fit.add(s, c, r, RADIUS_PX) as usize;
    }
    let after = fit.at(at).0 - truth(at);
    eprintln!(
        "error at {at} mm: before {before:+.3} px, after {after:+.3} px; {taken} of 3000 contaminated samples taken"
    );
    assert!(taken <= 30, "contaminated samples taken: {taken}");
    assert!(after.abs() < 0.1, "the line moved to {after:+.3} px off");
}

#[test]
fn clean_samples_at_new_places_extend_the_line() {
    let mut rng = Lcg(11);
    let mut fit = learnt_clean(&mut rng);
    let mut taken = 0;
    for i in 0..1000 {
        let s = (i % 250) as f64;
        let (c, r) = silhouette(s, 0.05, 0.0, &mut rng);
        taken += fit.add(s, c, r, RADIUS_PX) as usize;
    }
    assert!(taken >= 950, "clean samples taken: {taken} of 1000");
    for s in [0.0, 120.0, 240.0] {
        let e = fit.at(s).0 - truth(s);
        assert!(e.abs() < 0.02, "at {s} mm: {e:+.4} px");
    }
    assert!((fit.at(100.0).1 - RATIO).abs() < 0.005);
}

#[test]
fn a_line_that_runs_elsewhere_than_extrapolated_is_still_learnt() {
    // Learnt over [0, 60] mm only (slope not yet known), then the rod goes to [150, 250] mm
    // where the line runs 0.4 px away from the first part's mean: both edges move alike.
    let mut rng = Lcg(13);
    let mut fit = CentreFit::default();
    for i in 0..300 {
        let s = (i % 60) as f64;
        let (c, r) = silhouette(s, 0.05, 0.0, &mut rng);
        fit.add(s, c, r, RADIUS_PX);
    }
    let mut taken = 0;
    for i in 0..1000 {
        let s = 150.0 + (i % 100) as f64;
        let (c, r) = silhouette(s, 0.05, 0.0, &mut rng);
        taken += fit.add(s, c, r, RADIUS_PX) as usize;
    }
    assert!(taken >= 950, "clean samples taken: {taken} of 1000");
    let e = fit.at(200.0).0 - truth(200.0);
    assert!(e.abs() < 0.02, "at 200 mm: {e:+.4} px");
}

/// The mm scale: calibration measured it at the reference (scale error 0 there). A rod that
/// stays 120 mm away, where its barcode shows a scale error of 0.5 %, with the error growing
/// steadily along the rod (a camera pitched along it), is 0.3 mm off on the calibrated line
/// (the integral of the error from the reference): that, not twice it, is what comes off.
#[test]
fn a_still_rod_far_from_the_reference_gets_the_integral_of_the_scale_error() {
    use rodtrack_core::track::ScaleFit;
    let (s_ref, s, b) = (40.0, 160.0, 0.005);
    let mut fit = ScaleFit::default();
    assert_eq!(fit.to_true(s, s_ref), s, "nothing learnt: unchanged");
    let expect = s - 0.5 * b * (s - s_ref);
    for k in 0..200 {
        assert!(fit.add(s, b));
        let got = fit.to_true(s, s_ref);
        assert!(
            (got - expect).abs() < 0.01,
            "after {} frames: {got:.4} mm, expected {expect:.4} mm",
            k + 1
        );
    }
    // The reference itself stays where calibration put it.
    assert!((fit.to_true(s_ref, s_ref) - s_ref).abs() < 1e-9);
}

/// Each ring's silhouette carries a small bias of its own (its neighbours in the print blur
/// into it). A marker that moves a little around one place must not turn those biases into a
/// slope of the line, which would carry them far along the travel.
#[test]
fn the_rings_own_biases_do_not_make_a_slope() {
    use rodtrack_core::track::Silhouette;
    let rings = [
        (42.0, 0.0),
        (46.0, 0.0),
        (50.0, 0.0),
        (54.0, 0.09),
        (70.0, -0.05),
    ];
    let i_ring = |u: f64| rings.iter().position(|r| r.0 == u).unwrap();
    let mut fit = CentreFit::default();
    let mut rng = Lcg(17);
    for i in 0..900 {
        let pos = [-5.0, 0.0, 5.0][i % 3];
        let frame: Vec<Silhouette> = rings
            .iter()
            .map(|&(u, bias)| {
                let s = pos + u;
                let (c, r) = silhouette(s, 0.02, 0.0, &mut rng);
                Silhouette {
                    ring: i_ring(u),
                    white: true,
                    contrast_dn: 100.0,
                    s_mm: s,
                    offset_px: c + bias,
                    ratio: r,
                    radius_px: RADIUS_PX,
                }
            })
            .collect();
        fit.add_frame(&frame);
    }
    // The line's own slope (0.002 px/mm) is not observable over +-5 mm either: what matters
    // is that no slope from the rings' biases is made up.
    let e = fit.at(250.0).0 - fit.at(52.4).0;
    assert!(e.abs() < 0.03, "extrapolated 200 mm away: {e:+.3} px");
}

/// A ring: marker `u`, white, contrast with the background (DN), and an extra offset of its
/// silhouette as a function of `s`.
type Ring = (f64, bool, f64, fn(f64) -> f64);

/// One frame of `rings` with the marker at `pos`.
fn frame_of(rings: &[Ring], pos: f64, rng: &mut Lcg) -> Vec<rodtrack_core::track::Silhouette> {
    rings
        .iter()
        .enumerate()
        .map(|(i, &(u, white, contrast_dn, extra))| {
            let s = pos + u;
            let (c, r) = silhouette(s, 0.03, 0.0, rng);
            rodtrack_core::track::Silhouette {
                ring: i,
                white,
                contrast_dn,
                s_mm: s,
                offset_px: c + extra(s),
                ratio: r,
                radius_px: RADIUS_PX,
            }
        })
        .collect()
}

fn none(_: f64) -> f64 {
    0.0
}

/// Something beside the rod at one stretch of the travel (a line on the table, a figure)
/// moves the silhouettes of the rings that pass there, more the further along: a slope of
/// their own of 0.003 px/mm. A third of the rings see it; the line must follow the others
/// (the mean of all would be 0.001 px/mm off: 0.1 px over 100 mm, 0.009 rad on a rod of
/// 11 px radius).
#[test]
fn rings_that_something_beside_the_rod_sways_do_not_bend_the_line() {
    fn swayed(s: f64) -> f64 {
        0.003 * (s - 50.0)
    }
    let rings: Vec<Ring> = [
        (10.0, none as fn(f64) -> f64),
        (14.0, none),
        (26.0, swayed),
        (34.0, none),
        (42.0, swayed),
        (46.0, swayed),
        (50.0, none),
        (54.0, none),
        (70.0, none),
    ]
    .iter()
    .map(|&(u, f)| (u, true, 100.0, f))
    .collect();
    let mut fit = CentreFit::default();
    let mut rng = Lcg(19);
    for i in 0..2000 {
        let pos = -100.0 + (i % 201) as f64;
        fit.add_frame(&frame_of(&rings, pos, &mut rng));
    }
    let slope = 0.002;
    assert!(
        (fit.slope() - slope).abs() < 0.0002,
        "slope {:.5} px/mm, truth {slope}",
        fit.slope()
    );
}

/// Where the black ink stands out little from the background, its rings' silhouettes are
/// the noisier and the more easily swayed: the line follows the white rings, which stand out
/// more. And the other way round against a bright background.
#[test]
fn the_rings_that_stand_out_more_are_the_witnesses() {
    fn swayed(s: f64) -> f64 {
        -0.002 * s
    }
    for (white_contrast, black_contrast, white_sway, black_sway) in [
        (
            100.0,
            15.0,
            none as fn(f64) -> f64,
            swayed as fn(f64) -> f64,
        ),
        (15.0, 100.0, swayed, none),
    ] {
        let mut rings: Vec<Ring> = Vec::new();
        for k in 0..6 {
            rings.push((10.0 + 8.0 * k as f64, true, white_contrast, white_sway));
            rings.push((14.0 + 8.0 * k as f64, false, black_contrast, black_sway));
        }
        let mut fit = CentreFit::default();
        let mut rng = Lcg(23);
        for i in 0..2000 {
            let pos = -100.0 + (i % 201) as f64;
            fit.add_frame(&frame_of(&rings, pos, &mut rng));
        }
        assert!(
            (fit.slope() - 0.002).abs() < 0.0002,
            "white contrast {white_contrast}, black {black_contrast}: slope {:.5} px/mm",
            fit.slope()
        );
    }
}

/// Rings whose rows hold something of their neighbours (a strong lens bends a ring's image
/// away from the straight row across the rod) are narrower than the others and swayed along
/// the travel. Six of ten such rings: the line follows the four that are as wide as the widest.
#[test]
fn rings_narrowed_by_their_neighbours_are_not_witnesses() {
    fn swayed(s: f64) -> f64 {
        -0.003 * s
    }
    let mut fit = CentreFit::default();
    let mut rng = Lcg(29);
    for i in 0..2000 {
        let pos = -100.0 + (i % 201) as f64;
        let frame: Vec<rodtrack_core::track::Silhouette> = (0..10)
            .map(|k| {
                let narrowed = k % 5 != 0 && k % 5 != 3;
                let s = pos + 10.0 + 6.0 * k as f64;
                let (c, r) = silhouette(s, 0.03, 0.0, &mut rng);
                rodtrack_core::track::Silhouette {
                    ring: k,
                    white: true,
                    contrast_dn: 100.0,
                    s_mm: s,
                    offset_px: c + if narrowed { swayed(s) } else { 0.0 },
                    ratio: r - if narrowed { 0.015 } else { 0.0 },
                    radius_px: RADIUS_PX,
                }
            })
            .collect();
        fit.add_frame(&frame);
    }
    assert!(
        (fit.slope() - 0.002).abs() < 0.0002,
        "slope {:.5} px/mm, truth 0.002",
        fit.slope()
    );
}
