//! The paper's search for the barcode's scale and direction on its binary line, fast and with
//! the direct form's exact result.

use crate::signal::{ncc_direct_at, ncc_runs_prefix, prefix_sums, KernelRuns, KernelStats};

/// The barcode's kernel expanded to samples of `1 / cell` cells each (the sample count rounded),
/// read from its far end when `dir` is negative: `black` where a cell is black, `1 - black`
/// elsewhere.
pub(super) fn barcode_kernel(kernel: &[bool], cell: f64, dir: i32, black: f32) -> Vec<f32> {
    let len = (kernel.len() as f64 * cell).round() as usize;
    (0..len)
        .map(|i| {
            let c = (((i as f64 + 0.5) / cell) as usize).min(kernel.len() - 1);
            let c = if dir > 0 { c } else { kernel.len() - 1 - c };
            if kernel[c] {
                black
            } else {
                1.0 - black
            }
        })
        .collect()
}

/// How far (in `C^2`) the prefix-sum form's values may lie from the direct form's, with room
/// to spare: both are within a few 1e-5 of each other on lines of a few thousand samples.
const CANDIDATE_MARGIN_C2: f32 = 1e-3;

/// The best `(C^2, cell, dir, offset)` over the scales `cell` = 2, 2.02, ... (times 1.01 while
/// under 25 px) and both directions of the kernels `expand(cell, dir)` on `bin`, exactly as
/// the paper's direct search finds it: the first largest `C^2` in that order, each value
/// computed by [`crate::signal::ncc_direct`]'s arithmetic. The prefix-sum form
/// ([`ncc_runs_prefix`]) finds the few offsets that can hold the largest value; only those are
/// computed directly. (Neighbouring scales can tie on a binary line, so the direct form's own
/// rounding must decide, or the paper's parameters would change.)
pub(super) fn paper_kernel_search(
    bin: &[f32],
    expand: impl Fn(f64, i32) -> Vec<f32>,
) -> Option<(f32, f64, i32, usize)> {
    let (mut prefix, mut prefix2) = (vec![0.0; bin.len() + 1], vec![0.0; bin.len() + 1]);
    prefix_sums(bin, &mut prefix, &mut prefix2);
    let mut runs = KernelRuns::default();
    let mut corr = Vec::new();
    let scales = || {
        let mut cell = 2.0f64;
        std::iter::from_fn(move || {
            let c = cell;
            cell *= 1.01;
            (c < 25.0).then_some(c)
        })
        .flat_map(|c| [(c, 1), (c, -1)])
    };
    // The fast form's values for one scale and direction into `corr`; the kernel, or None
    // where it does not fit the line.
    let mut fast = |cell: f64, dir: i32, corr: &mut Vec<f32>| -> Option<Vec<f32>> {
        let k = expand(cell, dir);
        if k.len() + 1 >= bin.len() {
            return None;
        }
        corr.resize(bin.len() - k.len() + 1, 0.0);
        runs.fill_from(&k);
        ncc_runs_prefix(&runs, &prefix, &prefix2, corr);
        Some(k)
    };
    // Pass 1: the largest C^2 of the fast form.
    let mut fast_max: Option<f32> = None;
    for (cell, dir) in scales() {
        if fast(cell, dir, &mut corr).is_some() {
            for &cv in &corr {
                fast_max = Some(fast_max.map_or(cv * cv, |m| m.max(cv * cv)));
            }
        }
    }
    let floor = fast_max? - CANDIDATE_MARGIN_C2;
    // Pass 2: in the direct search's order, its exact values at the candidates.
    let mut best: Option<(f32, f64, i32, usize)> = None;
    for (cell, dir) in scales() {
        let Some(k) = fast(cell, dir, &mut corr) else {
            continue;
        };
        let stats = KernelStats::of(&k);
        for (i, &f) in corr.iter().enumerate() {
            if f * f < floor {
                continue;
            }
            let cv = ncc_direct_at(&k, stats, &bin[i..i + k.len()]);
            if best.is_none_or(|b| cv * cv > b.0) {
                best = Some((cv * cv, cell, dir, i));
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::ncc_direct;

    /// The direct search, as the paper's calibration wrote it.
    fn direct_search(
        bin: &[f32],
        expand: impl Fn(f64, i32) -> Vec<f32>,
    ) -> Option<(f32, f64, i32, usize)> {
        let mut best: Option<(f32, f64, i32, usize)> = None;
        let mut cell = 2.0f64;
        let mut corr = Vec::new();
        while cell < 25.0 {
            for dir in [1, -1] {
                let k = expand(cell, dir);
                if k.len() + 1 >= bin.len() {
                    continue;
                }
                corr.resize(bin.len() - k.len() + 1, 0.0);
                ncc_direct(&k, bin, &mut corr);
                for (i, &cv) in corr.iter().enumerate() {
                    if best.is_none_or(|b| cv * cv > b.0) {
                        best = Some((cv * cv, cell, dir, i));
                    }
                }
            }
            cell *= 1.01;
        }
        best
    }

    fn expand_kernel(kernel: &[bool]) -> impl Fn(f64, i32) -> Vec<f32> + '_ {
        move |cell, dir| barcode_kernel(kernel, cell, dir, 1.0)
    }

    /// Binary lines holding the barcode at several scales, both ways, with noise flips and
    /// clutter: the fast search returns exactly the direct one's answer (the same C^2 bits).
    #[test]
    fn the_fast_search_finds_exactly_what_the_direct_one_finds() {
        let kernel: Vec<bool> = "1001101010000101".chars().map(|c| c == '1').collect();
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..24 {
            let cell = 3.0 + 9.0 * rnd();
            let dir = if case % 2 == 0 { 1 } else { -1 };
            let n = 600 + (rnd() * 600.0) as usize;
            let mut bin: Vec<f32> = (0..n)
                .map(|_| if rnd() < 0.5 { 1.0 } else { 0.0 })
                .collect();
            // Runs of clutter, then the kernel planted at a random place.
            for i in 1..n {
                if rnd() < 0.8 {
                    bin[i] = bin[i - 1];
                }
            }
            let k = expand_kernel(&kernel)(cell, dir);
            let at = (rnd() * (n - k.len() - 1) as f64) as usize;
            bin[at..at + k.len()].copy_from_slice(&k);
            for _ in 0..case {
                let j = (rnd() * n as f64) as usize % n;
                bin[j] = 1.0 - bin[j];
            }
            let fast = paper_kernel_search(&bin, expand_kernel(&kernel));
            let direct = direct_search(&bin, expand_kernel(&kernel));
            let bits = |b: Option<(f32, f64, i32, usize)>| {
                b.map(|b| (b.0.to_bits(), b.1.to_bits(), b.2, b.3))
            };
            assert_eq!(bits(fast), bits(direct), "case {case}");
        }
    }
}
