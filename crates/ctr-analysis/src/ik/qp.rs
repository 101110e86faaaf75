//! The Levenberg-Marquardt step as a small convex QP:
//!
//! ```text
//! minimize   1/2 dq^T H dq - g^T dq
//! subject to lo <= a_r . (q + dq) <= hi   for every limit row r
//!            a_m . dq <= b_m                  the linearised stability margin (optional)
//! ```
//!
//! solved with clarabel. One solver is built on the first constrained step and then
//! reused (presolve off; `update_P`, `update_q`, `update_b`; the constraint matrix
//! changes only in the margin's row, `update_A`, its sparsity never), which costs about 20 us a step instead of about 30 us and a hundred
//! allocations for a fresh one. The caller tries the unconstrained minimizer first
//! (`H dq = g`) and only comes here when it leaves the limits: when it stays inside,
//! it is the QP's solution.

use crate::limits::{JointLimits, Row};
use crate::model::MAX_JOINTS;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::{SMatrix, SVector};

/// Which side of a row a constraint of the QP is.
#[derive(Clone, Copy, Debug)]
enum Side {
    /// `a . dq = lo - a . q`
    Equal,
    /// `a . dq <= hi - a . q`
    Upper,
    /// `-a . dq <= a . q - lo`
    Lower,
}

pub(crate) struct StepQp {
    n: usize,
    rows: Vec<Row>,
    /// QP constraints in order (equalities first): row index and side
    cons: Vec<(usize, Side)>,
    n_eq: usize,
    a: CscMatrix<f64>,
    /// with a margin row (the last row): where its entry of each column sits in
    /// `a.nzval`
    margin_entries: Option<Vec<usize>>,
    solver: Option<DefaultSolver<f64>>,
    p_values: Vec<f64>,
    q_values: Vec<f64>,
    b_values: Vec<f64>,
    /// QPs solved (statistics)
    pub solves: u64,
}

impl std::fmt::Debug for StepQp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StepQp")
            .field("n", &self.n)
            .field("constraints", &self.cons.len())
            .field("solves", &self.solves)
            .finish()
    }
}

impl Clone for StepQp {
    /// A copy with the same problem and no solver yet (built on first use).
    fn clone(&self) -> Self {
        StepQp {
            n: self.n,
            rows: self.rows.clone(),
            cons: self.cons.clone(),
            n_eq: self.n_eq,
            a: self.a.clone(),
            margin_entries: self.margin_entries.clone(),
            solver: None,
            p_values: self.p_values.clone(),
            q_values: self.q_values.clone(),
            b_values: self.b_values.clone(),
            solves: 0,
        }
    }
}

impl StepQp {
    /// The QP of `limits`, with a last row for the margin when `margin_row`.
    pub fn new(limits: &JointLimits, margin_row: bool) -> Self {
        let n = 2 * limits.n_tubes();
        let rows = limits.rows();
        let mut cons = Vec::new();
        for (r, row) in rows.iter().enumerate() {
            if row.lo == row.hi {
                cons.push((r, Side::Equal));
            }
        }
        let n_eq = cons.len();
        for (r, row) in rows.iter().enumerate() {
            if row.lo == row.hi {
                continue;
            }
            if row.hi.is_finite() {
                cons.push((r, Side::Upper));
            }
            if row.lo.is_finite() {
                cons.push((r, Side::Lower));
            }
        }
        let (mut ri, mut ci, mut v) = (Vec::new(), Vec::new(), Vec::new());
        for (k, &(r, side)) in cons.iter().enumerate() {
            let sign = if let Side::Lower = side { -1.0 } else { 1.0 };
            for &(j, a) in &rows[r].terms {
                ri.push(k);
                ci.push(j);
                v.push(sign * a);
            }
        }
        let n_rows = cons.len() + usize::from(margin_row);
        if margin_row {
            // a structural entry in every column (its values change each step)
            for j in 0..n {
                ri.push(cons.len());
                ci.push(j);
                v.push(1.0);
            }
        }
        let a = CscMatrix::new_from_triplets(n_rows, n, ri, ci, v);
        // the margin row is the last row: the last entry of each column
        let margin_entries = margin_row.then(|| (0..n).map(|j| a.colptr[j + 1] - 1).collect());
        StepQp {
            n,
            rows,
            n_eq,
            b_values: vec![0.0; n_rows],
            cons,
            a,
            margin_entries,
            solver: None,
            p_values: vec![0.0; n * (n + 1) / 2],
            q_values: vec![0.0; n],
            solves: 0,
        }
    }

    /// The constrained step from `q` (the leading `2 n` block of `h` and `g`), with the
    /// margin's row `a . dq <= b` when the QP has one (`margin`; ignored otherwise, and
    /// `0 <= 0` when missing), or `None` if clarabel does not solve it (also when the
    /// margin's row cannot be met within the limits).
    pub fn step(
        &mut self,
        h: &SMatrix<f64, MAX_JOINTS, MAX_JOINTS>,
        g: &SVector<f64, MAX_JOINTS>,
        q: &[f64],
        margin: Option<(&SVector<f64, MAX_JOINTS>, f64)>,
    ) -> Option<Vec<f64>> {
        let n = self.n;
        let mut k = 0;
        for j in 0..n {
            for i in 0..=j {
                self.p_values[k] = h[(i, j)];
                k += 1;
            }
            self.q_values[j] = -g[j];
        }
        for (b, &(r, side)) in self.b_values.iter_mut().zip(&self.cons) {
            let row = &self.rows[r];
            let aq = row.value(q);
            *b = match side {
                Side::Equal => row.lo - aq,
                Side::Upper => row.hi - aq,
                Side::Lower => aq - row.lo,
            };
        }
        if let Some(entries) = &self.margin_entries {
            let (row, b) = margin.map_or((None, 0.0), |(a, b)| (Some(a), b));
            for (j, &k) in entries.iter().enumerate() {
                self.a.nzval[k] = row.map_or(0.0, |a| a[j]);
            }
            self.b_values[self.cons.len()] = b;
        }
        self.solves += 1;
        match &mut self.solver {
            Some(s) => {
                s.update_P(&self.p_values).ok()?;
                s.update_q(&self.q_values).ok()?;
                if self.margin_entries.is_some() {
                    s.update_A(&self.a.nzval).ok()?;
                }
                s.update_b(&self.b_values).ok()?;
            }
            None => {
                let colptr = (0..=n).map(|j| j * (j + 1) / 2).collect();
                let rowval = (0..n).flat_map(|j| 0..=j).collect();
                let p = CscMatrix::new(n, n, colptr, rowval, self.p_values.clone());
                let mut cones = Vec::new();
                if self.n_eq > 0 {
                    cones.push(SupportedConeT::ZeroConeT(self.n_eq));
                }
                if self.b_values.len() > self.n_eq {
                    cones.push(SupportedConeT::NonnegativeConeT(
                        self.b_values.len() - self.n_eq,
                    ));
                }
                let settings = DefaultSettingsBuilder::default()
                    .presolve_enable(false)
                    .equilibrate_enable(false)
                    .verbose(false)
                    .build()
                    .ok()?;
                self.solver = Some(
                    DefaultSolver::new(
                        &p,
                        &self.q_values,
                        &self.a,
                        &self.b_values,
                        &cones,
                        settings,
                    )
                    .ok()?,
                );
            }
        }
        let s = self.solver.as_mut()?;
        s.solve();
        match s.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                let x = s.solution.x.clone();
                x.iter().all(|v| v.is_finite()).then_some(x)
            }
            _ => None,
        }
    }
}
