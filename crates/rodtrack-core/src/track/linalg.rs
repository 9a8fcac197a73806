//! Small dense linear algebra for the phase fit.

/// The inverse of the weighted normal matrix `sum w [1 c s]^T [1 c s]` of a phase table.
pub(super) fn normal_inverse(table: &[(f64, f64, f64)]) -> [[f64; 3]; 3] {
    let mut g = [[0.0f64; 3]; 3];
    for &(w, c, s) in table {
        let x = [1.0, c, s];
        for i in 0..3 {
            for j in 0..3 {
                g[i][j] += w * x[i] * x[j];
            }
        }
    }
    invert3(&g)
}

/// The inverse of a 3x3 matrix (zero when it is singular).
pub(super) fn invert3(g: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = g[0][0] * (g[1][1] * g[2][2] - g[1][2] * g[2][1])
        - g[0][1] * (g[1][0] * g[2][2] - g[1][2] * g[2][0])
        + g[0][2] * (g[1][0] * g[2][1] - g[1][1] * g[2][0]);
    let mut inv = [[0.0f64; 3]; 3];
    if det.abs() < 1e-300 {
        return inv;
    }
    for (i, row) in inv.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let (a0, a1) = ((j + 1) % 3, (j + 2) % 3);
            let (b0, b1) = ((i + 1) % 3, (i + 2) % 3);
            *v = (g[a0][b0] * g[a1][b1] - g[a0][b1] * g[a1][b0]) / det;
        }
    }
    inv
}
