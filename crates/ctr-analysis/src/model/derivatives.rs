//! The derivatives of a row's tip: the core's analytic Jacobians in the joints and in the
//! tubes' stiffness and curvature scales: the joints' asked in the solve
//! ([`RowSolver::fk_jacobian`]), or either at a solution kept from a run's chain of
//! solves ([`RowSolver::fk_kept`], [`RowSolver::derivatives_at`]).

use super::{Kept, RowSolver};
use ctr_core::SolveError;
use ctr_formats::FkResult;

impl RowSolver<'_> {
    /// [`fk_actual`](Self::fk_actual) of a row without a tip force, with the joint
    /// Jacobian of the tip as measured in `columns`: `2 n` columns in file order and
    /// units (per mm, per degree), entries 0..3 `d position`, 3..6 the tip frame's
    /// angular velocity in the measuring frame. The core's analytic Jacobian
    /// ([`SolveError::Unsupported`] under gravity, where it has none); no margin.
    ///
    /// ```
    /// use ctr_analysis::model::ModelSpec;
    /// use ctr_formats::AnyRobot;
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33); // straight
    /// let rows = ModelSpec::plain(&AnyRobot::new(&[t]).unwrap(), ctr_core::Model::Torsion).rows()?;
    /// let mut columns = Vec::new();
    /// let tip = rows.solver().fk_jacobian(&[50.0, 30.0], &mut columns)?;
    /// assert!((tip.position[2] - 50.0).abs() < 1e-12);
    /// assert!((columns[0][2] - 1.0).abs() < 1e-9); // feeding moves the tip along z
    /// assert!((columns[1][5] - 1f64.to_radians()).abs() < 1e-12); // turning spins it
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Panics
    /// If `actual.len() != 2 * n_tubes`.
    pub fn fk_jacobian(
        &mut self,
        actual: &[f64],
        columns: &mut Vec<[f64; 6]>,
    ) -> Result<FkResult, SolveError> {
        self.bound.fk_jacobian(actual, columns)
    }

    /// [`fk_actual`](Self::fk_actual) without a stability margin, with the core's
    /// solution kept ([`Kept`]) for [`derivatives_at`](Self::derivatives_at): a run's
    /// rows solved in order, warm, then differentiated on any thread.
    ///
    /// ```
    /// use ctr_analysis::model::ModelSpec;
    /// use ctr_formats::AnyRobot;
    /// let t = ctr_core::TubeParams { curvature_radius_mm: Some(100.0), ..ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
    /// let rows = ModelSpec::plain(&AnyRobot::new(&[t]).unwrap(), ctr_core::Model::Torsion).rows()?;
    /// let (_, kept) = rows.solver().fk_kept(&[50.0, 10.0], [0.0; 3])?;
    /// let (mut later, mut within) = (Vec::new(), Vec::new());
    /// rows.solver().derivatives_at(&[50.0, 10.0], &kept, Some(&mut later), None)?;
    /// rows.solver().fk_jacobian(&[50.0, 10.0], &mut within)?;
    /// assert_eq!(later, within);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Panics
    /// If `actual.len() != 2 * n_tubes`.
    pub fn fk_kept(
        &mut self,
        actual: &[f64],
        force_n: [f64; 3],
    ) -> Result<(FkResult, Kept), SolveError> {
        self.bound.fk_kept(actual, force_n)
    }

    /// The joint columns (into `joints`, as [`fk_jacobian`](Self::fk_jacobian)'s) and
    /// the scale columns (into `scales`: `2 n` columns, first per tube the stiffness
    /// scale's, E I and G J together, the `stiffness` effect's factor relative to the
    /// one solved at; then per tube the curvature scale's, the precurvature `k_i`
    /// relative to the one solved at, whose reciprocal is the `precurvature` effect's
    /// radius factor; entries as the joint columns') asked for, at `kept`, the row
    /// `actual` as [`fk_kept`](Self::fk_kept) solved it without a tip force (by any
    /// solver of this model: nothing is solved again). Not with a sensor offset, under a
    /// load or boundary friction moments ([`SolveError::Unsupported`]).
    ///
    /// # Panics
    /// If `actual.len() != 2 * n_tubes`, or `kept` is of another tube count.
    pub fn derivatives_at(
        &self,
        actual: &[f64],
        kept: &Kept,
        joints: Option<&mut Vec<[f64; 6]>>,
        scales: Option<&mut Vec<[f64; 6]>>,
    ) -> Result<(), SolveError> {
        self.bound.derivatives_at(actual, kept, joints, scales)
    }
}
