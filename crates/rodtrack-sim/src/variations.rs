//! Named setup variations the tracker is tested on, applied to a scene and its cameras.

use crate::cameras::SimCamera;
use crate::scene::SceneConfig;
use crate::SimError;

/// Names accepted by [`apply_variation`].
pub const VARIATION_NAMES: [&str; 6] = [
    "default",
    "yaw180",
    "flipped_markers",
    "strong_distortion",
    "dim",
    "thick_rod",
];

/// Applies a named variation, `asbuilt:SEED` (see [`as_built`]), `exposure:US`, or several
/// of them joined by `+` (applied left to right, e.g. `asbuilt:3+exposure:2000`):
/// - `yaw180`: every camera turned by 180 degrees about its viewing axis (same place);
/// - `flipped_markers`: every marker's `u` axis reversed (centre kept);
/// - `strong_distortion`: `k1 = -0.35` on every camera;
/// - `dim`: camera brightness 0.3;
/// - `thick_rod`: 20 mm rods (the marker wraps once around them);
/// - `exposure:US`: every camera exposes for `US` microseconds (the motion blur: a ball at 15
///   m/s smears 30 mm in 2000 us), its gain lowered to keep the image's levels, as an operator
///   sets a camera up for a longer exposure.
pub fn apply_variation(
    name: &str,
    scene: &mut SceneConfig,
    cameras: &mut [SimCamera],
) -> Result<(), SimError> {
    if name.contains('+') {
        for part in name.split('+') {
            apply_variation(part, scene, cameras)?;
        }
        return Ok(());
    }
    if let Some(us) = name.strip_prefix("exposure:") {
        let us: f64 = us
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && *v > 0.0)
            .ok_or_else(|| {
                SimError::Config(format!(
                    "setup variation `{name}`: `exposure:` takes a positive number of microseconds"
                ))
            })?;
        for c in cameras.iter_mut() {
            c.brightness *= c.exposure_us / us;
            c.exposure_us = us;
        }
        return Ok(());
    }
    if let Some(seed) = name.strip_prefix("asbuilt:") {
        let seed: u64 = seed.parse().map_err(|_| {
            SimError::Config(format!(
                "setup variation `{name}`: `asbuilt:` takes a whole number seed"
            ))
        })?;
        as_built(seed, scene, cameras);
        return Ok(());
    }
    match name {
        "default" => {}
        "yaw180" => {
            for c in cameras.iter_mut() {
                // Turning the camera about its own viewing axis: compose the rotation.
                let r = c.camera.pose.rotation;
                let flip = [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]];
                let mut nr = [[0.0; 3]; 3];
                for i in 0..3 {
                    for j in 0..3 {
                        nr[i][j] = (0..3).map(|k| flip[i][k] * r[k][j]).sum();
                    }
                }
                let centre = c.camera.pose.centre_world();
                c.camera.pose.rotation = nr;
                let t: Vec<f64> = (0..3)
                    .map(|i| -(0..3).map(|k| nr[i][k] * centre[k]).sum::<f64>())
                    .collect();
                c.camera.pose.translation_mm = [t[0], t[1], t[2]];
            }
        }
        "flipped_markers" => {
            let dirs: Vec<f64> = scene.rods.iter().map(|r| -r.marker_dir).collect();
            *scene = scene.clone().with_marker_dirs(&dirs);
        }
        "strong_distortion" => {
            for c in cameras.iter_mut() {
                c.camera.intrinsics.k1 = -0.35;
            }
        }
        "dim" => {
            for c in cameras.iter_mut() {
                c.brightness = 0.3;
            }
        }
        "thick_rod" => *scene = scene.clone().with_rod_diameter(20.0),
        other => {
            return Err(SimError::Config(format!(
                "unknown setup variation `{other}`; known: {}",
                VARIATION_NAMES.join(", ")
            )))
        }
    }
    Ok(())
}

/// A table as built rather than as drawn, drawn at random from `seed`: each camera tilted up
/// to 4 degrees about both image axes and turned up to 3 degrees about its viewing axis,
/// shifted by up to 25 mm, its focal length within 3 %, `k1` in [-0.35, -0.15], its principal
/// point up to 15 px off; each rod up to 1 mm off its place across the table and 0.5 mm in
/// height; each marker's print at a random angle around its rod (the seam).
pub fn as_built(seed: u64, scene: &mut SceneConfig, cameras: &mut [SimCamera]) {
    let mut rng = crate::rng::Rng::new(seed ^ 0xA5B1_u64.rotate_left(40));
    for c in cameras.iter_mut() {
        let centre = c.camera.pose.centre_world();
        let shift = [
            rng.range(-25.0, 25.0),
            rng.range(-25.0, 25.0),
            rng.range(-25.0, 25.0),
        ];
        let centre = [
            centre[0] + shift[0],
            centre[1] + shift[1],
            centre[2] + shift[2],
        ];
        let yaw = rng.range(-3.0, 3.0).to_radians();
        let pitch = rng.range(-4.0, 4.0).to_radians();
        let roll = rng.range(-4.0, 4.0).to_radians();
        // The camera's own rotation composed in camera coordinates: about z (yaw), x (pitch:
        // along the rods), y (roll: across them).
        let (sy, cy) = yaw.sin_cos();
        let (sp, cp) = pitch.sin_cos();
        let (sr, cr) = roll.sin_cos();
        let rz = [[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]];
        let rx = [[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]];
        let ry = [[cr, 0.0, sr], [0.0, 1.0, 0.0], [-sr, 0.0, cr]];
        let r = mat(&ry, &mat(&rx, &mat(&rz, &c.camera.pose.rotation)));
        let t: Vec<f64> = (0..3)
            .map(|i| -(0..3).map(|k| r[i][k] * centre[k]).sum::<f64>())
            .collect();
        c.camera.pose.rotation = r;
        c.camera.pose.translation_mm = [t[0], t[1], t[2]];
        let k = &mut c.camera.intrinsics;
        let f = k.fx * rng.range(0.97, 1.03);
        k.fx = f;
        k.fy = f;
        k.cx += rng.range(-15.0, 15.0);
        k.cy += rng.range(-15.0, 15.0);
        k.k1 = rng.range(-0.35, -0.15);
    }
    for r in scene.rods.iter_mut() {
        r.x_mm += rng.range(-1.0, 1.0);
        r.z_mm += rng.range(-0.5, 0.5);
        r.psi0_rad = rng.range(0.0, std::f64::consts::TAU);
    }
}

fn mat(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cameras::default_cameras;

    #[test]
    fn yaw180_keeps_the_camera_in_place_and_turns_the_image() {
        let mut scene = SceneConfig::default();
        let mut cams = default_cameras();
        let before = cams[0].camera;
        apply_variation("yaw180", &mut scene, &mut cams).unwrap();
        let after = cams[0].camera;
        let (a, b) = (before.pose.centre_world(), after.pose.centre_world());
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-9);
        }
        // A point right of the centre now appears left of it.
        let p = [700.0, 300.0, 80.0];
        let (u0, v0) = before.project(p).unwrap();
        let (u1, v1) = after.project(p).unwrap();
        let (cx, cy) = (before.intrinsics.cx, before.intrinsics.cy);
        assert!((u0 - cx) * (u1 - cx) < 0.0 && (v0 - cy) * (v1 - cy) < 0.0);
        for n in VARIATION_NAMES {
            let mut s = SceneConfig::default();
            let mut c = default_cameras();
            apply_variation(n, &mut s, &mut c).unwrap();
        }
        assert!(apply_variation("nope", &mut scene, &mut cams).is_err());
        assert!(apply_variation("exposure:-5", &mut scene, &mut cams).is_err());
        assert!(apply_variation("asbuilt:3+nope", &mut scene, &mut cams).is_err());
    }

    #[test]
    fn setups_join_and_an_exposure_keeps_the_levels() {
        let mut scene = SceneConfig::default();
        let mut cams = default_cameras();
        apply_variation("asbuilt:3+exposure:2000", &mut scene, &mut cams).unwrap();
        let (mut s2, mut c2) = (SceneConfig::default(), default_cameras());
        apply_variation("asbuilt:3", &mut s2, &mut c2).unwrap();
        for (a, b) in cams.iter().zip(&c2) {
            assert_eq!(a.camera, b.camera);
            assert_eq!(a.exposure_us, 2000.0);
            assert!((a.brightness * a.exposure_us - b.brightness * b.exposure_us).abs() < 1e-9);
        }
    }
}
