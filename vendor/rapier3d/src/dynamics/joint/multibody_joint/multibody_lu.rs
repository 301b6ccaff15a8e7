//! pma-exo fork: the multibody's LU factorisation, kept across steps.
//!
//! rapier factored its augmented mass matrices with `nalgebra::LU::new` on a copy made every
//! step (upstream's `TODO: avoid allocation inside LU at each timestep`): two allocations per
//! matrix per step. This is the same factorisation (partial row pivoting, nalgebra's
//! `gauss_step` / `gauss_step_swap` in nalgebra's order) and the same solve, into storage that
//! is overwritten in place while the matrix keeps its size, so the results are identical bit
//! for bit and a step allocates nothing for it.

use crate::alloc_prelude::*;
use crate::math::Real;
use na::constraint::{SameNumberOfRows, ShapeConstraint};
use na::{DMatrix, DMatrixView, Dim, Dyn, Matrix, StorageMut};

/// An LU factorisation with partial (row) pivoting whose storage is reused.
#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Clone, Debug, Default)]
pub struct MultibodyLu {
    lu: DMatrix<Real>,
    /// The row interchanges, in the order they were made.
    pivots: Vec<(usize, usize)>,
}

impl MultibodyLu {
    /// Factors `matrix` (square), overwriting the previous factorisation.
    pub(crate) fn factor(&mut self, matrix: DMatrixView<'_, Real>) {
        if self.lu.shape() == matrix.shape() {
            self.lu.copy_from(&matrix);
        } else {
            self.lu = matrix.into_owned();
        }
        self.pivots.clear();
        let n = self.lu.nrows().min(self.lu.ncols());
        self.pivots.reserve(n); // a no-op once the capacity is there
        // nalgebra 0.35's `LU::new`, step for step.
        for i in 0..n {
            let piv = self.lu.view_range(i.., i).icamax() + i;
            let diag = self.lu[(piv, i)];
            if diag == 0.0 {
                // No non-zero entries on this column.
                continue;
            }
            if piv != i {
                self.pivots.push((i, piv));
                self.lu.columns_range_mut(..i).swap_rows(i, piv);
                na::linalg::gauss_step_swap(&mut self.lu, diag, i, piv);
            } else {
                na::linalg::gauss_step(&mut self.lu, diag, i);
            }
        }
    }

    /// Solves `self * x = b` in place; `false` (and `b` garbage) if the matrix is singular.
    /// nalgebra's `LU::solve_mut`.
    pub fn solve_mut<R2: Dim, C2: Dim, S2>(&self, b: &mut Matrix<Real, R2, C2, S2>) -> bool
    where
        S2: StorageMut<Real, R2, C2>,
        ShapeConstraint: SameNumberOfRows<R2, Dyn>,
    {
        assert_eq!(
            self.lu.nrows(),
            b.nrows(),
            "LU solve matrix dimension mismatch."
        );
        for &(i, piv) in &self.pivots {
            b.swap_rows(i, piv);
        }
        let _ = self.lu.solve_lower_triangular_with_diag_mut(b, 1.0);
        self.lu.solve_upper_triangular_mut(b)
    }

    /// The factored matrix rebuilt from its factors, `P⁻¹ L U` (allocates: for checks).
    pub fn reconstruct(&self) -> DMatrix<Real> {
        let mut l = self.lu.clone();
        l.fill_upper_triangle(0.0, 1);
        l.fill_diagonal(1.0);
        let mut u = self.lu.clone();
        u.fill_lower_triangle(0.0, 1);
        let mut m = l * u;
        for &(i, piv) in self.pivots.iter().rev() {
            m.swap_rows(i, piv);
        }
        m
    }
}
