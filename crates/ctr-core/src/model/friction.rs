//! Friction between tubes: hysteresis of the relative rotation (and feed).
//!
//! Two switchable models: the kinematic play operator ([`PlayFriction`], below) and the
//! seed's boundary friction moment ([`BoundaryMoment`], further below), which changes
//! the mechanics' boundary condition.
//!
//! Friction opposes relative rotation, so what reaches the distal end of a tube lags the
//! actuator until the friction moment is overcome, and the lag changes sign with the
//! direction of motion: hysteresis. Here it is the play (backlash) operator on each
//! neighbouring pair's relative rotation, the memory-carrying form of the seed's
//! boundary friction moment (Liu et al. 2023, eq. 10: `beta'(L) = mu' |M| (1/k_2z -
//! 1/k_1z)`, sign set by the direction of relative rotation): the actual relative
//! rotation `y` follows the commanded one `x = theta_{i+1} - theta_i` only once `x`
//! has moved `w` past it,
//!
//! ```text
//! y <- min(x + w, max(x - w, y))
//! ```
//!
//! with half-width `w` (rad) growing with the friction coefficient. Tube 1 turns as
//! commanded; tube i+1 turns to `theta_i(actual) + y_i`. Feed friction is the same
//! operator on each exposed length `s_i` (half-width in mm). The state starts centred at
//! the first command of a run ([`PlayFriction::reset`]).

use crate::model::joints::Joints;
use crate::model::robot::Robot;
use crate::real::Real;
use crate::solve::{Model, Request, Solution, SolveError, Solver};

/// Play-operator friction parameters and memory for a robot of `N` tubes.
///
/// ```
/// use ctr_core::{friction::PlayFriction, Joints};
/// let mut f = PlayFriction::<f64, 2>::new([0.1, 0.0], [0.0; 2]);
/// let q = |t: f64| Joints::new([10.0, 50.0], [0.0, t]);
/// f.reset(&q(0.0));
/// assert_eq!(f.apply(&q(0.05)).theta_rad[1], 0.0);          // inside the play: no motion
/// assert!((f.apply(&q(0.3)).theta_rad[1] - 0.2).abs() < 1e-15); // dragged, lagging by w
/// assert!((f.apply(&q(0.25)).theta_rad[1] - 0.2).abs() < 1e-15); // reversal: stays
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlayFriction<T, const N: usize> {
    /// Half-width of the rotation play of pair (i, i+1), rad; the last entry is unused.
    pub rotation_half_width_rad: [T; N],
    /// Half-width of the feed play of each tube, mm.
    pub feed_half_width_mm: [T; N],
    rotation: [T; N],
    feed: [T; N],
}

impl<T: Real, const N: usize> PlayFriction<T, N> {
    /// Friction with the given half-widths, state centred at zero.
    ///
    /// ```
    /// let f = ctr_core::friction::PlayFriction::<f64, 3>::new([0.1; 3], [0.0; 3]);
    /// assert_eq!(f.rotation_half_width_rad[0], 0.1);
    /// ```
    pub fn new(rotation_half_width_rad: [T; N], feed_half_width_mm: [T; N]) -> Self {
        PlayFriction {
            rotation_half_width_rad,
            feed_half_width_mm,
            rotation: [T::zero(); N],
            feed: [T::zero(); N],
        }
    }

    /// Centres the memory on a command (the start of a run).
    ///
    /// ```
    /// # use ctr_core::{friction::PlayFriction, Joints};
    /// let mut f = PlayFriction::<f64, 2>::new([0.1, 0.0], [0.0; 2]);
    /// f.reset(&Joints::new([10.0, 50.0], [0.0, 1.0]));
    /// assert_eq!(f.apply(&Joints::new([10.0, 50.0], [0.0, 1.0])).theta_rad[1], 1.0);
    /// ```
    pub fn reset(&mut self, q: &Joints<T, N>) {
        for i in 0..N {
            self.feed[i] = q.s_mm[i];
            if i + 1 < N {
                self.rotation[i] = q.theta_rad[i + 1] - q.theta_rad[i];
            }
        }
    }

    /// Steps the memory to a new command and returns the actual joints.
    pub fn apply(&mut self, q: &Joints<T, N>) -> Joints<T, N> {
        let mut out = *q;
        play_step(
            &mut self.rotation,
            &mut self.feed,
            &self.rotation_half_width_rad,
            &self.feed_half_width_mm,
            &mut out.s_mm,
            &mut out.theta_rad,
        );
        out
    }
}

/// One step of the play-operator friction on slices (any number of tubes): moves the
/// memories `rotation` (per pair) and `feed` (per tube) to the command in `s` and
/// `theta` and overwrites those with the actual joints. [`PlayFriction::apply`] is this
/// on arrays; the std layer calls it for robots whose size is known at run time.
///
/// ```
/// let (mut rot, mut feed) = ([0.0_f64], [10.0, 50.0]);
/// let (mut s, mut theta) = ([10.0, 50.0], [0.0, 0.3]);
/// ctr_core::friction::play_step(&mut rot, &mut feed, &[0.1], &[0.0, 0.0], &mut s, &mut theta);
/// assert!((theta[1] - 0.2).abs() < 1e-15);
/// ```
pub fn play_step<T: Real>(
    rotation: &mut [T],
    feed: &mut [T],
    rotation_half_width: &[T],
    feed_half_width: &[T],
    s: &mut [T],
    theta: &mut [T],
) {
    let n = s
        .len()
        .min(theta.len())
        .min(feed.len())
        .min(feed_half_width.len());
    for i in 0..n {
        feed[i] = play(feed[i], s[i], feed_half_width[i]);
        s[i] = feed[i];
    }
    let pairs = n
        .saturating_sub(1)
        .min(rotation.len())
        .min(rotation_half_width.len());
    // commanded relative rotations first: the loop below overwrites theta
    let mut prev_cmd = if n > 0 { theta[0] } else { T::zero() };
    for i in 0..pairs {
        let x = theta[i + 1] - prev_cmd;
        prev_cmd = theta[i + 1];
        rotation[i] = play(rotation[i], x, rotation_half_width[i]);
        theta[i + 1] = theta[i] + rotation[i];
    }
    // feeds must keep their order even where plays differ
    for i in 1..n {
        if s[i] < s[i - 1] {
            s[i] = s[i - 1];
        }
    }
}

/// The play operator: output `y` follows input `x` once it is `w` away.
#[inline]
pub fn play<T: Real>(y: T, x: T, w: T) -> T {
    (x + w).min((x - w).max(y))
}

// ---------------------------------------------------------------------------------------

/// The seed's boundary friction moment, with a memory of the direction of relative
/// rotation (hysteresis).
///
/// # Physics
///
/// Where tube j ends inside its neighbour (its tip at `s_j`), the inner tube j+1 leaves
/// it with a concentrated contact that carries tube j's bending moment
/// `M_j = E I_j (u - k_j e_j)` (`u` the shared curvature just before the tip, `e_j`
/// tube j's precurvature direction). Relative rotation of the pair there meets a
/// friction moment `tau_j = mu'_j |M_j|` (Liu et al. 2023, Sensors 23:3709, eq. 10:
/// `beta'(L) = mu' |M| (1/k_2z - 1/k_1z)`; `mu'` lumps the friction coefficient and
/// the ratio of the tube radius to the lever arm of the contact forces, so it is
/// dimensionless), with the sign of the direction of relative rotation
/// `sigma_j = sign(d(theta_{j+1} - theta_j))`. It enters the twist boundary-value
/// problem of [`crate::integrate::twist`] as the torque at tube j's tip and its reaction on tube
/// j+1:
///
/// ```text
/// G J_j u_j(s_j) = sigma_j mu'_j |M_j|,      G J_{j+1} [u_{j+1}]_{s_j} = sigma_j mu'_j |M_j|
/// ```
///
/// (the free tip's zero-torque condition of the frictionless model becomes a prescribed
/// torque; the total torque stays zero). For two tubes the relative twist at the
/// boundary is then `beta'(s_1) = u_2 - u_1 = -sigma mu' |M| (1/G J_1 + 1/G J_2)`: the
/// seed's eq. 10 with both compliances adding (the seed prints their difference).
/// The memory is the sign: it flips only when the commanded relative rotation reverses,
/// so a rotation forward and back traces two branches (a hysteresis loop) whose width
/// grows with `mu'`. Sticking (friction below its limit after a reversal) is not
/// modelled: the moment switches sign at once.
///
/// ```
/// use ctr_core::{friction::BoundaryMoment, Joints, Robot, Solver, TubeParams};
/// let outer = TubeParams { curvature_radius_mm: Some(200.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
/// let inner = TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) };
/// let robot = Robot::new([outer, inner]).unwrap();
/// let mut friction = BoundaryMoment::new([0.2, 0.0]);
/// let mut solver = Solver::default();
/// let at = |deg: f64| Joints::from_mm_deg([40.0, 90.0], [0.0, deg]);
/// friction.step(&mut solver, &robot, &at(80.0)).unwrap();
/// let forward = friction.step(&mut solver, &robot, &at(90.0)).unwrap();
/// friction.step(&mut solver, &robot, &at(100.0)).unwrap();
/// let back = friction.step(&mut solver, &robot, &at(90.0)).unwrap();
/// // same command, different direction of approach: different tips
/// assert!((forward.tip.position - back.tip.position).norm() > 1e-3);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundaryMoment<T, const N: usize> {
    /// `mu'` of pair (j, j+1) (tube j's tip), dimensionless; the last entry is unused.
    pub mu: [T; N],
    direction: [T; N],
    last: Option<[T; N]>,
}

impl<T: Real, const N: usize> BoundaryMoment<T, N> {
    /// Friction with coefficients `mu` and no remembered direction.
    ///
    /// ```
    /// let f = ctr_core::friction::BoundaryMoment::<f64, 2>::new([0.1, 0.0]);
    /// assert_eq!(f.direction(), [0.0, 0.0]);
    /// ```
    pub fn new(mu: [T; N]) -> Self {
        BoundaryMoment {
            mu,
            direction: [T::zero(); N],
            last: None,
        }
    }

    /// Forgets the direction memory (the start of a run): no friction moment until a
    /// pair turns.
    ///
    /// ```
    /// let mut f = ctr_core::friction::BoundaryMoment::<f64, 2>::new([0.1, 0.0]);
    /// f.reset();
    /// assert_eq!(f.direction(), [0.0, 0.0]);
    /// ```
    pub fn reset(&mut self) {
        self.direction = [T::zero(); N];
        self.last = None;
    }

    /// The remembered direction of relative rotation of each pair: +1, -1 or 0 (not
    /// moved yet).
    ///
    /// ```
    /// use ctr_core::{friction::BoundaryMoment, Joints};
    /// let mut f = BoundaryMoment::<f64, 2>::new([0.1, 0.0]);
    /// f.update(&Joints::new([10.0, 50.0], [0.0, 0.0]));
    /// f.update(&Joints::new([10.0, 50.0], [0.0, -0.1]));
    /// assert_eq!(f.direction()[0], -1.0);
    /// ```
    pub fn direction(&self) -> [T; N] {
        self.direction
    }

    /// Steps the direction memory to a new command (a pair that did not turn keeps its
    /// direction).
    ///
    /// ```
    /// use ctr_core::{friction::BoundaryMoment, Joints};
    /// let mut f = BoundaryMoment::<f64, 2>::new([0.1, 0.0]);
    /// f.update(&Joints::new([10.0, 50.0], [0.0, 0.0]));
    /// f.update(&Joints::new([10.0, 50.0], [0.0, 0.2]));
    /// f.update(&Joints::new([10.0, 50.0], [0.0, 0.2]));
    /// assert_eq!(f.direction()[0], 1.0);
    /// ```
    pub fn update(&mut self, q: &Joints<T, N>) {
        let mut rel = [T::zero(); N];
        for j in 0..N - 1 {
            rel[j] = q.theta_rad[j + 1] - q.theta_rad[j];
        }
        if let Some(last) = self.last {
            for j in 0..N - 1 {
                let d = rel[j] - last[j];
                if d > T::zero() {
                    self.direction[j] = T::one();
                } else if d < T::zero() {
                    self.direction[j] = -T::one();
                }
            }
        }
        self.last = Some(rel);
    }

    /// The boundary moment coefficient of each pair, `mu'_j sigma_j`: what
    /// [`Request::friction`] takes.
    ///
    /// ```
    /// use ctr_core::{friction::BoundaryMoment, Joints};
    /// let mut f = BoundaryMoment::<f64, 2>::new([0.1, 0.0]);
    /// f.update(&Joints::new([10.0, 50.0], [0.0, 0.0]));
    /// f.update(&Joints::new([10.0, 50.0], [0.0, -0.1]));
    /// assert_eq!(f.coefficients(), [-0.1, 0.0]);
    /// ```
    pub fn coefficients(&self) -> [T; N] {
        let mut out = [T::zero(); N];
        for j in 0..N.saturating_sub(1) {
            out[j] = self.mu[j] * self.direction[j];
        }
        out
    }

    /// Steps the memory to `q` and solves the torsion model with the friction moments it
    /// implies (the trajectory API; a single solve takes [`Request::friction`]).
    pub fn step(
        &mut self,
        solver: &mut Solver<T, N>,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
    ) -> Result<Solution<T, N>, SolveError> {
        self.update(q);
        let request = Request::new(*q, Model::Torsion).friction(self.coefficients());
        solver.solve(robot, request)
    }
}
