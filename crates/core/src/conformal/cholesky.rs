//! Sparse Cholesky factorization of symmetric positive definite matrices
//! (faer, AMD fill-reducing ordering), factored once and reused for several
//! right-hand sides.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::SparseColMat;
use faer::{Conj, Mat, Par, Side};

/// Why a factorization or solve failed.
#[derive(Debug, thiserror::Error)]
pub enum CholeskyError {
    /// The matrix could not be assembled (bad indices, out of memory).
    #[error("matrix assembly failed: {0}")]
    Assembly(String),
    /// The symbolic or numeric factorization failed (e.g. the matrix is not
    /// numerically positive definite).
    #[error("Cholesky factorization failed: {0}")]
    Factorization(String),
}

/// The factorization `A = L Lᵀ` of a sparse symmetric positive definite
/// matrix. Always computed sequentially so that results do not depend on the
/// thread count.
pub struct SpdFactor {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
}

impl SpdFactor {
    /// Factor `a`, reading its lower triangle.
    pub fn new(a: &SparseColMat<usize, f64>) -> Result<Self, CholeskyError> {
        let a = a.as_ref();
        if a.nrows() != a.ncols() {
            return Err(CholeskyError::Assembly(format!(
                "matrix is {} × {}, not square",
                a.nrows(),
                a.ncols()
            )));
        }
        let symbolic = factorize_symbolic_cholesky(
            a.symbolic(),
            Side::Lower,
            SymmetricOrdering::Amd,
            Default::default(),
        )
        .map_err(|e| CholeskyError::Factorization(format!("{e:?}")))?;
        let mut values = vec![0.0; symbolic.len_val()];
        let req = symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
        let mut buf =
            MemBuffer::try_new(req).map_err(|e| CholeskyError::Factorization(format!("{e:?}")))?;
        symbolic
            .factorize_numeric_llt::<f64>(
                &mut values,
                a,
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut buf),
                Default::default(),
            )
            .map_err(|e| CholeskyError::Factorization(format!("{e:?}")))?;
        Ok(Self { symbolic, values })
    }

    /// Dimension of the factored matrix.
    pub fn dim(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Solve `A X = B` for the columns of `b` (each of length [`Self::dim`]),
    /// in place.
    pub fn solve_columns(&self, columns: &mut [Vec<f64>]) -> Result<(), CholeskyError> {
        let n = self.dim();
        if columns.iter().any(|c| c.len() != n) {
            return Err(CholeskyError::Assembly(
                "right-hand side has the wrong length".into(),
            ));
        }
        let k = columns.len();
        if k == 0 {
            return Ok(());
        }
        let mut rhs = Mat::<f64>::from_fn(n, k, |i, j| columns[j][i]);
        let req = self.symbolic.solve_in_place_scratch::<f64>(k, Par::Seq);
        let mut buf =
            MemBuffer::try_new(req).map_err(|e| CholeskyError::Factorization(format!("{e:?}")))?;
        LltRef::<usize, f64>::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            rhs.as_mut(),
            Par::Seq,
            MemStack::new(&mut buf),
        );
        for (j, col) in columns.iter_mut().enumerate() {
            for (i, x) in col.iter_mut().enumerate() {
                *x = rhs[(i, j)];
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conformal::laplacian::csc_from_columns;

    #[test]
    fn solves_a_small_spd_system() {
        // Tridiagonal [2 -1; -1 2 -1; -1 2], x = (1, 2, 3) gives b = (0, 0, 4).
        let a = csc_from_columns(
            3,
            vec![
                vec![(0, 2.0), (1, -1.0)],
                vec![(0, -1.0), (1, 2.0), (2, -1.0)],
                vec![(1, -1.0), (2, 2.0)],
            ],
        );
        let f = SpdFactor::new(&a).unwrap();
        let mut cols = vec![vec![0.0, 0.0, 4.0], vec![1.0, 0.0, 1.0]];
        f.solve_columns(&mut cols).unwrap();
        for (x, e) in cols[0].iter().zip([1.0, 2.0, 3.0]) {
            assert!((x - e).abs() < 1e-12);
        }
        for (x, e) in cols[1].iter().zip([1.0, 1.0, 1.0]) {
            assert!((x - e).abs() < 1e-12);
        }
    }

    #[test]
    fn rejects_an_indefinite_matrix() {
        let a = csc_from_columns(2, vec![vec![(0, 1.0)], vec![(1, -1.0)]]);
        assert!(SpdFactor::new(&a).is_err());
    }
}
