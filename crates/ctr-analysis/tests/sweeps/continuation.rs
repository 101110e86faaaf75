//! An independent model of a two-tube robot's twist and the branch a physical robot
//! follows along a joint sweep: numerical continuation with the actuator angles as the
//! parameter, written from the seed's two-tube formulation and nothing of `ctr-core`
//! but the tube parameters.
//!
//! # Model (seed eq. 8; Dupont et al., IEEE T-RO 26(2) 2010; Gilbert, Hendrick & Webster,
//! IEEE T-RO 32(1) 2016)
//!
//! With `b = psi_1 - psi_2` the relative twist angle of the outer tube against the inner
//! one and `K_i = E_i I_i`, `J_i = G_i J_i`, the torsion balance of the overlapped part
//! (both tubes present, `0 <= s <= s_1`) is
//!
//! ```text
//! b'' = C sin b    over parts where both tubes are curved,   C = K1 K2 k1 k2 (1/J1 + 1/J2) / (K1 + K2)
//! b'' = 0          elsewhere
//! ```
//!
//! (`C = (1 + nu) k1 k2` when both tubes have the same Poisson ratio.) The total torque
//! `J1 u1 + J2 u2` is zero, so `u1 = b' J2 / (J1 + J2)`, `u2 = -b' J1 / (J1 + J2)`. Behind
//! the guide exit tube i twists uniformly over its transmission `L_i = length_i - s_i`, so
//! `b(0) = theta_1 - theta_2 + L_eff b'(0)` with `L_eff = (L1 J2 + L2 J1) / (J1 + J2)`; the
//! outer tube's free tip carries no torque: `b'(s_1) = 0`. Shooting on `x = b'(0)` gives
//! the scalar residual `r(x) = b'(s_1)`; `dr/dx` (integrated with the variational equation
//! `db'' = C cos b db`) is positive on a stable branch, zero at a fold (a snap) and
//! negative on the unstable branch between two folds.
//!
//! The backbone is tube 2's material frame `g' = g (u_x, u_y, u_2; 0, 0, 1)^` with the
//! bending curvature `sum_l a_l (-sin b_l, cos b_l)`, `a_l = K_l k_l / sum_present K` over
//! tube l's curved part, started at the guide exit turned by `psi_2(0) = theta_2 + L_2 u_2(0)`.
//!
//! # Continuation
//!
//! Along a sweep the robot follows its branch quasi-statically: from one row to the next
//! the actuator angles move in small substeps, each solved by Newton from the last
//! solution; when the branch ends (a fold: Newton fails or lands on the unstable side)
//! the robot jumps, and the new branch is the stable root of `r` found by scanning every
//! root at that angle. Every root of `r` lies in `|x| <= 2 sqrt|C|` (a first integral of
//! the overlap's equation with `b'(s_1) = 0`).

use ctr_core::TubeParams;
use nalgebra::{Matrix3, Rotation3, Vector3};
use std::f64::consts::PI;

/// RK4 step of the twist and of the frame, mm (tip error far below 0.01 mm).
const STEP_MM: f64 = 0.05;
/// Substeps of the actuator angles between two rows.
const SUBSTEPS: usize = 16;
/// Points of the scan for every root of `r` at a jump.
const SCAN_POINTS: usize = 4000;
/// Points of the scan for the lowest eigenvalue.
const MU_SCAN_POINTS: usize = 400;
/// Newton's residual tolerance, rad/mm.
const TOLERANCE: f64 = 1e-13;

/// One tube as the model needs it.
#[derive(Clone, Copy, Debug)]
struct Tube {
    length: f64,
    curved: f64,
    k: f64,
    ei: f64,
    gj: f64,
}

impl Tube {
    fn new(p: &TubeParams<f64>) -> Self {
        let d4 = p.outer_diameter_mm.powi(4) - p.inner_diameter_mm.powi(4);
        let ei = p
            .bending_stiffness_nmm2
            .unwrap_or(p.youngs_modulus_mpa * PI * d4 / 64.0);
        let gj = p
            .torsional_stiffness_nmm2
            .unwrap_or(p.youngs_modulus_mpa / (2.0 * (1.0 + p.poisson_ratio)) * PI * d4 / 32.0);
        Tube {
            length: p.length_mm,
            curved: p.curved_length_mm,
            k: p.curvature_radius_mm.map_or(0.0, |r| 1.0 / r),
            ei,
            gj,
        }
    }
    /// Curved at arc length `s` when fed by `feed`.
    fn curved_at(&self, s: f64, feed: f64) -> bool {
        self.k != 0.0 && s >= feed - self.curved && s <= feed
    }
}

/// A two-tube robot at one pair of feeds.
#[derive(Clone, Copy, Debug)]
pub struct TwoTubes {
    t: [Tube; 2],
    /// feeds, mm
    s: [f64; 2],
}

/// One equilibrium: its unknown, its residual's slope and its tip.
#[derive(Clone, Copy, Debug)]
pub struct Equilibrium {
    /// `b'(0)`, rad/mm.
    pub x: f64,
    /// `dr/dx`: positive stable, zero at a fold, negative unstable.
    pub slope: f64,
    /// Tip position, mm.
    pub tip: [f64; 3],
}

impl TwoTubes {
    /// The robot of `params` (outer first) at feeds `s` (mm).
    pub fn new(params: &[TubeParams<f64>], s: [f64; 2]) -> Self {
        TwoTubes {
            t: [Tube::new(&params[0]), Tube::new(&params[1])],
            s,
        }
    }

    /// `C` of the module doc, 1/mm^2.
    pub fn coupling(&self) -> f64 {
        let [a, b] = self.t;
        a.ei * b.ei * a.k * b.k * (1.0 / a.gj + 1.0 / b.gj) / (a.ei + b.ei)
    }

    /// `L_eff`: the transmissions' compliance-weighted length, mm.
    pub fn transmission(&self) -> f64 {
        let [a, b] = self.t;
        let (l1, l2) = (a.length - self.s[0], b.length - self.s[1]);
        (l1 * b.gj + l2 * a.gj) / (a.gj + b.gj)
    }

    /// Where both tubes are curved over `[0, s_1]`: `(start, end)`, mm, if anywhere.
    pub fn overlap(&self) -> Option<(f64, f64)> {
        let start = (self.s[0] - self.t[0].curved)
            .max(self.s[1] - self.t[1].curved)
            .max(0.0);
        let end = self.s[0];
        (self.t[0].k != 0.0 && self.t[1].k != 0.0 && end > start).then_some((start, end))
    }

    /// `b(0)` for actuator angles `theta` (rad) and unknown `x`.
    fn b0(&self, theta: [f64; 2], x: f64) -> f64 {
        theta[0] - theta[1] + self.transmission() * x
    }

    /// Integrates `(b, b', db, db')` over `[0, s_1]`; `f` sees every step's start.
    fn shoot(&self, theta: [f64; 2], x: f64, mut f: impl FnMut(f64, f64, f64)) -> (f64, f64) {
        let c = self.coupling();
        let mut y = [self.b0(theta, x), x, self.transmission(), 1.0];
        let end = self.s[0];
        let steps = (end / STEP_MM).ceil().max(1.0) as usize;
        let h = end / steps as f64;
        for i in 0..steps {
            let s0 = i as f64 * h;
            f(s0, y[0], y[1]);
            let both =
                |s: f64| self.t[0].curved_at(s, self.s[0]) && self.t[1].curved_at(s, self.s[1]);
            let rhs = |s: f64, y: [f64; 4]| {
                let g = if both(s) { c } else { 0.0 };
                [y[1], g * y[0].sin(), y[3], g * y[0].cos() * y[2]]
            };
            // the curved parts start inside a step only where a cut falls: evaluate the
            // coefficient at the step's middle (steps are short against every length)
            let sm = s0 + 0.5 * h;
            y = rk4(y, h, |y| rhs(sm, y));
        }
        f(end, y[0], y[1]);
        (y[1], y[3])
    }

    /// The residual `r(x) = b'(s_1)` and its slope at actuator angles `theta`, rad.
    pub fn residual(&self, theta: [f64; 2], x: f64) -> (f64, f64) {
        self.shoot(theta, x, |_, _, _| {})
    }

    /// The tip of the solution `x` at `theta`, mm.
    pub fn tip(&self, theta: [f64; 2], x: f64) -> [f64; 3] {
        let mut b_at = Vec::new();
        self.shoot(theta, x, |s, b, db| b_at.push((s, b, db)));
        let [a, bt] = self.t;
        let u2 = |db: f64| -db * a.gj / (a.gj + bt.gj);
        let psi2 = theta[1] + (bt.length - self.s[1]) * u2(x);
        let mut r = Rotation3::from_axis_angle(&Vector3::z_axis(), psi2).into_inner();
        let mut p = Vector3::zeros();
        let (s1, s2) = (self.s[0], self.s[1]);
        // the relative angle and its rate at s (s <= s_1), linear between stored steps
        let state = |s: f64| -> (f64, f64) {
            let i = b_at.partition_point(|e| e.0 <= s).clamp(1, b_at.len() - 1);
            let (sa, ba, da) = b_at[i - 1];
            let (sb, bb, dbb) = b_at[i];
            let w = if sb > sa { (s - sa) / (sb - sa) } else { 0.0 };
            (ba + w * (bb - ba), da + w * (dbb - da))
        };
        let curvature = |s: f64| -> Vector3<f64> {
            if s <= s1 {
                let (b, db) = state(s);
                let (k1, k2) = (
                    if a.curved_at(s, s1) { a.k } else { 0.0 },
                    if bt.curved_at(s, s2) { bt.k } else { 0.0 },
                );
                let sum = a.ei + bt.ei;
                let (a1, a2) = (a.ei * k1 / sum, bt.ei * k2 / sum);
                Vector3::new(-a1 * b.sin(), a1 * b.cos() + a2, u2(db))
            } else {
                let k2 = if bt.curved_at(s, s2) { bt.k } else { 0.0 };
                Vector3::new(0.0, k2, 0.0)
            }
        };
        let steps = (s2 / STEP_MM).ceil().max(1.0) as usize;
        let h = s2 / steps as f64;
        for i in 0..steps {
            let u = curvature((i as f64 + 0.5) * h);
            let half = r * exp_so3(&(u * (0.5 * h)));
            p += half * Vector3::z() * h;
            r *= exp_so3(&(u * h));
        }
        [p.x, p.y, p.z]
    }

    /// Newton on `r` from `x` at `theta`: the root, if it converges.
    pub fn newton(&self, theta: [f64; 2], mut x: f64) -> Option<f64> {
        for _ in 0..40 {
            let (r, slope) = self.residual(theta, x);
            if r.abs() < TOLERANCE {
                return Some(x);
            }
            if slope == 0.0 || !slope.is_finite() {
                return None;
            }
            x -= r / slope;
        }
        None
    }

    /// Every root of `r` at `theta`, by a scan of `|x| <= 2.2 sqrt|C|` and bisection.
    pub fn roots(&self, theta: [f64; 2]) -> Vec<f64> {
        let span = 2.2 * self.coupling().abs().sqrt();
        if span == 0.0 || self.overlap().is_none() {
            return self.newton(theta, 0.0).into_iter().collect();
        }
        let xs: Vec<f64> = (0..=SCAN_POINTS)
            .map(|i| -span + 2.0 * span * i as f64 / SCAN_POINTS as f64)
            .collect();
        let rs: Vec<f64> = xs.iter().map(|&x| self.residual(theta, x).0).collect();
        let mut roots = Vec::new();
        for i in 0..SCAN_POINTS {
            if rs[i] == 0.0 || rs[i].signum() != rs[i + 1].signum() {
                let (mut lo, mut hi) = (xs[i], xs[i + 1]);
                let rlo = rs[i];
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if self.residual(theta, mid).0.signum() == rlo.signum() {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                roots.push(
                    self.newton(theta, 0.5 * (lo + hi))
                        .unwrap_or(0.5 * (lo + hi)),
                );
            }
        }
        roots
    }

    /// The stiffness of the softest twist mode at the root `x`, relative to the
    /// uncoupled tubes': the lowest eigenvalue `mu_1` of the second variation of the
    /// elastic energy, `-h'' + C cos(b) h = mu h` on `[0, s_1]` with the transmission a
    /// spring (`h'(0) = h(0) / L_eff`) and a free tip (`h'(s_1) = 0`), over the same
    /// without coupling (`omega tan(omega s_1) = 1 / L_eff`, `mu_0 = omega^2`). Found as
    /// the first sign change of the shooting function `h'(s_1; mu)` scanned up in `mu`.
    pub fn stiffness_ratio(&self, theta: [f64; 2], x: f64) -> f64 {
        let c = self.coupling();
        let l = self.transmission();
        let end = self.s[0];
        let steps = (end / STEP_MM).ceil().max(1.0) as usize;
        let h = end / steps as f64;
        let run = |mu: f64| -> f64 {
            let mut y = [self.b0(theta, x), x, l, 1.0];
            for i in 0..steps {
                let sm = (i as f64 + 0.5) * h;
                let both = self.t[0].curved_at(sm, self.s[0]) && self.t[1].curved_at(sm, self.s[1]);
                let g = if both { c } else { 0.0 };
                y = rk4(y, h, |y| {
                    [y[1], g * y[0].sin(), y[3], (g * y[0].cos() - mu) * y[2]]
                });
            }
            y[3]
        };
        let (mut lo, mut hi) = (0.0, std::f64::consts::FRAC_PI_2 / end);
        for _ in 0..100 {
            let w = 0.5 * (lo + hi);
            if w * (w * end).tan() < 1.0 / l {
                lo = w;
            } else {
                hi = w;
            }
        }
        let mu0 = lo * lo;
        // below every eigenvalue the shooting function keeps the sign it has far below
        let mut a = -4.0 * c.abs() - mu0;
        let below = run(a).signum();
        let top = 2.0 * mu0 + 4.0 * c.abs();
        let step = (top - a) / MU_SCAN_POINTS as f64;
        for _ in 0..MU_SCAN_POINTS {
            let b = a + step;
            if run(b).signum() != below {
                let (mut lo, mut hi) = (a, b);
                for _ in 0..60 {
                    let m = 0.5 * (lo + hi);
                    if run(m).signum() == below {
                        lo = m;
                    } else {
                        hi = m;
                    }
                }
                return 0.5 * (lo + hi) / mu0;
            }
            a = b;
        }
        f64::NAN
    }

    /// The equilibrium at `x` (a root) and `theta`.
    pub fn equilibrium(&self, theta: [f64; 2], x: f64) -> Equilibrium {
        Equilibrium {
            x,
            slope: self.residual(theta, x).1,
            tip: self.tip(theta, x),
        }
    }
}

/// `exp` of the skew matrix of `w`.
fn exp_so3(w: &Vector3<f64>) -> Matrix3<f64> {
    Rotation3::new(*w).into_inner()
}

/// One row of a continuation: the equilibrium the robot is on, and whether it got there
/// by a jump from the row before.
#[derive(Clone, Copy, Debug)]
pub struct Followed {
    /// The equilibrium.
    pub eq: Equilibrium,
    /// The robot snapped between the row before and this one.
    pub jumped: bool,
    /// Where the branch ended, as a fraction of the step from the row before (within
    /// one substep).
    pub fold: Option<f64>,
}

/// The branch a robot at fixed feeds `s` follows along actuator angles `rows` (rad, one
/// pair a row), starting from the stable equilibrium nearest `x = 0` at the first row.
pub fn follow(params: &[TubeParams<f64>], s: [f64; 2], rows: &[[f64; 2]]) -> Vec<Followed> {
    let robot = TwoTubes::new(params, s);
    let stable = |theta: [f64; 2], roots: Vec<f64>| -> Vec<f64> {
        roots
            .into_iter()
            .filter(|&x| robot.residual(theta, x).1 > 0.0)
            .collect()
    };
    let first = stable(rows[0], robot.roots(rows[0]));
    let mut x = *first
        .iter()
        .min_by(|a, b| a.abs().total_cmp(&b.abs()))
        .expect("a stable equilibrium at the first row");
    let mut out = vec![Followed {
        eq: robot.equilibrium(rows[0], x),
        jumped: false,
        fold: None,
    }];
    for w in rows.windows(2) {
        let mut jumped = false;
        let mut fold = None;
        for k in 1..=SUBSTEPS {
            let f = k as f64 / SUBSTEPS as f64;
            let theta = [
                w[0][0] + f * (w[1][0] - w[0][0]),
                w[0][1] + f * (w[1][1] - w[0][1]),
            ];
            let next = robot.newton(theta, x).filter(|&n| {
                robot.residual(theta, n).1 > 0.0
                    && (n - x).abs() < 0.1 * (robot.coupling().abs().sqrt() + 1e-9)
            });
            x = match next {
                Some(n) => n,
                None => {
                    // the branch ended: the robot jumps to the other stable equilibrium
                    jumped = true;
                    fold = Some((k as f64 - 0.5) / SUBSTEPS as f64);
                    let candidates = stable(theta, robot.roots(theta));
                    *candidates
                        .iter()
                        .min_by(|a, b| (*a - x).abs().total_cmp(&(*b - x).abs()))
                        .expect("a stable equilibrium after a jump")
                }
            };
        }
        out.push(Followed {
            eq: robot.equilibrium(w[1], x),
            jumped,
            fold,
        });
    }
    out
}

/// One classical Runge-Kutta step of `y' = rhs(y)` over `h`.
fn rk4(y: [f64; 4], h: f64, rhs: impl Fn([f64; 4]) -> [f64; 4]) -> [f64; 4] {
    let add = |y: [f64; 4], k: [f64; 4], w: f64| -> [f64; 4] {
        core::array::from_fn(|j| y[j] + w * k[j])
    };
    let k1 = rhs(y);
    let k2 = rhs(add(y, k1, 0.5 * h));
    let k3 = rhs(add(y, k2, 0.5 * h));
    let k4 = rhs(add(y, k3, h));
    core::array::from_fn(|j| y[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]))
}
