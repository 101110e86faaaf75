//! Small fixed-size linear algebra on arrays, for plain and dual numbers alike: the
//! products of the integrators, Newton's linear solve and the stability margin.

use crate::real::{c, Real};
use core::ops::{Add, Mul, Neg, Sub};

/// Arithmetic shared by plain and dual numbers, without the scalar type.
pub(crate) trait Ring:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self>
{
}
impl<S: Copy + Add<Output = S> + Sub<Output = S> + Mul<Output = S> + Neg<Output = S>> Ring for S {}

/// A 3-vector.
pub(crate) type V3<S> = [S; 3];
/// A 3 x 3 matrix, row-major.
pub(crate) type M3<S> = [[S; 3]; 3];

/// `a x b`.
#[inline(always)]
pub(crate) fn cross<S: Ring>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The 3 x 3 product `a b`.
#[inline(always)]
pub(crate) fn mat_mul<S: Ring>(a: &M3<S>, b: &M3<S>) -> M3<S> {
    core::array::from_fn(|i| {
        core::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
    })
}

/// Largest absolute value of the first `m` entries (twice the largest finite number if
/// one is not finite).
pub(crate) fn max_abs<T: Real, const N: usize>(r: &[T; N], m: usize) -> T {
    let mut n = T::zero();
    for v in r.iter().take(m) {
        if !v.is_finite() {
            return T::max_value().unwrap_or(T::one()) * c(2.0);
        }
        n = n.max(v.abs());
    }
    n
}

/// Solves `J dx = r` for the leading `m x m` block by Gaussian elimination with
/// partial pivoting; `None` if singular.
#[inline(always)]
pub(crate) fn solve_linear<T: Real, const N: usize>(
    mut a: [[T; N]; N],
    mut b: [T; N],
    m: usize,
) -> Option<[T; N]> {
    let mut scale = T::zero();
    for row in a.iter().take(m) {
        for v in row.iter().take(m) {
            scale = scale.max(v.abs());
        }
    }
    let tiny = scale * T::default_epsilon() * c(16.0);
    for col in 0..m {
        let mut piv = col;
        for row in col + 1..m {
            if a[row][col].abs() > a[piv][col].abs() {
                piv = row;
            }
        }
        let pivot = a[piv][col].abs();
        if pivot <= tiny || !pivot.is_finite() {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..m {
            let f = a[row][col] / a[col][col];
            for k in col..m {
                let v = a[col][k];
                a[row][k] -= f * v;
            }
            let v = b[col];
            b[row] -= f * v;
        }
    }
    let mut x = [T::zero(); N];
    for col in (0..m).rev() {
        let mut acc = b[col];
        for k in col + 1..m {
            acc -= a[col][k] * x[k];
        }
        x[col] = acc / a[col][col];
    }
    Some(x)
}

/// Smallest singular value of the leading `m x m` block (m <= 3), from the eigenvalues
/// of `J^T J`, signed with `det J`; unused dimensions are padded so they never count.
pub(crate) fn smallest_singular_value<T: Real, const N: usize>(jac: &[[T; N]; N], m: usize) -> T {
    if m == 1 {
        return jac[0][0];
    }
    if m == 2 {
        // closed form for 2x2: sigma_min = |det| / sigma_max, sigma_max^2 the larger
        // eigenvalue of J^T J
        let (a, b, cc, d) = (jac[0][0], jac[0][1], jac[1][0], jac[1][1]);
        let det = a * d - b * cc;
        let fro = a * a + b * b + cc * cc + d * d;
        let disc = (fro * fro - det * det * c(4.0)).max(T::zero()).sqrt();
        let smax = ((fro + disc) * c(0.5)).sqrt();
        return if smax > T::zero() {
            det / smax
        } else {
            T::zero()
        };
    }
    const PAD: f64 = 1e30;
    let mut a = nalgebra::Matrix3::<T>::from_diagonal_element(c(PAD));
    for i in 0..m.min(3) {
        for k in 0..m.min(3) {
            a[(i, k)] = jac[i][k];
        }
    }
    let ata = a.transpose() * a;
    let eig = nalgebra::SymmetricEigen::new(ata).eigenvalues;
    let min = eig
        .iter()
        .fold(T::max_value().unwrap_or(T::one()), |acc, &v| acc.min(v));
    // the sign of det J tells the branches apart: it is +1 with no coupling (J = I) and
    // flips at every bifurcation the solution passes
    let sigma = min.max(T::zero()).sqrt();
    if a.determinant() < T::zero() {
        -sigma
    } else {
        sigma
    }
}

/// The unit right singular vector of the smallest singular value of the leading
/// `m x m` block (m <= 3): the direction of the unknowns the block is softest in (at a
/// fold, the mode along which the solution snaps).
pub(crate) fn softest_direction<T: Real, const N: usize>(jac: &[[T; N]; N], m: usize) -> [T; N] {
    let mut v = [T::zero(); N];
    if m == 1 {
        v[0] = T::one();
        return v;
    }
    // the unused dimensions are padded with twice the block's Frobenius norm, more than
    // any of its singular values (a fixed huge pad would swamp the block's eigenvalues
    // in rounding: with 1e30, J^T J holds 1e60 and the 2 x 2 block's vectors are lost)
    let mut fro = T::zero();
    for row in jac.iter().take(m.min(3)) {
        for v in row.iter().take(m.min(3)) {
            fro += *v * *v;
        }
    }
    let pad = if fro > T::zero() {
        fro.sqrt() * c(2.0)
    } else {
        T::one()
    };
    let mut a = nalgebra::Matrix3::<T>::from_diagonal_element(pad);
    for i in 0..m.min(3) {
        for k in 0..m.min(3) {
            a[(i, k)] = jac[i][k];
        }
    }
    let eig = nalgebra::SymmetricEigen::new(a.transpose() * a);
    let mut best = 0;
    for k in 1..3 {
        if eig.eigenvalues[k] < eig.eigenvalues[best] {
            best = k;
        }
    }
    for (i, item) in v.iter_mut().enumerate().take(m.min(3)) {
        *item = eig.eigenvectors[(i, best)];
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_solve_and_margin() {
        let a = [[2.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 4.0]];
        let x = solve_linear(a, [3.0, 5.0, 5.0], 3).unwrap();
        for (i, row) in a.iter().enumerate() {
            let r: f64 = row.iter().zip(&x).map(|(p, q)| p * q).sum();
            assert!((r - [3.0, 5.0, 5.0][i]).abs() < 1e-14);
        }
        assert!(solve_linear([[1.0, 2.0], [2.0, 4.0]], [1.0, 2.0], 2).is_none());
        // diag(3, -0.5): sigma_min 0.5, det < 0
        let m: f64 = smallest_singular_value(&[[3.0, 0.0], [0.0, -0.5]], 2);
        assert!((m + 0.5).abs() < 1e-15);
        let m3: f64 =
            smallest_singular_value(&[[3.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 0.25]], 3);
        assert!((m3 - 0.25).abs() < 1e-12);
        let v: [f64; 3] =
            softest_direction(&[[3.0, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 2.0]], 3);
        assert!((v[1].abs() - 1.0).abs() < 1e-12 && v[0].abs() < 1e-12);
    }

    /// A 2 x 2 block in 3 x 3 arrays (a three-tube robot's shooting Jacobian): the right
    /// singular vector of its smallest singular value, `J^T J v = sigma^2 v`, not an axis.
    #[test]
    fn the_softest_direction_of_a_two_by_two_block() {
        let jac = [
            [0.9755520014869622, 0.028339249963063806, 0.0],
            [-1.2711266168363353, 0.2943040153961433, 0.0],
            [0.0, 0.0, 0.0],
        ];
        let v: [f64; 3] = softest_direction(&jac, 2);
        let sigma: f64 = smallest_singular_value(&jac, 2);
        // J^T J v against sigma^2 v
        let jv = [
            jac[0][0] * v[0] + jac[0][1] * v[1],
            jac[1][0] * v[0] + jac[1][1] * v[1],
        ];
        for k in 0..2 {
            let jtjv = jac[0][k] * jv[0] + jac[1][k] * jv[1];
            assert!((jtjv - sigma * sigma * v[k]).abs() < 1e-12, "{v:?}");
        }
        assert!((v[0] * v[0] + v[1] * v[1] - 1.0).abs() < 1e-12 && v[2] == 0.0);
        assert!(v[0].abs() > 0.1, "{v:?}"); // not the axis the 1e30 pad gave
    }
}
