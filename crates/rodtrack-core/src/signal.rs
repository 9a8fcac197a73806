//! 1-D signal steps: the paper's IIR band-pass (eq. 3), hysteresis (eq. 4) and normalised
//! cross-correlation (eq. 5), and rodtrack's faster and finer variants.
//!
//! **Equation (3).** The paper writes `H(z) = (1 - f) z^-1 / (1 - f z^-1)` with
//! `f = -T / (T + 1)` and calls both filters low-pass. Taken literally the pole sits at a
//! negative `f` and the filter amplifies the highest frequency (gain `(1 - f) / (1 + f)` at
//! Nyquist: 21 for `T = 10`), which is not a low-pass. We implement the first-order low-pass the
//! text describes, with the pole at `+T / (T + 1)`, so that `T` is the filter's time constant in
//! samples; the test `literal_sign_is_not_low_pass` shows the difference.

/// The paper's filter constants.
pub const PAPER_T_FAST: f32 = 0.5;
/// The paper's slow filter constant.
pub const PAPER_T_SLOW: f32 = 10.0;
/// The paper's hysteresis threshold `P_high = -P_low`.
pub const PAPER_HYSTERESIS: f32 = 8.0;

/// One first-order low-pass of eq. (3): `y[n] = a y[n-1] + (1 - a) x[n-1]`, `a = T / (T + 1)`,
/// started at rest on the first sample (`y[0] = x[0]`, so that a bright line does not ring).
pub fn iir_lowpass(x: &[f32], t: f32, y: &mut [f32]) {
    assert_eq!(x.len(), y.len(), "iir_lowpass: output length");
    if x.is_empty() {
        return;
    }
    let a = t / (t + 1.0);
    y[0] = x[0];
    for n in 1..x.len() {
        y[n] = a * y[n - 1] + (1.0 - a) * x[n - 1];
    }
}

/// The paper's band-pass: `H1(x) - H2(x)` with `T1 = 0.5`, `T2 = 10`, in one pass.
pub fn paper_bandpass(x: &[f32], out: &mut [f32]) {
    assert_eq!(x.len(), out.len(), "paper_bandpass: output length");
    if x.is_empty() {
        return;
    }
    let a1 = PAPER_T_FAST / (PAPER_T_FAST + 1.0);
    let a2 = PAPER_T_SLOW / (PAPER_T_SLOW + 1.0);
    let (mut y1, mut y2) = (x[0], x[0]);
    out[0] = 0.0;
    for n in 1..x.len() {
        y1 = a1 * y1 + (1.0 - a1) * x[n - 1];
        y2 = a2 * y2 + (1.0 - a2) * x[n - 1];
        out[n] = y1 - y2;
    }
}

/// Hysteresis thresholding, eq. (4): output 1 above `high`, 0 below `low`, else the previous
/// output (starting at 0).
pub fn hysteresis(x: &[f32], low: f32, high: f32, out: &mut [f32]) {
    assert_eq!(x.len(), out.len(), "hysteresis: output length");
    let mut state = 0.0f32;
    for (o, &v) in out.iter_mut().zip(x) {
        if v > high {
            state = 1.0;
        } else if v < low {
            state = 0.0;
        }
        *o = state;
    }
}

/// Normalised cross-correlation (eq. 5) of `kernel` with `signal` at every offset `k` in
/// `0..=signal.len() - kernel.len()`, using the window's own mean and deviation. A flat window
/// gives 0. This is the paper's O(samples x kernel) form, the reference for
/// [`ncc_cells_prefix`].
pub fn ncc_direct(kernel: &[f32], signal: &[f32], out: &mut [f32]) {
    let n = kernel.len();
    assert!(
        n > 0 && signal.len() >= n,
        "ncc_direct: signal shorter than kernel"
    );
    assert_eq!(out.len(), signal.len() - n + 1, "ncc_direct: output length");
    let stats = KernelStats::of(kernel);
    for (k, o) in out.iter_mut().enumerate() {
        *o = ncc_direct_at(kernel, stats, &signal[k..k + n]);
    }
}

/// A kernel's mean and root sum of squared deviations, as [`ncc_direct`] computes them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KernelStats {
    mean: f32,
    root_ss: f32,
}

impl KernelStats {
    /// The statistics of `kernel` (not empty).
    pub fn of(kernel: &[f32]) -> Self {
        let n = kernel.len();
        let mean = kernel.iter().sum::<f32>() / n as f32;
        let root_ss = kernel
            .iter()
            .map(|v| (v - mean) * (v - mean))
            .sum::<f32>()
            .sqrt();
        KernelStats { mean, root_ss }
    }
}

/// [`ncc_direct`] at one offset: `window` is the signal's `kernel.len()` samples there. The
/// same arithmetic, so the value is bit for bit the one [`ncc_direct`] writes.
#[inline]
pub fn ncc_direct_at(kernel: &[f32], stats: KernelStats, window: &[f32]) -> f32 {
    let (mk, sk) = (stats.mean, stats.root_ss);
    let n = kernel.len();
    let ml = window.iter().sum::<f32>() / n as f32;
    let mut num = 0.0f32;
    let mut sl = 0.0f32;
    for (a, b) in kernel.iter().zip(window) {
        num += (a - mk) * (b - ml);
        sl += (b - ml) * (b - ml);
    }
    let den = sk * sl.sqrt();
    if den > 1e-6 {
        num / den
    } else {
        0.0
    }
}

/// Fills `prefix` (length `signal.len() + 1`) with running sums of `signal` and `prefix2` with
/// running sums of its squares, in f64 so that long lines lose no precision.
pub fn prefix_sums(signal: &[f32], prefix: &mut [f64], prefix2: &mut [f64]) {
    assert_eq!(prefix.len(), signal.len() + 1, "prefix_sums: length");
    assert_eq!(prefix2.len(), signal.len() + 1, "prefix_sums: length");
    prefix[0] = 0.0;
    prefix2[0] = 0.0;
    for (i, &v) in signal.iter().enumerate() {
        let v = v as f64;
        prefix[i + 1] = prefix[i] + v;
        prefix2[i + 1] = prefix2[i] + v * v;
    }
}

/// NCC of a kernel made of `cells.len()` cells of `cell_len` samples each (cell `c` has the
/// constant value `cells[c]`) with `signal`, in O(samples x cells) using prefix sums. Equal to
/// [`ncc_direct`] with the kernel expanded to samples. `prefix`/`prefix2` come from
/// [`prefix_sums`] on the same signal.
pub fn ncc_cells_prefix(
    cells: &[f32],
    cell_len: usize,
    prefix: &[f64],
    prefix2: &[f64],
    out: &mut [f32],
) {
    let n_cells = cells.len();
    let n = n_cells * cell_len;
    let len = prefix.len() - 1;
    assert!(
        n > 0 && len >= n,
        "ncc_cells_prefix: signal shorter than kernel"
    );
    assert_eq!(out.len(), len - n + 1, "ncc_cells_prefix: output length");
    let mk = cells.iter().sum::<f32>() as f64 / n_cells as f64;
    let sk2: f64 = cells
        .iter()
        .map(|&c| (c as f64 - mk) * (c as f64 - mk) * cell_len as f64)
        .sum();
    let sk = sk2.sqrt();
    for (k, o) in out.iter_mut().enumerate() {
        let sum = prefix[k + n] - prefix[k];
        let sum2 = prefix2[k + n] - prefix2[k];
        let var = sum2 - sum * sum / n as f64;
        // sum_i (K_i - mk)(x_i - ml) = sum_c (cells_c - mk) * cellsum_c  (the ml term vanishes).
        let mut num = 0.0f64;
        let mut base = k;
        for &c in cells {
            num += (c as f64 - mk) * (prefix[base + cell_len] - prefix[base]);
            base += cell_len;
        }
        let den = sk * var.max(0.0).sqrt();
        *o = if den > 1e-6 { (num / den) as f32 } else { 0.0 };
    }
}

/// A kernel as runs of constant value: `bounds[r]..bounds[r + 1]` holds `values[r]`
/// (`bounds` starts at 0 and ends at the kernel's length). Cleared and refilled, so that a
/// search over many kernels reuses the buffers.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct KernelRuns {
    /// Run boundaries, samples: `values.len() + 1` of them.
    pub bounds: Vec<usize>,
    /// Each run's value.
    pub values: Vec<f32>,
}

impl KernelRuns {
    /// The runs of an expanded kernel (adjacent equal samples merged).
    pub fn fill_from(&mut self, kernel: &[f32]) {
        self.bounds.clear();
        self.values.clear();
        for (i, &v) in kernel.iter().enumerate() {
            if self.values.last() != Some(&v) {
                self.bounds.push(i);
                self.values.push(v);
            }
        }
        self.bounds.push(kernel.len());
    }

    /// The kernel's length, samples.
    pub fn len(&self) -> usize {
        self.bounds.last().copied().unwrap_or(0)
    }

    /// True for an empty kernel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// NCC of a kernel given as runs of constant value with `signal`, in O(samples x runs) using
/// prefix sums: equal to [`ncc_direct`] with the kernel expanded to samples (to rounding; the
/// sums are f64 here). `prefix`/`prefix2` come from [`prefix_sums`] on the same signal. For
/// the searches over many kernel scales and long lines, where the direct form costs
/// O(samples x kernel samples) per scale.
pub fn ncc_runs_prefix(runs: &KernelRuns, prefix: &[f64], prefix2: &[f64], out: &mut [f32]) {
    let n = runs.len();
    let len = prefix.len() - 1;
    assert!(
        n > 0 && len >= n,
        "ncc_runs_prefix: signal shorter than kernel"
    );
    assert_eq!(out.len(), len - n + 1, "ncc_runs_prefix: output length");
    let run_len = |r: usize| (runs.bounds[r + 1] - runs.bounds[r]) as f64;
    let mk = (0..runs.values.len())
        .map(|r| runs.values[r] as f64 * run_len(r))
        .sum::<f64>()
        / n as f64;
    let sk = (0..runs.values.len())
        .map(|r| (runs.values[r] as f64 - mk).powi(2) * run_len(r))
        .sum::<f64>()
        .sqrt();
    for (k, o) in out.iter_mut().enumerate() {
        let sum = prefix[k + n] - prefix[k];
        let sum2 = prefix2[k + n] - prefix2[k];
        let var = sum2 - sum * sum / n as f64;
        // sum_i (K_i - mk)(x_i - ml) = sum_r (v_r - mk) * runsum_r (the ml term vanishes).
        let mut num = 0.0f64;
        for (r, &v) in runs.values.iter().enumerate() {
            let (a, b) = (runs.bounds[r], runs.bounds[r + 1]);
            num += (v as f64 - mk) * (prefix[k + b] - prefix[k + a]);
        }
        let den = sk * var.max(0.0).sqrt();
        *o = if den > 1e-6 { (num / den) as f32 } else { 0.0 };
    }
}

/// Index of the largest `v * v` (the paper's `argmax C^2`); first one on ties.
pub fn argmax_sq(v: &[f32]) -> Option<usize> {
    let mut best: Option<(usize, f32)> = None;
    for (i, &x) in v.iter().enumerate() {
        let s = x * x;
        if best.is_none_or(|(_, b)| s > b) {
            best = Some((i, s));
        }
    }
    best.map(|(i, _)| i)
}

/// Index of the largest value; first one on ties.
pub fn argmax(v: &[f32]) -> Option<usize> {
    let mut best: Option<(usize, f32)> = None;
    for (i, &x) in v.iter().enumerate() {
        if best.is_none_or(|(_, b)| x > b) {
            best = Some((i, x));
        }
    }
    best.map(|(i, _)| i)
}

/// Sub-sample offset in `[-0.5, 0.5]` of a peak at `i` by a parabola through its neighbours.
pub fn parabolic_offset(v: &[f32], i: usize) -> f32 {
    if i == 0 || i + 1 >= v.len() {
        return 0.0;
    }
    let (a, b, c) = (v[i - 1], v[i], v[i + 1]);
    let den = a - 2.0 * b + c;
    if den.abs() < 1e-12 {
        return 0.0;
    }
    (0.5 * (a - c) / den).clamp(-0.5, 0.5)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use proptest::prelude::*;

    /// The plainly written reference: two filters, then their difference.
    fn bandpass_reference(x: &[f32]) -> Vec<f32> {
        let mut a = vec![0.0; x.len()];
        let mut b = vec![0.0; x.len()];
        iir_lowpass(x, PAPER_T_FAST, &mut a);
        iir_lowpass(x, PAPER_T_SLOW, &mut b);
        a.iter().zip(&b).map(|(p, q)| p - q).collect()
    }

    #[test]
    fn lowpass_step_response_and_dc_gain() {
        let x: Vec<f32> = (0..200).map(|i| if i < 10 { 0.0 } else { 100.0 }).collect();
        let mut y = vec![0.0; x.len()];
        iir_lowpass(&x, 10.0, &mut y);
        assert_eq!(y[10], 0.0, "one sample delay");
        // After T samples a first-order low-pass has risen to about 1 - e^-1.
        let a = 10.0f32 / 11.0;
        assert!((y[21] - 100.0 * (1.0 - a.powi(11))).abs() < 1e-3);
        assert!((y[199] - 100.0).abs() < 0.01);
    }

    #[test]
    fn literal_sign_is_not_low_pass() {
        // With the pole at -T/(T+1), the gain at Nyquist would be (1 - f)/(1 + f).
        let f = -10.0f64 / 11.0;
        assert!((1.0 - f) / (1.0 + f) > 20.0);
        // Ours attenuates an alternating signal.
        let x: Vec<f32> = (0..100)
            .map(|i| if i % 2 == 0 { 10.0 } else { -10.0 })
            .collect();
        let mut y = vec![0.0; x.len()];
        iir_lowpass(&x, 10.0, &mut y);
        assert!(y[50..].iter().all(|v| v.abs() < 1.0));
    }

    #[test]
    fn bandpass_matches_reference_and_kills_dc() {
        let x: Vec<f32> = (0..300)
            .map(|i| 80.0 + 0.3 * i as f32 + if (i / 7) % 2 == 0 { 60.0 } else { 0.0 })
            .collect();
        let mut out = vec![0.0; x.len()];
        paper_bandpass(&x, &mut out);
        let r = bandpass_reference(&x);
        for (a, b) in out.iter().zip(&r) {
            assert!((a - b).abs() < 1e-3);
        }
        let flat = vec![120.0f32; 50];
        let mut o = vec![0.0; 50];
        paper_bandpass(&flat, &mut o);
        assert!(o.iter().all(|v| v.abs() < 1e-4));
    }

    #[test]
    fn hysteresis_follows_eq_4() {
        let x = [0.0, 9.0, 5.0, -5.0, -9.0, 7.0, 8.5, -7.9];
        let mut o = [0.0; 8];
        hysteresis(&x, -8.0, 8.0, &mut o);
        assert_eq!(o, [0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0]);
    }

    proptest! {
        #[test]
        fn ncc_of_a_signal_with_itself_is_one(v in proptest::collection::vec(0.0f32..255.0, 8..40)) {
            let spread = v.iter().cloned().fold(f32::MIN, f32::max) - v.iter().cloned().fold(f32::MAX, f32::min);
            prop_assume!(spread > 1.0);
            let mut o = [0.0f32];
            ncc_direct(&v, &v, &mut o);
            prop_assert!((o[0] - 1.0).abs() < 1e-4);
        }

        #[test]
        fn prefix_ncc_equals_direct(
            cells in proptest::collection::vec(0.0f32..1.0, 3..17),
            cell_len in 1usize..6,
            sig in proptest::collection::vec(0.0f32..255.0, 120..200),
        ) {
            let kernel: Vec<f32> = cells.iter().flat_map(|c| std::iter::repeat_n(*c, cell_len)).collect();
            let mut d = vec![0.0; sig.len() - kernel.len() + 1];
            ncc_direct(&kernel, &sig, &mut d);
            let mut p = vec![0.0; sig.len() + 1];
            let mut p2 = vec![0.0; sig.len() + 1];
            prefix_sums(&sig, &mut p, &mut p2);
            let mut f = vec![0.0; d.len()];
            ncc_cells_prefix(&cells, cell_len, &p, &p2, &mut f);
            for (a, b) in d.iter().zip(&f) {
                prop_assert!((a - b).abs() < 2e-3, "{} vs {}", a, b);
            }
        }
    }

    proptest! {
        #[test]
        fn runs_ncc_equals_direct(
            cells in proptest::collection::vec(prop_oneof![Just(0.0f32), Just(1.0f32), 0.0f32..1.0], 3..17),
            cell in 1.0f64..7.0,
            sig in proptest::collection::vec(0.0f32..255.0, 130..220),
        ) {
            // Cells of a fractional length, rounded to samples as the calibration's searches do.
            let len = (cells.len() as f64 * cell).round() as usize;
            let kernel: Vec<f32> = (0..len)
                .map(|i| cells[(((i as f64 + 0.5) / cell) as usize).min(cells.len() - 1)])
                .collect();
            prop_assume!(kernel.len() < sig.len());
            let mut d = vec![0.0; sig.len() - kernel.len() + 1];
            ncc_direct(&kernel, &sig, &mut d);
            let mut p = vec![0.0; sig.len() + 1];
            let mut p2 = vec![0.0; sig.len() + 1];
            prefix_sums(&sig, &mut p, &mut p2);
            let mut runs = KernelRuns::default();
            runs.fill_from(&kernel);
            prop_assert_eq!(runs.len(), kernel.len());
            let mut f = vec![0.0; d.len()];
            ncc_runs_prefix(&runs, &p, &p2, &mut f);
            for (a, b) in d.iter().zip(&f) {
                prop_assert!((a - b).abs() < 2e-3, "{} vs {}", a, b);
            }
        }
    }

    #[test]
    fn ncc_finds_a_planted_kernel_and_parabola_is_exact_on_a_parabola() {
        let kernel: Vec<f32> = "1001101010000101"
            .chars()
            .flat_map(|c| std::iter::repeat_n(if c == '1' { 0.0 } else { 1.0 }, 4))
            .collect();
        let mut sig = vec![0.7f32; 300];
        for (i, k) in kernel.iter().enumerate() {
            sig[123 + i] = 30.0 + 150.0 * k;
        }
        let mut o = vec![0.0; sig.len() - kernel.len() + 1];
        ncc_direct(&kernel, &sig, &mut o);
        assert_eq!(argmax_sq(&o), Some(123));
        let p = [1.0f32, 3.0, 2.0];
        // Parabola through (-1,1), (0,3), (1,2): vertex at x = 0.5*(1-2)/(1-6+2) = 1/6.
        assert!((parabolic_offset(&p, 1) - 1.0 / 6.0).abs() < 1e-6);
    }
}
