//! The solver's linear algebra: the damped pseudo-inverse of a step's Jacobian ([`DampedPinv`])
//! and its null space, from one Cholesky factorisation, and the products it needs.

use nalgebra::{DMatrix, DVector};

/// The damped pseudo-inverse of a Jacobian J, `J^+ = J^T (J J^T + lambda I)^-1` (the
/// normal-equation form `(J^T J + lambda I)^-1 J^T` when J is tall), by one Cholesky factorisation
/// of the smaller damped Gram matrix, shared by the step ([`apply`](Self::apply)) and the null
/// space ([`null_space`](Self::null_space)). The pseudo-inverse itself is never formed (a solve
/// with one right-hand side per joint cost a fifth of a Talos iteration). When the damped matrix
/// is not positive definite (lambda = 0 and J rank-deficient), `J^+` is 0.
pub(super) struct DampedPinv {
    ch: Option<nalgebra::linalg::Cholesky<f64, nalgebra::Dyn>>,
    wide: bool,
}

impl DampedPinv {
    pub(super) fn new(j: &DMatrix<f64>, lam: f64) -> DampedPinv {
        let wide = j.nrows() <= j.ncols();
        DampedPinv { ch: damped_gram(j, lam, wide).cholesky(), wide }
    }

    /// `J^+ v` (`j` the matrix this was made from).
    pub(super) fn apply(&self, j: &DMatrix<f64>, v: &DVector<f64>) -> DVector<f64> {
        match (&self.ch, self.wide) {
            (Some(ch), true) => j.tr_mul(&ch.solve(v)),
            (Some(ch), false) => ch.solve(&j.tr_mul(v)),
            (None, _) => DVector::zeros(j.ncols()),
        }
    }

    /// `I - J^+ J`, the secondary step's null-space projector (`j` the matrix this was made
    /// from). For a wide J it is `I - B^T B` with `B = L^-1 J`, `L` the Cholesky factor, by
    /// forward substitution on the columns of `J^T` (contiguous).
    pub(super) fn null_space(&self, j: &DMatrix<f64>) -> DMatrix<f64> {
        let (m, n) = j.shape();
        let Some(ch) = &self.ch else { return DMatrix::identity(n, n) };
        if !self.wide {
            return DMatrix::identity(n, n) - ch.solve(&j.transpose()) * j;
        }
        let l = ch.l_dirty();
        // column i of bt = (row i of J - sum over k < i of L[i, k] row k of B) / L[i, i]
        let mut bt = j.transpose();
        for i in 0..m {
            for k in 0..i {
                let lik = l[(i, k)];
                if lik != 0.0 {
                    let (done, rest) = bt.as_mut_slice().split_at_mut(i * n);
                    let (bk, bi) = (&done[k * n..(k + 1) * n], &mut rest[..n]);
                    bi.iter_mut().zip(bk).for_each(|(x, y)| *x -= lik * y);
                }
            }
            let d = l[(i, i)];
            bt.column_mut(i).iter_mut().for_each(|x| *x /= d);
        }
        let mut out = DMatrix::identity(n, n);
        out.gemm(-1.0, &bt, &bt.transpose(), 1.0);
        out
    }
}

/// The damped Gram matrix of `j`: `J J^T + lambda I` when `wide`, else `J^T J + lambda I`.
/// A primary step's J is small and mostly zeros (Talos: about 20 x 34, a sole's rows touching
/// the base and one leg, a posture row one joint), and a general matrix product spent its time
/// packing and allocating there (with the posture rows of `active_rows`, a Talos edge state went
/// from 43.4 to 33.2 us: benches/results/criterion_ab_gram.json): a wide J with at most a quarter
/// of its entries non-zero adds, per column, the outer product of that column's non-zero entries
/// (the lower triangle, then mirrored). A denser J (the posture step's, nv x nv) goes through
/// the general product, whose vectorised kernel wins there.
fn damped_gram(j: &DMatrix<f64>, lam: f64, wide: bool) -> DMatrix<f64> {
    let (m, n) = j.shape();
    let js = j.as_slice();
    let sparse = wide && 4 * js.iter().filter(|&&x| x != 0.0).count() <= m * n;
    if !sparse {
        let mut a = if wide { j * j.transpose() } else { j.tr_mul(j) };
        for k in 0..a.nrows() {
            a[(k, k)] += lam;
        }
        return a;
    }
    let mut a = DMatrix::zeros(m, m);
    let out = a.as_mut_slice();
    // the non-zero entries of one column: (row, value), rows ascending
    let mut nz: Vec<(usize, f64)> = Vec::with_capacity(m);
    for col in js.chunks_exact(m.max(1)).take(n) {
        nz.clear();
        nz.extend(col.iter().enumerate().filter(|&(_, &x)| x != 0.0).map(|(i, &x)| (i, x)));
        for (p, &(k, xk)) in nz.iter().enumerate() {
            // column k of the lower triangle: rows i >= k gain J[i, c] J[k, c]
            for &(i, xi) in &nz[p..] {
                out[k * m + i] += xi * xk;
            }
        }
    }
    for k in 0..m {
        out[k * m + k] += lam;
        for i in k + 1..m {
            out[i * m + k] = out[k * m + i];
        }
    }
    a
}

/// `a * b` for a sparse `a` (a posture Jacobian: diagonal but for the free-flyer's block): each
/// non-zero of `a` adds a multiple of a row of `b` (a column of `b^T`, contiguous).
pub(super) fn sparse_mul(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let bt = b.transpose();
    let mut out_t = DMatrix::zeros(b.ncols(), a.nrows());
    for i in 0..a.nrows() {
        for k in 0..a.ncols() {
            let x = a[(i, k)];
            if x != 0.0 {
                out_t.column_mut(i).axpy(x, &bt.column(k), 1.0);
            }
        }
    }
    out_t.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The damped pseudo-inverse written out: J^T (J J^T + lambda I)^-1.
    fn explicit_pinv(j: &DMatrix<f64>, lam: f64) -> DMatrix<f64> {
        let m = j.nrows();
        j.transpose() * (j * j.transpose() + DMatrix::identity(m, m) * lam).try_inverse().unwrap()
    }

    fn random_matrix(rows: usize, cols: usize, seed: u64) -> DMatrix<f64> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        DMatrix::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0))
    }

    /// The factorised step and null space (no pseudo-inverse formed) against the formulas written
    /// out, for wide and tall Jacobians, with and without damping, with a rank-deficient one.
    #[test]
    fn damped_pinv_matches_the_explicit_formula() {
        for (rows, cols, lam, seed) in [(20, 34, 1e-3, 1), (3, 7, 0.0, 2), (7, 7, 1e-6, 3), (12, 5, 0.1, 4), (1, 6, 0.0, 5)] {
            let j = random_matrix(rows, cols, seed);
            let v = random_matrix(rows, 1, seed + 100).column(0).into_owned();
            let pinv = if rows <= cols {
                explicit_pinv(&j, lam)
            } else {
                (j.transpose() * &j + DMatrix::identity(cols, cols) * lam).try_inverse().unwrap() * j.transpose()
            };
            let d = DampedPinv::new(&j, lam);
            assert!((d.apply(&j, &v) - &pinv * &v).amax() < 1e-9, "{rows}x{cols}: step");
            let n1 = DMatrix::identity(cols, cols) - &pinv * &j;
            assert!((d.null_space(&j) - n1).amax() < 1e-9, "{rows}x{cols}: null space");
        }
        // rank-deficient (a zero row) without damping: J J^T is singular, J^+ = 0, as before
        let mut j = random_matrix(4, 6, 9);
        j.row_mut(1).fill(0.0);
        let d = DampedPinv::new(&j, 0.0);
        assert!(d.ch.is_none());
        assert_eq!(d.apply(&j, &DVector::from_element(4, 1.0)), DVector::zeros(6));
        assert_eq!(d.null_space(&j), DMatrix::identity(6, 6));
    }

    #[test]
    fn damped_gram_is_the_product() {
        // wide and tall; dense, a third non-zero (the general product) and a seventh non-zero
        // (the sparse sum), with a row and a column of zeros, as a step's J has
        let cases = [(19, 38, 1e-4, 1), (38, 19, 1e-4, 2), (6, 6, 0.0, 3), (1, 4, 0.5, 4), (0, 5, 0.1, 5), (38, 38, 1e-6, 6)];
        for ((rows, cols, lam, seed), keep) in cases.into_iter().flat_map(|c| [1, 3, 7].map(|k| (c, k))) {
            let mut j = random_matrix(rows, cols, seed);
            for (k, x) in j.iter_mut().enumerate() {
                if k % keep != 0 {
                    *x = 0.0;
                }
            }
            if rows > 2 && cols > 2 {
                j.row_mut(1).fill(0.0);
                j.column_mut(2).fill(0.0);
            }
            let wide = rows <= cols;
            let expected = if wide { &j * j.transpose() + DMatrix::identity(rows, rows) * lam } else { j.transpose() * &j + DMatrix::identity(cols, cols) * lam };
            let got = damped_gram(&j, lam, wide);
            assert_eq!(got.shape(), expected.shape(), "{rows}x{cols}, 1 in {keep}");
            assert!(got.iter().zip(expected.iter()).all(|(a, b)| (a - b).abs() <= 1e-12 * (1.0 + b.abs())), "{rows}x{cols}, 1 in {keep}");
            assert_eq!(got, got.transpose(), "{rows}x{cols}, 1 in {keep}: symmetric");
        }
    }

    #[test]
    fn sparse_mul_is_the_product() {
        let mut a = DMatrix::zeros(9, 9);
        a.view_mut((0, 0), (3, 3)).copy_from(&random_matrix(3, 3, 11));
        for i in 3..9 {
            a[(i, i)] = 0.5 + i as f64;
        }
        let b = random_matrix(9, 9, 12);
        assert!((sparse_mul(&a, &b) - &a * &b).amax() < 1e-12);
        let wide = random_matrix(4, 9, 13);
        assert!((sparse_mul(&wide, &b) - &wide * &b).amax() < 1e-12);
    }
}
