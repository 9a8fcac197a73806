//! Light level, glare, shot and read noise and 8-bit quantisation, and the noisy copies of
//! the still image used by the fast path.

use super::renderer::CameraRenderer;
use crate::rng::{hash_words, Rng};

/// Number of noisy copies of the still image kept for the fast path.
const NOISY_COPIES: usize = 8;

impl CameraRenderer {
    fn noise_params(&self) -> (f32, f32) {
        let gain = self.cam.noise.gain_e_per_dn;
        let inv_gain = if gain.is_finite() && gain > 0.0 {
            (1.0 / gain) as f32
        } else {
            0.0
        };
        let read2 = (self.cam.noise.read_noise_dn * self.cam.noise.read_noise_dn) as f32;
        (inv_gain, read2)
    }

    /// Makes the noisy copies of the still image used by the fast path of [`Self::finish`].
    pub(super) fn build_noisy_copies(&mut self, noise: &[f32], seed: u64) {
        let n = if self.cam.noise.is_none() {
            1
        } else {
            NOISY_COPIES
        };
        let rad = std::mem::replace(&mut self.rad, self.bg.clone());
        let mut copies = Vec::with_capacity(n);
        // Antithetic pairs (noise n and -n): per pixel the copies' noise has exactly zero mean
        // and, on average, the model's variance (8 independent draws would show 7/8 of it).
        let half = n.div_ceil(2);
        for k in 0..n {
            let mut out = vec![0u8; self.w * self.h * self.ch];
            let sign = if k >= half { -1.0 } else { 1.0 };
            let seed = hash_words(&[seed, (k % half) as u64]);
            self.finish_full(1.0, 0.0, noise, seed, sign, &mut out);
            copies.push(out);
        }
        self.rad = rad;
        self.noisy_bg = copies;
    }

    /// Light level, glare, noise and quantisation. When the light is as in the still image,
    /// rows come from a noisy copy of it (chosen at random per row) and only the pixels drawn
    /// this frame (marker ranges and object tiles) get fresh noise.
    pub(super) fn finish(
        &mut self,
        brightness: f32,
        glare: f32,
        noise: &[f32],
        seed: u64,
        out: &mut [u8],
    ) {
        let still = brightness == 1.0 && (glare <= 0.0 || self.glare.is_none());
        if !still {
            self.finish_full(brightness, glare, noise, seed, 1.0, out);
            return;
        }
        let rw = self.w * self.ch;
        let mut rng = Rng::new(hash_words(&[seed, 0x00C0_B1E5]));
        let nc = self.noisy_bg.len() as u64;
        for (y, row) in out.chunks_exact_mut(rw).take(self.h).enumerate() {
            let v = rng.below(nc) as usize;
            row.copy_from_slice(&self.noisy_bg[v][y * rw..(y + 1) * rw]);
        }
        let (inv_gain, read2) = self.noise_params();
        let noisy = !self.cam.noise.is_none() && noise.len() > 2 * rw;
        let span = (noise.len().saturating_sub(rw)).max(1) as u64;
        let ch = self.ch;
        for &t in &self.prev_tiles {
            let r = self.tile_rect(t as usize);
            for y in r.y0..r.y1 {
                let a = (y * self.w + r.x0) * ch;
                let b = (y * self.w + r.x1) * ch;
                let off = rng.below(span) as usize;
                let nz = if noisy {
                    &noise[off..off + (b - a)]
                } else {
                    &[][..]
                };
                quantise_span(
                    &self.rad[a..b],
                    nz,
                    &mut out[a..b],
                    1.0,
                    read2,
                    inv_gain,
                    1.0,
                );
            }
        }
        for &(i, a, b) in &self.prev_ranges {
            let off = rng.below(span) as usize;
            for (j, sp) in self.strips[i].px[a..b].iter().enumerate() {
                let p = sp.idx as usize * ch;
                let nz = if noisy {
                    &noise[(off + j * ch) % span as usize..][..ch]
                } else {
                    &[][..]
                };
                quantise_span(
                    &self.rad[p..p + ch],
                    nz,
                    &mut out[p..p + ch],
                    1.0,
                    read2,
                    inv_gain,
                    1.0,
                );
            }
        }
    }

    /// Light level, glare, noise (times `sign`) and quantisation over the whole frame.
    #[allow(clippy::too_many_arguments)]
    fn finish_full(
        &self,
        brightness: f32,
        glare: f32,
        noise: &[f32],
        seed: u64,
        sign: f32,
        out: &mut [u8],
    ) {
        let rw = self.w * self.ch;
        let (inv_gain, read2) = self.noise_params();
        let noisy = !self.cam.noise.is_none() && noise.len() > rw;
        let mut rng = Rng::new(hash_words(&[seed, 0x004E_015E]));
        let span = (noise.len().saturating_sub(rw)).max(1) as u64;
        let glare_map = self.glare.as_deref().filter(|_| glare > 0.0);
        for (y, row) in out.chunks_exact_mut(rw).take(self.h).enumerate() {
            let rad = &self.rad[y * rw..(y + 1) * rw];
            if noisy {
                let off = rng.below(span) as usize;
                let nz = &noise[off..off + rw];
                match glare_map {
                    Some(gm) => {
                        let gr = &gm[y * rw..(y + 1) * rw];
                        for (((o, &r), &n), &g) in row.iter_mut().zip(rad).zip(nz).zip(gr) {
                            let v = r * brightness + g * glare;
                            let s = (read2 + v.max(0.0) * inv_gain).sqrt();
                            *o = quantise(v + sign * s * n);
                        }
                    }
                    None => quantise_span(rad, nz, row, brightness, read2, inv_gain, sign),
                }
            } else {
                for (i, (o, &r)) in row.iter_mut().zip(rad).enumerate() {
                    let g = glare_map.map(|m| m[y * rw + i]).unwrap_or(0.0);
                    *o = quantise(r * brightness + g * glare);
                }
            }
        }
    }
}

/// `out = quantise(b r + sign sigma(b r) n)`; no noise when `nz` is empty.
#[inline]
fn quantise_span(
    rad: &[f32],
    nz: &[f32],
    out: &mut [u8],
    b: f32,
    read2: f32,
    inv_gain: f32,
    sign: f32,
) {
    if nz.is_empty() {
        for (o, &r) in out.iter_mut().zip(rad) {
            *o = quantise(r * b);
        }
        return;
    }
    for ((o, &r), &n) in out.iter_mut().zip(rad).zip(nz) {
        let v = r * b;
        let s = (read2 + v.max(0.0) * inv_gain).sqrt();
        *o = quantise(v + sign * s * n);
    }
}

/// Rounds to the nearest DN and clips to 0..255 (integer clamp: vectorises).
#[inline(always)]
fn quantise(v: f32) -> u8 {
    ((v + 0.5) as i32).clamp(0, 255) as u8
}

/// A table of standard normal values for the noise (indexed at random offsets per row).
pub(crate) fn noise_table(len: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed);
    (0..len).map(|_| rng.gaussian() as f32).collect()
}
