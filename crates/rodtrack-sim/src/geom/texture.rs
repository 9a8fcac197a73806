//! The marker's print as a texture, box-filtered analytically.

use rodtrack_core::Marker;

/// The marker's print, box-filtered analytically over a footprint in `(u, psi)`.
#[derive(Debug, Clone)]
pub(crate) struct MarkerTexture {
    pub len: f32,
    bc0: f32,
    cell: f32,
    /// Black cells before cell `i`.
    prefix: Vec<f32>,
    kernel: Vec<bool>,
    g0: f32,
    bs: f32,
    bits: u32,
    steps: f32,
}

impl MarkerTexture {
    pub fn new(m: &Marker) -> MarkerTexture {
        let mut prefix = vec![0.0f32];
        for &b in m.kernel() {
            let last = *prefix.last().unwrap_or(&0.0);
            prefix.push(last + if b { 1.0 } else { 0.0 });
        }
        MarkerTexture {
            len: m.length_mm() as f32,
            bc0: m.barcode_start_mm() as f32,
            cell: m.cell_mm() as f32,
            prefix,
            kernel: m.kernel().to_vec(),
            g0: m.gray_start_mm() as f32,
            bs: m.bit_space_mm() as f32,
            bits: m.bits(),
            steps: m.steps() as f32,
        }
    }

    /// Black length of the barcode in `[bc0, u]`, mm.
    #[inline]
    fn barcode_cum(&self, u: f32) -> f32 {
        let x = ((u - self.bc0) / self.cell).clamp(0.0, self.kernel.len() as f32);
        let i = (x.floor() as usize).min(self.kernel.len() - 1);
        let frac = x - i as f32;
        (self.prefix[i] + if self.kernel[i] { frac } else { 0.0 }) * self.cell
    }

    /// Mean of bit `k` of `gray(floor(steps psi / 2 pi))` over `[psi - h, psi + h]`.
    #[inline]
    fn bit_mean(&self, k: u32, psi: f32, h: f32) -> f32 {
        let sc = self.steps / std::f32::consts::TAU;
        // Bit k of gray(n) is floor((n + 2^k) / 2^(k+1)) mod 2: it repeats every 2^(k+2) steps
        // and is black over the second half of each period after a shift of 2^k. The top bit
        // (black for n in [steps/2, steps)) repeats every `steps` (n wraps around the rod).
        let (period, shift) = if k + 1 >= self.bits {
            (self.steps, 0.0)
        } else {
            ((4u32 << k) as f32, (1u32 << k) as f32)
        };
        let cum = |s: f32| {
            let x = (s + shift) / period;
            let f = x.floor();
            f * 0.5 + (x - f - 0.5).max(0.0)
        };
        let s0 = (psi - h) * sc;
        let s1 = (psi + h) * sc;
        if s1 - s0 < 1e-4 {
            let x = (0.5 * (s0 + s1) + shift) / period;
            return if x - x.floor() >= 0.5 { 1.0 } else { 0.0 };
        }
        (period * (cum(s1) - cum(s0)) / (s1 - s0)).clamp(0.0, 1.0)
    }

    /// (paper fraction, black fraction) of the footprint `[u - hu, u + hu] x [psi - hpsi,
    /// psi + hpsi]`.
    pub fn coverage(&self, u: f32, psi: f32, hu: f32, hpsi: f32) -> (f32, f32) {
        let hu = hu.max(1e-4);
        let (u0, u1) = (u - hu, u + hu);
        let inv = 1.0 / (u1 - u0);
        let ov = |a: f32, b: f32| (u1.min(b) - u0.max(a)).max(0.0);
        let paper = ov(0.0, self.len) * inv;
        let mut black = self.barcode_cum(u1) - self.barcode_cum(u0);
        for k in 0..self.bits {
            let a = self.g0 + k as f32 * self.bs;
            let o = ov(a, a + self.bs);
            if o > 0.0 {
                black += o * self.bit_mean(k, psi, hpsi);
            }
        }
        (paper, (black * inv).min(paper))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// The analytic box filter agrees with the marker's own point definition.
    #[test]
    fn texture_matches_marker_definition() {
        let m = Marker::v1();
        let t = MarkerTexture::new(&m);
        let mut bad = 0;
        for i in 0..2000 {
            let u = -3.0 + 112.0 * (i as f64 + 0.37) / 2000.0;
            for j in 0..64 {
                // Print angles beyond one turn must wrap.
                let psi = TAU * (j as f64 + 0.29) / 64.0 - TAU + TAU * (i % 3) as f64;
                let (paper, black) = t.coverage(u as f32, psi as f32, 1e-5, 1e-6);
                let inside = (0.0..m.length_mm()).contains(&u);
                assert_eq!(paper > 0.5, inside, "u {u}");
                let want = inside && m.is_black(u, psi);
                if (black > 0.5) != want {
                    bad += 1;
                }
            }
        }
        assert_eq!(bad, 0);
        // A footprint over a whole bit-0 period is half black.
        let (_, b) = t.coverage(75.0, 1.0, 0.1, (TAU / 8.0) as f32 * 0.5);
        assert!((b - 0.5).abs() < 1e-3, "{b}");
    }
}
