//! The twist equations with their variations: the sensitivities of the relative angles
//! and twist rates to the shooting unknowns `x_k = u_k(0)`, integrated alongside the
//! values by the same RK4 steps (so they are exact derivatives of the discrete map).
//!
//! Linearising [`crate::integrate::twist`]'s equations, with `beta_jk = d b_j / d x_k`
//! and `omega_jk = d u_j / d x_k`:
//!
//! ```text
//! beta_jk'  = omega_jk - d u_n / d x_k
//! omega_jk' = g_j sum_l a_l cos(b_j - b_l) (beta_jk - beta_lk)
//! ```
//!
//! The angle's sensitivity is carried once (`beta`), not as the derivatives of its
//! cosine and sine: a third of the work of dual numbers, which is why Newton's passes
//! use this state and the Jacobian passes (which need the pose) use duals.

use super::twist::{rotate_angles, TwistOde, TwistSection, TwistState};
use super::OdeState;
use crate::real::Real;

/// Twist values and their sensitivities to the `N - 1` shooting unknowns.
#[derive(Clone, Copy)]
pub(crate) struct Variations<T, const N: usize> {
    pub v: TwistState<T, N>,
    /// `d b_j / d x_k`
    pub db: [[T; N]; N],
    /// `d u_j / d x_k`
    pub dw: [[T; N]; N],
}

impl<T: Real, const N: usize> OdeState<T> for Variations<T, N> {
    #[inline(always)]
    fn zip_with<const K: usize>(&mut self, k: [&Self; K], f: impl Fn(T, [T; K]) -> T) {
        for j in 0..N - 1 {
            for cc in 0..2 {
                self.v.z[j][cc] = f(self.v.z[j][cc], k.map(|x| x.v.z[j][cc]));
            }
            self.v.w[j] = f(self.v.w[j], k.map(|x| x.v.w[j]));
            for m in 0..N - 1 {
                self.db[j][m] = f(self.db[j][m], k.map(|x| x.db[j][m]));
                self.dw[j][m] = f(self.dw[j][m], k.map(|x| x.dw[j][m]));
            }
        }
    }
}

/// Tube n's twist sensitivities `d u_n / d x_k` from the conservation of torque.
#[inline(always)]
fn inner_sensitivity<T: Real, const N: usize>(
    sec: &TwistSection<T, T, T, N>,
    dw: &[[T; N]; N],
) -> [T; N] {
    let mut dun = [T::zero(); N];
    for j in 0..N - 1 {
        if sec.present[j] {
            for k in 0..N - 1 {
                dun[k] -= sec.gj[j] * dw[j][k];
            }
        }
    }
    for d in dun.iter_mut() {
        *d *= sec.inv_gj_n;
    }
    dun
}

impl<T: Real, const N: usize> TwistOde<T, T, T, N> for Variations<T, N> {
    #[inline(always)]
    fn values(&self) -> &TwistState<T, N> {
        &self.v
    }
    #[inline(always)]
    fn values_mut(&mut self) -> &mut TwistState<T, N> {
        &mut self.v
    }
    #[inline(always)]
    fn rhs(&self, sec: &TwistSection<T, T, T, N>) -> Self {
        let v = sec.rhs(&self.v);
        let mut d = Variations {
            v,
            db: [[T::zero(); N]; N],
            dw: [[T::zero(); N]; N],
        };
        let dun = inner_sensitivity(sec, &self.dw);
        for j in 0..N - 1 {
            if !sec.present[j] {
                continue;
            }
            for k in 0..N - 1 {
                d.db[j][k] = self.dw[j][k] - dun[k];
            }
            if !sec.curved_g[j] {
                continue;
            }
            let [cj, sj] = self.v.z[j];
            for l in 0..N {
                if l != j && sec.curved_a[l] {
                    let [cl, sl] = self.v.z[l];
                    let cosd = cj * cl + sj * sl;
                    for k in 0..N - 1 {
                        d.dw[j][k] += sec.g[j] * sec.a[l] * cosd * (self.db[j][k] - self.db[l][k]);
                    }
                }
            }
        }
        d
    }
    #[inline(always)]
    fn rotate(&mut self, sec: &TwistSection<T, T, T, N>, un: T, h: T) {
        let dun = inner_sensitivity(sec, &self.dw);
        rotate_angles(&mut self.v.z, &self.v.w, &sec.present, un, h);
        for j in 0..N - 1 {
            if sec.present[j] {
                for k in 0..N - 1 {
                    self.db[j][k] += (self.dw[j][k] - dun[k]) * h;
                }
            }
        }
    }
}
