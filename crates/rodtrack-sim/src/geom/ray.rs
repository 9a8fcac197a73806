//! The 3-vector type and the ray tests against primitives: cylinders along `y`, boxes.

/// A 3-vector.
pub type V3 = [f32; 3];

#[inline(always)]
pub(crate) fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// A rod hit (or near miss, for the antialiased silhouette).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RodSample {
    pub t: f32,
    /// World `y` of the hit.
    pub y: f32,
    /// Angle of the surface normal from `+z` towards `+x`: `atan2(n_x, n_z)`.
    pub a: f32,
    /// Diffuse shading factor.
    pub shade: f32,
    /// Specular factor (times the steel's specular strength).
    pub spec: f32,
    /// Texture footprint half-widths, mm along the rod and rad around it.
    pub hu: f32,
    pub hpsi: f32,
    /// Silhouette coverage.
    pub alpha: f32,
}

/// Ray against an infinite cylinder along `y` through `(x, z)` with radius `r`. `foot` is the
/// angular size of the pixel (or sub-sample), for the footprint and the silhouette coverage.
#[inline]
pub(crate) fn rod_sample(
    x: f32,
    z: f32,
    r: f32,
    o: V3,
    d: V3,
    foot: f32,
    ambient: f32,
) -> Option<RodSample> {
    let ox = o[0] - x;
    let oz = o[2] - z;
    let a = d[0] * d[0] + d[2] * d[2];
    if a < 1e-12 {
        return None;
    }
    let b = ox * d[0] + oz * d[2];
    let tc = -b / a;
    if tc <= 0.0 {
        return None;
    }
    let cx = ox + tc * d[0];
    let cz = oz + tc * d[2];
    let dmin2 = cx * cx + cz * cz;
    let w = tc * foot;
    let lim = r + 0.5 * w;
    if dmin2 >= lim * lim {
        return None;
    }
    let dmin = dmin2.sqrt();
    let alpha = (0.5 + (r - dmin) / w.max(1e-6)).clamp(0.0, 1.0);
    let (t, nx, nz) = if dmin < r {
        let t = tc - ((r * r - dmin2) / a).sqrt();
        ((t), (ox + t * d[0]) / r, (oz + t * d[2]) / r)
    } else {
        let inv = 1.0 / dmin.max(1e-9);
        (tc, cx * inv, cz * inv)
    };
    let y = o[1] + t * d[1];
    let shade = ambient + (1.0 - ambient) * nz.max(0.0);
    // Half vector between the light (straight up) and the view direction (-d).
    let (hx, hy, hz) = (-d[0], -d[1], 1.0 - d[2]);
    let hn = (hx * hx + hy * hy + hz * hz).sqrt().max(1e-9);
    let ndh = ((nx * hx + nz * hz) / hn).max(0.0);
    let ndh2 = ndh * ndh;
    let ndh4 = ndh2 * ndh2;
    let ndh8 = ndh4 * ndh4;
    let spec = ndh8 * ndh8 * ndh8 * ndh8; // ^32
    let cos_i = (nx * d[0] + nz * d[2]).abs().max(0.08);
    let sin_ax = (1.0 - d[1] * d[1]).max(0.05).sqrt();
    let hu = 0.5 * w / sin_ax;
    let hpsi = (0.5 * w / (r * cos_i)).min(std::f32::consts::PI);
    Some(RodSample {
        t,
        y,
        a: nx.atan2(nz),
        shade,
        spec,
        hu,
        hpsi,
        alpha,
    })
}

/// Ray against an infinite cylinder along `y`: entry distance and world `y` of the hit.
#[inline]
pub(crate) fn rod_hit(x: f32, z: f32, r: f32, o: V3, d: V3) -> Option<(f32, f32)> {
    let ox = o[0] - x;
    let oz = o[2] - z;
    let a = d[0] * d[0] + d[2] * d[2];
    let b = ox * d[0] + oz * d[2];
    let c = ox * ox + oz * oz - r * r;
    let disc = b * b - a * c;
    if disc <= 0.0 || a < 1e-12 {
        return None;
    }
    let t = (-b - disc.sqrt()) / a;
    (t > 0.0).then(|| (t, o[1] + t * d[1]))
}

/// Ray against an axis-aligned box: entry distance and the entry face's axis and sign.
#[inline]
pub(crate) fn ray_box(o: V3, inv: V3, lo: V3, hi: V3) -> Option<(f32, usize, f32)> {
    let mut tmin = 0.0f32;
    let mut tmax = f32::INFINITY;
    let mut axis = 0usize;
    let mut sign = 0.0f32;
    for k in 0..3 {
        let t1 = (lo[k] - o[k]) * inv[k];
        let t2 = (hi[k] - o[k]) * inv[k];
        let (tn, tf, s) = if t1 < t2 {
            (t1, t2, -1.0)
        } else {
            (t2, t1, 1.0)
        };
        if tn > tmin {
            tmin = tn;
            axis = k;
            sign = s;
        }
        tmax = tmax.min(tf);
        if tmin > tmax {
            return None;
        }
    }
    if sign == 0.0 {
        return None; // origin inside the box
    }
    Some((tmin, axis, sign))
}

#[inline]
pub(super) fn inv_dir(d: V3) -> V3 {
    d.map(|v| {
        if v.abs() < 1e-20 {
            1e20f32.copysign(v)
        } else {
            1.0 / v
        }
    })
}
