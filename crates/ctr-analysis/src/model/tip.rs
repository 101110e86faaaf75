//! The row model's tip as the inverse kinematics and the tip Jacobian see it.
//!
//! [`TipFk`] hides the tube count: the row model's kernel ([`super::Kernel`]) and the
//! core's `Solver<f64, N>` behind an object that solves joint vectors given as slices
//! (mm, rad), the joint offsets added as the row model adds them (file units). It keeps
//! the core solver's warm-start memory for the current iterate, so that trial points
//! and the finite-difference probes around the iterate start from its converged twist.
//!
//! [`tip_jacobian`] is the only place the tip Jacobian comes from (the IK's steps,
//! `Ik::tip_jacobian`, [`RowModel::tip_jacobian`](super::RowModel::tip_jacobian)). It
//! takes the core's analytic joint Jacobian ([`TipFk::jacobian`]: the kernel's, through
//! the joint offsets, clearance kinks, sensor offset and registration) where the model
//! has one, and otherwise (gravity) central finite differences of the core FK solved to
//! tight tolerances (`residual_tolerance_per_mm` [`FK_RESIDUAL_TOLERANCE`]) with steps
//! [`FD_STEP_MM`] / [`FD_STEP_RAD`], one-sided where a probe would leave the joint limits.

use super::Kernel;
use crate::limits::JointLimits;
use crate::margin::Margins;
use ctr_core::{Frame, JointJacobian, Joints, Solver, SolverConfig, Status};
use ctr_formats::joints_of;
use nalgebra::{Matrix3, Rotation3, SMatrix, UnitQuaternion, Vector3};

/// Most joints (`2 * MAX_TUBES`): the IK's matrices have this size, padded.
pub(crate) const MAX_JOINTS: usize = 2 * ctr_core::MAX_TUBES;
/// The tip Jacobian, padded with zero columns beyond `2 n`.
pub(crate) type Jacobian = SMatrix<f64, 6, MAX_JOINTS>;

/// Free-tip twist residual the IK's FK solves to, rad/mm (the core default is 1e-12).
pub const FK_RESIDUAL_TOLERANCE: f64 = 1e-13;
/// A solve that ends short of [`FK_RESIDUAL_TOLERANCE`] (the iteration bound hit at the
/// rounding floor) is still used when its residual is below this, rad/mm.
pub const FK_ACCEPT_RESIDUAL: f64 = 1e-11;
/// Finite-difference step on feeds, mm.
pub const FD_STEP_MM: f64 = 1e-6;
/// Finite-difference step on rotations, rad.
pub const FD_STEP_RAD: f64 = 1e-6;

/// One solve as the IK uses it: the tip and the stability margin there.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Solved {
    /// The tip frame, as measured.
    pub tip: Frame<f64>,
    /// The stability margin ([`crate::margin`], dimensionless); NaN unless the solver
    /// computes margins ([`TipFk::with_margins`]).
    pub margin: f64,
    /// The margin's gradient over the joint slice `s_1, theta_1, ...`: per mm, per rad
    /// ([`crate::margin::Margin::gradient`]); zero without margins.
    pub margin_gradient: [f64; MAX_JOINTS],
}

/// Tip forward kinematics of one robot on joint slices `s_1, theta_1, ...` (mm, rad).
pub(crate) trait TipFk: Send + Sync {
    /// The number of tubes.
    fn n_tubes(&self) -> usize;
    /// Forgets all warm-start memory.
    fn reset(&mut self);
    /// Solves `q` warm-started from the current iterate and keeps the result as the
    /// pending trial; `None` when the solve does not converge.
    fn trial(&mut self, q: &[f64]) -> Option<Solved>;
    /// Makes the pending trial the current iterate.
    fn accept(&mut self);
    /// Solves `q` warm-started from the current iterate without remembering it.
    fn probe(&self, q: &[f64]) -> Option<Solved>;
    /// Solves `q` cold.
    fn cold(&self, q: &[f64]) -> Option<Solved>;
    /// A copy with the same warm-start memory.
    fn boxed_clone(&self) -> Box<dyn TipFk>;
    /// The analytic tip Jacobian at `q` (the current iterate), written into the first
    /// `2 n` columns of `jac` as [`tip_jacobian`] lays them out; `false` (and `jac`
    /// untouched) where the model has none.
    fn jacobian(&self, q: &[f64], jac: &mut Jacobian) -> bool;
    /// From now on every solve computes its stability margin ([`Kernel::margin`]);
    /// before, [`Solved::margin`] is NaN (the probes cost solves the IK needs only with
    /// a margin floor).
    fn with_margins(&mut self);
    /// The stability margin at `q` ([`Kernel::margin`]), solved warm from the current
    /// iterate whether or not every solve computes it; NaN where the solve fails.
    fn margin(&self, q: &[f64]) -> f64;
}

/// [`TipFk`] on the row model's mechanics ([`crate::model`]): the robot file's static
/// effects (the robot already scaled; clearance kinks, sensor offset and registration,
/// gravity) through the one row kernel, and the joint offsets added in file units as
/// `ctr-cli fk` adds them. The tip is in the measuring frame, where the targets are.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CoreFk<const N: usize> {
    kernel: Kernel<N>,
    /// joint offsets, file order and units (mm, degrees); `None` when all are zero
    offsets: Option<[f64; MAX_JOINTS]>,
    current: Solver<f64, N>,
    pending: Solver<f64, N>,
    /// solves compute their stability margin ([`TipFk::with_margins`])
    margins: bool,
}

impl<const N: usize> CoreFk<N> {
    /// `kernel`'s tips, with the joint offsets `offsets` (file order and units).
    pub fn new(kernel: Kernel<N>, offsets: &[f64]) -> Self {
        let s = Solver::new(SolverConfig {
            residual_tolerance_per_mm: FK_RESIDUAL_TOLERANCE,
            ..SolverConfig::default()
        });
        let shifted = offsets.iter().any(|&o| o != 0.0);
        CoreFk {
            kernel,
            offsets: shifted
                .then(|| core::array::from_fn(|i| offsets.get(i).copied().unwrap_or(0.0))),
            current: s,
            pending: s,
            margins: false,
        }
    }

    /// The actual joints of the commanded `q` (mm, rad): plus the joint offsets, added
    /// in file units.
    fn actual(&self, q: &[f64]) -> Joints<f64, N> {
        match &self.offsets {
            None => Self::joints(q),
            Some(o) => {
                let file: [f64; MAX_JOINTS] = core::array::from_fn(|i| match q.get(i) {
                    Some(v) if i % 2 == 1 => v.to_degrees() + o[i],
                    Some(v) => v + o[i],
                    None => 0.0,
                });
                joints_of::<N>(&file[..2 * N])
            }
        }
    }

    fn solve_once(
        &self,
        solver: &mut Solver<f64, N>,
        q: &[f64],
    ) -> Option<ctr_core::Solution<f64, N>> {
        self.kernel.solve(solver, self.actual(q), [0.0; 3]).ok()
    }

    /// The joint slice `s_1, theta_1, ...` (mm, rad) as the core's joints.
    fn joints(q: &[f64]) -> Joints<f64, N> {
        Joints::new(
            core::array::from_fn(|i| q[2 * i]),
            core::array::from_fn(|i| q[2 * i + 1]),
        )
    }

    /// Whether a solve is good enough for the IK: converged (or at the rounding floor
    /// below [`FK_ACCEPT_RESIDUAL`]) with a finite tip.
    fn accepted(sol: &ctr_core::Solution<f64, N>) -> bool {
        (sol.status == Status::Converged || sol.residual_per_mm <= FK_ACCEPT_RESIDUAL)
            && sol.tip.position.iter().all(|v| v.is_finite())
    }

    /// The tip at `q`, and its stability margin ([`Kernel::margin`]) when `margins`.
    fn solve(&self, solver: &mut Solver<f64, N>, q: &[f64]) -> Option<Solved> {
        let ok = Self::accepted;
        let mut sol = self.solve_once(solver, q)?;
        if !ok(&sol) {
            // a warm start from far away can fail where a cold one does not
            solver.reset();
            sol = self.solve_once(solver, q)?;
            if !ok(&sol) {
                return None;
            }
        }
        let mut out = Solved {
            tip: sol.tip,
            margin: f64::NAN,
            margin_gradient: [0.0; MAX_JOINTS],
        };
        if self.margins {
            let m = self
                .kernel
                .margin(solver, self.actual(q), [0.0; 3], &sol, Margins::Exact);
            out.margin = m.value;
            // the kernel's order s_1..s_n, theta_1..theta_n per degree; the slice's is
            // interleaved per rad (the offsets are constant: the same gradient)
            for i in 0..N {
                out.margin_gradient[2 * i] = m.gradient[i];
                out.margin_gradient[2 * i + 1] = m.gradient[N + i].to_degrees();
            }
        }
        Some(out)
    }
}

impl<const N: usize> TipFk for CoreFk<N> {
    fn n_tubes(&self) -> usize {
        N
    }

    fn reset(&mut self) {
        self.current.reset();
        self.pending.reset();
    }

    fn trial(&mut self, q: &[f64]) -> Option<Solved> {
        let mut s = self.current;
        let tip = self.solve(&mut s, q);
        self.pending = s;
        tip
    }

    fn accept(&mut self) {
        self.current = self.pending;
    }

    fn probe(&self, q: &[f64]) -> Option<Solved> {
        let mut s = self.current;
        self.solve(&mut s, q)
    }

    fn cold(&self, q: &[f64]) -> Option<Solved> {
        let mut s = self.current;
        s.reset();
        self.solve(&mut s, q)
    }

    fn boxed_clone(&self) -> Box<dyn TipFk> {
        Box::new(*self)
    }

    fn with_margins(&mut self) {
        self.margins = true;
    }

    fn margin(&self, q: &[f64]) -> f64 {
        let mut s = self.current;
        let with = CoreFk {
            margins: true,
            ..*self
        };
        with.solve(&mut s, q).map_or(f64::NAN, |s| s.margin)
    }

    fn jacobian(&self, q: &[f64], jac: &mut Jacobian) -> bool {
        if q.len() != 2 * N {
            return false;
        }
        let mut s = self.current;
        let mut analytic = JointJacobian::nan();
        // the derivative with respect to the commanded joints is that with respect to
        // the actual ones: the offsets are constant (under gravity the core has none)
        let Ok(sol) = self.kernel.jacobian(&mut s, self.actual(q), &mut analytic) else {
            return false;
        };
        let finite = analytic
            .feed
            .iter()
            .chain(&analytic.rotation)
            .all(|c| c.iter().all(|v| v.is_finite()));
        if !(Self::accepted(&sol) && finite) {
            return false;
        }
        for i in 0..N {
            jac.set_column(2 * i, &analytic.feed[i]);
            jac.set_column(2 * i + 1, &analytic.rotation[i]);
        }
        true
    }
}

/// The rotation vector (axis times angle, angle in `[0, pi]`) of the rotation matrix
/// `r`, through its quaternion (Shepperd's method: no `acos`, so accurate for tiny
/// angles and safe for matrices a few ulps off orthogonal).
pub(crate) fn log_so3(r: &Matrix3<f64>) -> Vector3<f64> {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r));
    let (w, v) = if q.w < 0.0 {
        (-q.w, -q.imag())
    } else {
        (q.w, q.imag())
    };
    let s = v.norm();
    if s == 0.0 {
        return Vector3::zeros();
    }
    v * (2.0 * s.atan2(w) / s)
}

/// The tip Jacobian at `q` (whose tip is `tip`, and which is the current iterate of
/// `fk`): rows 0..3 `d position / d q` (mm per mm or per rad), rows 3..6 the tip's
/// angular velocity in W per unit joint rate. Written into the first `2 n` columns of `jac`.
///
/// The core's analytic Jacobian where [`TipFk::jacobian`] has one, else central
/// differences (see the module docs) whose probes stay inside `limits`: a joint at a
/// bound gets a one-sided difference. Either way a joint pinned between two bounds (no
/// step of [`FD_STEP_MM`] / [`FD_STEP_RAD`] possible either way) gets a zero column.
pub(crate) fn tip_jacobian(
    fk: &dyn TipFk,
    limits: &JointLimits,
    q: &[f64],
    tip: &Frame<f64>,
    jac: &mut Jacobian,
) {
    let n = q.len();
    if fk.jacobian(q, jac) {
        let mut probe_q = q.to_vec();
        for j in 0..n {
            let h = if j % 2 == 0 { FD_STEP_MM } else { FD_STEP_RAD };
            let mut admits = |delta: f64| {
                probe_q.copy_from_slice(q);
                probe_q[j] += delta;
                limits.admits(&probe_q)
            };
            if !admits(h) && !admits(-h) {
                jac.column_mut(j).fill(0.0);
            }
        }
        return;
    }
    let mut probe_q = q.to_vec();
    let mut probe = |j: usize, delta: f64| -> Option<Frame<f64>> {
        probe_q.copy_from_slice(q);
        probe_q[j] += delta;
        if !limits.admits(&probe_q) {
            return None;
        }
        fk.probe(&probe_q).map(|s| s.tip)
    };
    for j in 0..n {
        let h = if j % 2 == 0 { FD_STEP_MM } else { FD_STEP_RAD };
        let plus = probe(j, h);
        let minus = probe(j, -h);
        let (a, b, width) = match (&plus, &minus) {
            (Some(p), Some(m)) => (p, m, 2.0 * h),
            (Some(p), None) => (p, tip, h),
            (None, Some(m)) => (tip, m, h),
            (None, None) => {
                jac.column_mut(j).fill(0.0);
                continue;
            }
        };
        let dp = (a.position - b.position) / width;
        let dw = log_so3(&(a.rotation * b.rotation.transpose())) / width;
        jac.fixed_view_mut::<3, 1>(0, j).copy_from(&dp);
        jac.fixed_view_mut::<3, 1>(3, j).copy_from(&dw);
    }
}

/// The tip Jacobian at `joints` (file units: `s_1` mm, `theta_1` degrees, ...) with
/// probes kept inside `limits`, at the FK solved cold (`fk`'s memory is cleared first):
/// one column per joint, in joint order; in each, entries 0..3 `d position / d joint`
/// (mm per mm, mm per degree), entries 3..6 the tip's angular velocity in W (rad per
/// mm, rad per degree). `None` when the FK does not converge at `joints`.
pub(crate) fn file_jacobian(
    fk: &mut dyn TipFk,
    limits: &JointLimits,
    joints: &[f64],
) -> Option<Vec<[f64; 6]>> {
    let q = limits.from_file_units(joints);
    fk.reset();
    let tip = fk.trial(&q)?.tip;
    fk.accept();
    let mut jac = Jacobian::zeros();
    tip_jacobian(&*fk, limits, &q, &tip, &mut jac);
    let per_degree = 1f64.to_radians();
    Some(
        (0..q.len())
            .map(|c| {
                let unit = if c % 2 == 1 { per_degree } else { 1.0 };
                core::array::from_fn(|r| jac[(r, c)] * unit)
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tip without its analytic Jacobian: `tip_jacobian` falls back to differences.
    struct DifferencesOnly(Box<dyn TipFk>);

    impl TipFk for DifferencesOnly {
        fn n_tubes(&self) -> usize {
            self.0.n_tubes()
        }
        fn reset(&mut self) {
            self.0.reset()
        }
        fn trial(&mut self, q: &[f64]) -> Option<Solved> {
            self.0.trial(q)
        }
        fn accept(&mut self) {
            self.0.accept()
        }
        fn probe(&self, q: &[f64]) -> Option<Solved> {
            self.0.probe(q)
        }
        fn cold(&self, q: &[f64]) -> Option<Solved> {
            self.0.cold(q)
        }
        fn boxed_clone(&self) -> Box<dyn TipFk> {
            Box::new(DifferencesOnly(self.0.boxed_clone()))
        }
        fn jacobian(&self, _: &[f64], _: &mut Jacobian) -> bool {
            false
        }
        fn with_margins(&mut self) {
            self.0.with_margins()
        }
        fn margin(&self, q: &[f64]) -> f64 {
            self.0.margin(q)
        }
    }

    /// The analytic path of `tip_jacobian` (interleaved columns, effects chained)
    /// equals its finite differences, with and without static effects; a joint pinned
    /// by its limits gets a zero column on both paths.
    #[test]
    fn analytic_tip_jacobian_equals_the_differences() {
        use crate::model::ModelSpec;
        use ctr_core::{Model, TubeParams};
        use ctr_formats::{AnyRobot, Registration};
        let t = |od, id, len, cl, r| TubeParams {
            curvature_radius_mm: Some(r),
            ..TubeParams::<f64>::new(od, id, len, cl, 58000.0, 0.33)
        };
        let robot = AnyRobot::new(&[
            t(1.9, 1.6, 160.0, 80.0, 300.0),
            t(1.4, 1.1, 220.0, 70.0, 180.0),
            t(0.9, 0.6, 280.0, 50.0, 80.0),
        ])
        .unwrap();
        // file units: mm and degrees
        let mut shifted = ModelSpec::plain(&robot, Model::Torsion).effects;
        shifted.joint_offset = Some(ctr_formats::JointOffset {
            feed_mm: vec![0.5, -0.3, 0.2],
            rotation_deg: vec![1.1, -2.3, 1.7],
        });
        shifted.registration = Some(Registration {
            translation_mm: [3.0, -1.0, 7.0],
            rotation_axis: [1.0, 2.0, -0.5],
            rotation_deg: 23.0,
        });
        shifted.sensor_offset = Some(ctr_formats::SensorOffset {
            offset_mm: [0.8, 0.0, 3.0],
        });
        let core_fk = |e: &ctr_formats::Effects, model| {
            let spec = ModelSpec {
                robot,
                model,
                effects: e.clone(),
                empirical: None,
                discrepancy: None,
            };
            spec.rows().unwrap().tip_fk()
        };
        let q = [30.0, 0.2, 60.0, 1.7, 95.0, -1.0];
        let limits = JointLimits::new(&[160.0, 220.0, 280.0], None).unwrap();
        // the first feed pinned at 30 mm
        let pinned = JointLimits::new(
            &[160.0, 220.0, 280.0],
            Some(&[
                ctr_formats::TubeLimits {
                    s_mm: Some([30.0, 30.0]),
                    ..Default::default()
                },
                Default::default(),
                Default::default(),
            ]),
        )
        .unwrap();
        for e in [ctr_formats::Effects::default(), shifted] {
            for model in [Model::Torsion, Model::Rigid] {
                for lim in [&limits, &pinned] {
                    let mut analytic = core_fk(&e, model);
                    let mut fd = DifferencesOnly(analytic.boxed_clone());
                    let tip = analytic.trial(&q).unwrap().tip;
                    analytic.accept();
                    fd.trial(&q).unwrap();
                    fd.accept();
                    let (mut ja, mut jf) = (Jacobian::zeros(), Jacobian::zeros());
                    assert!(analytic.jacobian(&q, &mut Jacobian::zeros()));
                    tip_jacobian(&*analytic, lim, &q, &tip, &mut ja);
                    tip_jacobian(&fd, lim, &q, &tip, &mut jf);
                    for c in 0..6 {
                        let (a, f) = (ja.column(c), jf.column(c));
                        let err = (a - f).norm() / f.norm().max(1e-9);
                        assert!(err < 1e-6, "{model:?} column {c}: {err:e}\n{a}\n{f}");
                    }
                    if std::ptr::eq(lim, &pinned) {
                        assert_eq!(ja.column(0).norm(), 0.0);
                    }
                }
            }
        }
    }

    #[test]
    fn log_so3_inverts_the_exponential() {
        for v in [
            Vector3::new(1e-9, -2e-9, 3e-10),
            Vector3::new(0.3, -0.2, 0.9),
            Vector3::new(0.0, 3.1, 0.0),
            Vector3::zeros(),
        ] {
            let r = Rotation3::from_scaled_axis(v).into_inner();
            let back = log_so3(&r);
            assert!(
                (back - v).norm() <= 1e-15 + 1e-13 * v.norm(),
                "{v} -> {back}"
            );
        }
    }
}
