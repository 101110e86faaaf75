//! The frames a pass along the backbone moves: the plain frame ([`Frame`], optionally
//! tracing backbone points), the frame with its derivatives (`Tangents`), or none
//! (`NoPose`); all behind `Pose`.
//!
//! # The derivatives as spatial twists
//!
//! `Tangents` carries the tip frame's derivatives (the pose half of the Jacobian
//! passes, [`crate::solve::jacobian`]) without differentiating 3 x 3 rotation matrices.
//!
//! The backbone's frame is a product of steps, `T' = T E`, with `E = exp(xi)` for a
//! body twist `xi = (w, v)` (a Magnus step, [`crate::math::se3::exp`]), a turn about the own z
//! axis, or a straight advance along it. A derivative direction `delta` of the frame is
//! kept as the spatial twist `eta = (phi, rho)` with
//! `delta T T^{-1} = [[phi]x, rho; 0, 0]`, so `delta R = [phi]x R` and
//! `delta p = phi x p + rho`. From `delta T' T'^{-1} = delta T T^{-1} + T (delta E
//! E^{-1}) T^{-1}`:
//!
//! ```text
//! phi' = phi + R phi_E,      rho' = rho + R rho_E + p x (R phi_E)
//! ```
//!
//! where `(phi_E, rho_E)` is `delta E E^{-1}`. For `E = exp(w, v)`, with
//! `R_E = I + a W + b W^2`, `p_E = V v`, `V = I + b W + d W^2` (`W = [w]x`, `t = |w|`,
//! `a = sin t / t`, `b = (1 - cos t)/t^2`, `d = (t - sin t)/t^3`), the left Jacobian of
//! SO(3) is `V` itself (Barfoot, State Estimation for Robotics, eq. 7.77 and 7.86):
//!
//! ```text
//! phi_E = V delta w
//! rho_E = delta p_E - phi_E x p_E = V delta v + C delta w
//! C delta w = 2 (w . delta w) (b' w x v + d' w x (w x v))
//!           + b delta w x v + d (delta w x (w x v) + w x (delta w x v)) - (V delta w) x p_E
//! ```
//!
//! with `b' = db/d(t^2) = (a - 2 b) / (2 t^2)` and `d' = (b - 3 d) / (2 t^2)` (their
//! Taylor series below `t^2 = 0.09`). Per step the plain 3 x 3 blocks `G = R V` and
//! `H = [p]x G + R C` are formed once and applied to every direction:
//! `phi += G delta w`, `rho += G delta v + H delta w` — 27 products per direction instead
//! of differentiating the exponential and the frame product entry by entry. A turn
//! `(cos a, sin a)` about z has `phi_E = delta a e_z`, `rho_E = 0`; an advance `h` along
//! z has `phi_E = 0`, `rho_E = delta h e_z`.
//!
//! At the end the derivative of the tip in direction `k` is `(phi_k x p + rho_k, phi_k)`:
//! the position's derivative and the spatial angular velocity, the rows of the
//! Jacobians.

use crate::math::dual::Dual;
use crate::math::linalg::{cross, mat_mul, M3, V3};
use crate::math::se3::{exp_of, Frame};
use crate::math::series::{sin_cos, SERIES_LIMIT_SQ, SINC, SIN_DEFECT, VERSINE};
use crate::model::effects::Registration;
use crate::real::{c, Real};
use nalgebra::{Matrix3, Vector3, Vector6};

/// A frame that a backbone integration moves step by step.
pub(crate) trait Pose<T, S> {
    /// False for `NoPose`: the pass then skips the pose's arithmetic altogether.
    const MOVES: bool = true;
    /// Moves the frame by `exp(w, v)` given in its own body coordinates.
    fn step(&mut self, w: V3<S>, v: V3<S>);
    /// Turns the frame about its own z axis by the angle whose (cos, sin) is given
    /// (a unit pair).
    fn rotate_z(&mut self, co: S, si: S);
    /// Turns the frame about its own y axis likewise.
    fn rotate_y(&mut self, co: S, si: S);
    /// Moves the frame by `h` along its own z axis.
    fn advance(&mut self, h: S);
    /// True when the pass should write backbone points: sections integrated in closed
    /// form are then cut into steps of the RK4 length too.
    fn traces(&self) -> bool {
        false
    }
    /// Writes the frame's origin as the next backbone point (where [`traces`](Self::traces)).
    fn mark(&mut self) {}
}

/// A pose that is not tracked (shooting iterations need only the free-tip twists).
pub(crate) struct NoPose;

impl<T, S> Pose<T, S> for NoPose {
    const MOVES: bool = false;
    #[inline(always)]
    fn step(&mut self, _: V3<S>, _: V3<S>) {}
    #[inline(always)]
    fn rotate_z(&mut self, _: S, _: S) {}
    #[inline(always)]
    fn rotate_y(&mut self, _: S, _: S) {}
    #[inline(always)]
    fn advance(&mut self, _: S) {}
}

impl<T: Real> Pose<T, T> for Frame<T> {
    #[inline(always)]
    fn step(&mut self, w: V3<T>, v: V3<T>) {
        let (r, p) = exp_of::<T, T>(w, v);
        self.compose(
            &Matrix3::new(
                r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
            ),
            &Vector3::new(p[0], p[1], p[2]),
        );
    }
    #[inline(always)]
    fn rotate_z(&mut self, co: T, si: T) {
        Frame::rotate_z(self, co, si);
    }
    #[inline(always)]
    fn rotate_y(&mut self, co: T, si: T) {
        Frame::rotate_y(self, co, si);
    }
    #[inline(always)]
    fn advance(&mut self, h: T) {
        self.position += self.rotation.column(2) * h;
    }
}

/// A plain frame that writes its origin into a caller's buffer at every
/// [`mark`](Pose::mark) (in the measuring frame of `registration`), counting the points
/// that did not fit.
pub(crate) struct Traced<'a, T: Real> {
    pub frame: Frame<T>,
    buf: &'a mut [Vector3<T>],
    registration: Option<Registration<T>>,
    /// Points the backbone has (written or not).
    pub needed: usize,
}

impl<'a, T: Real> Traced<'a, T> {
    /// Starts at `frame`, with no points written yet.
    pub fn new(
        frame: Frame<T>,
        buf: &'a mut [Vector3<T>],
        registration: Option<Registration<T>>,
    ) -> Self {
        Traced {
            frame,
            buf,
            registration,
            needed: 0,
        }
    }
}

impl<T: Real> Pose<T, T> for Traced<'_, T> {
    #[inline(always)]
    fn step(&mut self, w: V3<T>, v: V3<T>) {
        self.frame.step(w, v);
    }
    #[inline(always)]
    fn rotate_z(&mut self, co: T, si: T) {
        Frame::rotate_z(&mut self.frame, co, si);
    }
    #[inline(always)]
    fn rotate_y(&mut self, co: T, si: T) {
        Frame::rotate_y(&mut self.frame, co, si);
    }
    #[inline(always)]
    fn advance(&mut self, h: T) {
        Pose::<T, T>::advance(&mut self.frame, h);
    }
    fn traces(&self) -> bool {
        true
    }
    fn mark(&mut self) {
        if let Some(slot) = self.buf.get_mut(self.needed) {
            *slot = match &self.registration {
                Some(r) => r.apply_point(&self.frame.position),
                None => self.frame.position,
            };
        }
        self.needed += 1;
    }
}

/// A plain frame and, for each of `K` derivative directions, its spatial twist
/// `(phi, rho)` (see the [module doc](self)); stored direction-last so that each update
/// is one loop over the directions.
#[derive(Clone, Copy)]
pub(crate) struct Tangents<T, const K: usize> {
    /// rotation, row-major, columns the frame's axes in W
    pub r: M3<T>,
    /// origin in W, mm
    pub p: V3<T>,
    /// `phi[i][k]`: component i of direction k's angular part
    pub phi: [[T; K]; 3],
    /// `rho[i][k]`: component i of direction k's linear part
    pub rho: [[T; K]; 3],
}

/// `(a, b, d, b', d')` of the SE(3) exponential at `t2 = |w|^2` (see the
/// [module doc](self)); the same series and closed forms as [`exp_of`].
#[inline(always)]
fn coefficients<T: Real>(t2: T) -> [T; 5] {
    if t2 < c(SERIES_LIMIT_SQ) {
        [
            SINC.value(t2),
            VERSINE.value(t2),
            SIN_DEFECT.value(t2),
            VERSINE.derivative(t2),
            SIN_DEFECT.derivative(t2),
        ]
    } else {
        let t = t2.sqrt();
        let (s, co) = sin_cos(t);
        let a = s / t;
        let b = (T::one() - co) / t2;
        let d = (t - s) / (t2 * t);
        let half = c::<T>(0.5) / t2;
        [a, b, d, (a - b - b) * half, (b - d - d - d) * half]
    }
}

impl<T: Real, const K: usize> Tangents<T, K> {
    /// The world frame, no derivatives yet.
    pub fn identity() -> Self {
        let (o, l) = (T::zero(), T::one());
        Tangents {
            r: [[l, o, o], [o, l, o], [o, o, l]],
            p: [o; 3],
            phi: [[o; K]; 3],
            rho: [[o; K]; 3],
        }
    }

    /// The tip's derivative in direction `k`: `(dp, omega)` in W.
    pub fn column(&self, k: usize) -> Vector6<T> {
        let phi = [self.phi[0][k], self.phi[1][k], self.phi[2][k]];
        let pc = cross(&phi, &self.p);
        Vector6::new(
            pc[0] + self.rho[0][k],
            pc[1] + self.rho[1][k],
            pc[2] + self.rho[2][k],
            phi[0],
            phi[1],
            phi[2],
        )
    }

    /// Every direction's column (see [`column`](Self::column)).
    pub fn columns(&self) -> [Vector6<T>; K] {
        core::array::from_fn(|k| self.column(k))
    }

    /// Adds the spatial twist `(axis delta, p x axis delta)` of a turn about the W
    /// direction `axis` through the origin `p`, per direction `delta[k]`.
    #[inline(always)]
    fn add_turn(&mut self, axis: V3<T>, delta: &[T; K]) {
        let pa = cross(&self.p, &axis);
        for i in 0..3 {
            for k in 0..K {
                self.phi[i][k] += axis[i] * delta[k];
                self.rho[i][k] += pa[i] * delta[k];
            }
        }
    }
}

impl<T: Real, const K: usize> Pose<T, Dual<T, K>> for Tangents<T, K> {
    #[inline(always)]
    fn step(&mut self, w: V3<Dual<T, K>>, v: V3<Dual<T, K>>) {
        let wr = w.map(|x| x.re);
        let vr = v.map(|x| x.re);
        let t2 = wr[0] * wr[0] + wr[1] * wr[1] + wr[2] * wr[2];
        let [a, b, d, db, dd] = coefficients(t2);
        let one = T::one();
        let (x, y, z) = (wr[0], wr[1], wr[2]);
        let (xx, yy, zz) = (x * x, y * y, z * z);
        let (xy, xz, yz) = (x * y, x * z, y * z);
        // R_E = I + a W + b W^2, V = I + b W + d W^2 (W^2 = w w^T - t^2 I)
        let re = [
            [one - b * (yy + zz), b * xy - a * z, b * xz + a * y],
            [b * xy + a * z, one - b * (xx + zz), b * yz - a * x],
            [b * xz - a * y, b * yz + a * x, one - b * (xx + yy)],
        ];
        let vm = [
            [one - d * (yy + zz), d * xy - b * z, d * xz + b * y],
            [d * xy + b * z, one - d * (xx + zz), d * yz - b * x],
            [d * xz - b * y, d * yz + b * x, one - d * (xx + yy)],
        ];
        let wv = cross(&wr, &vr);
        let wwv = cross(&wr, &wv);
        let mut pe = [T::zero(); 3];
        for i in 0..3 {
            pe[i] = vr[i] + b * wv[i] + d * wwv[i];
        }
        // C, column by column (delta w = e_j)
        let two = c::<T>(2.0);
        let mut cm = [[T::zero(); 3]; 3];
        for j in 0..3 {
            let mut e = [T::zero(); 3];
            e[j] = one;
            let ev = cross(&e, &vr);
            let ewv = cross(&e, &wv);
            let wev = cross(&wr, &ev);
            let phi = [vm[0][j], vm[1][j], vm[2][j]];
            let pp = cross(&phi, &pe);
            let s = two * wr[j];
            for i in 0..3 {
                cm[i][j] =
                    s * (db * wv[i] + dd * wwv[i]) + b * ev[i] + d * (ewv[i] + wev[i]) - pp[i];
            }
        }
        let g = mat_mul(&self.r, &vm);
        let rc = mat_mul(&self.r, &cm);
        let mut h = [[T::zero(); 3]; 3];
        for j in 0..3 {
            let col = cross(&self.p, &[g[0][j], g[1][j], g[2][j]]);
            for i in 0..3 {
                h[i][j] = col[i] + rc[i][j];
            }
        }
        for i in 0..3 {
            for k in 0..K {
                let mut dphi = T::zero();
                let mut drho = T::zero();
                for j in 0..3 {
                    dphi += g[i][j] * w[j].eps[k];
                    drho += g[i][j] * v[j].eps[k] + h[i][j] * w[j].eps[k];
                }
                self.phi[i][k] += dphi;
                self.rho[i][k] += drho;
            }
        }
        // the plain frame
        for i in 0..3 {
            self.p[i] += self.r[i][0] * pe[0] + self.r[i][1] * pe[1] + self.r[i][2] * pe[2];
        }
        self.r = mat_mul(&self.r, &re);
    }

    #[inline(always)]
    fn rotate_z(&mut self, co: Dual<T, K>, si: Dual<T, K>) {
        let delta: [T; K] = core::array::from_fn(|k| co.re * si.eps[k] - si.re * co.eps[k]);
        self.add_turn([self.r[0][2], self.r[1][2], self.r[2][2]], &delta);
        for row in self.r.iter_mut() {
            let (x, y) = (row[0], row[1]);
            row[0] = x * co.re + y * si.re;
            row[1] = y * co.re - x * si.re;
        }
    }

    #[inline(always)]
    fn rotate_y(&mut self, co: Dual<T, K>, si: Dual<T, K>) {
        let delta: [T; K] = core::array::from_fn(|k| co.re * si.eps[k] - si.re * co.eps[k]);
        self.add_turn([self.r[0][1], self.r[1][1], self.r[2][1]], &delta);
        // R <- R Ry: columns x' = c x - s z, z' = s x + c z
        for row in self.r.iter_mut() {
            let (x, z) = (row[0], row[2]);
            row[0] = x * co.re - z * si.re;
            row[2] = x * si.re + z * co.re;
        }
    }

    #[inline(always)]
    fn advance(&mut self, h: Dual<T, K>) {
        for i in 0..3 {
            let axis = self.r[i][2];
            for k in 0..K {
                self.rho[i][k] += axis * h.eps[k];
            }
            self.p[i] += axis * h.re;
        }
    }
}

/// Spatial-twist columns `(dp, omega)` of a frame given as dual numbers: `dp` is the
/// position's derivative, `[omega]x = dR R^T` from its antisymmetric part.
pub(crate) fn columns_of_duals<T: Real, const K: usize>(
    position: &[Dual<T, K>; 3],
    rotation: &[[Dual<T, K>; 3]; 3],
) -> [Vector6<T>; K] {
    core::array::from_fn(|k| {
        let w = |i: usize, j: usize| {
            let mut acc = T::zero();
            for m in 0..3 {
                acc += rotation[i][m].eps[k] * rotation[j][m].re;
            }
            acc
        };
        let half = c::<T>(0.5);
        Vector6::new(
            position[0].eps[k],
            position[1].eps[k],
            position[2].eps[k],
            (w(2, 1) - w(1, 2)) * half,
            (w(0, 2) - w(2, 0)) * half,
            (w(1, 0) - w(0, 1)) * half,
        )
    })
}
