//! The work of `Robot`'s calls, run with the GIL released: each checks its rows as
//! `ctr-cli` checks a file, then calls the std layer (the row model's batch, its
//! backbone, the IK's Jacobian, the IK's batch) exactly as the CLI does, and returns
//! plain vectors for the numpy arrays.

use super::{cli_ik_options, model_kind, Robot};
use crate::arrays::Rows;
use crate::errors::{self, Fail};
use ctr_analysis::batch::{batch_fk, batch_ik, BatchOptions, IkBatchOptions};
use ctr_analysis::ik::{IkOptions, IkResult};
use ctr_analysis::model::{JacobianError, RowModel};
use ctr_core::{Model, Status};
use ctr_formats::parallel::map_rows;
use ctr_formats::{status_name, Error, ErrorKind, IkTarget, Location};

/// Rows a worker of the per-row maps (Jacobians, independent IK targets) takes at a time.
const MAP_BLOCK_ROWS: usize = 4;

/// The tips of a batch, flattened row after row.
pub(super) struct Tips {
    pub positions: Vec<f64>,
    pub quaternions: Vec<f64>,
    /// per row with `mark`, else empty
    pub statuses: Vec<&'static str>,
    /// per row with `mark`, else empty, rad/mm
    pub residuals: Vec<f64>,
    /// per row: the stability margin
    pub margins: Vec<f64>,
}

/// The IK's answers, flattened row after row.
pub(super) struct Inverse {
    /// joints in file units, `2 n` a row
    pub q: Vec<f64>,
    pub residuals: Vec<f64>,
    pub statuses: Vec<&'static str>,
}

/// The failure `ctr-cli fk --on-error fail` reports: the first failed row, and counts.
pub(super) fn solver_failed(
    location: Location,
    status: Status,
    residual_per_mm: f64,
    failed: usize,
    rows: usize,
) -> Error {
    Error::new(
        location,
        ErrorKind::SolverFailed {
            status,
            residual_per_mm,
            failed,
            rows,
        },
    )
}

impl Robot {
    /// The tips of `rows` under the row model `fkm` ([`batch_fk`], as `ctr-cli fk`
    /// solves a joint file); `mark` keeps rows that did not converge with their status,
    /// else the first such row is the error; `margins` computes each row's stability
    /// margin (else NaN).
    pub(super) fn tips(
        &self,
        fkm: &RowModel,
        rows: &Rows,
        times: Option<&[f64]>,
        threads: usize,
        mark: bool,
        margins: bool,
    ) -> Result<Tips, Error> {
        self.check_joints(rows, "q")?;
        let options = BatchOptions {
            threads,
            margins,
            ..BatchOptions::default()
        };
        let results = batch_fk(fkm, &rows.data, times, &options, &())
            .map_err(|e| Error::new(Location::file("t_s"), model_kind(e)))?;
        let m = rows.rows;
        let mut out = Tips {
            positions: Vec::with_capacity(3 * m),
            quaternions: Vec::with_capacity(4 * m),
            statuses: Vec::with_capacity(if mark { m } else { 0 }),
            residuals: Vec::with_capacity(if mark { m } else { 0 }),
            margins: Vec::with_capacity(m),
        };
        let mut failed = 0;
        let mut first_failure = None;
        for (i, r) in results.into_iter().enumerate() {
            let at = || errors::at("q", i, rows.batched);
            let fk = r.map_err(|e| Error::new(at(), fkm.row_error(e)))?;
            if fk.status != Status::Converged {
                failed += 1;
                first_failure.get_or_insert((at(), fk.status, fk.residual_per_mm));
            }
            out.positions.extend_from_slice(&fk.position);
            out.quaternions.extend_from_slice(&fk.quaternion);
            out.margins.push(fk.stability_margin);
            if mark {
                out.statuses.push(status_name(fk.status));
                out.residuals.push(fk.residual_per_mm);
            }
        }
        if let (false, Some((at, status, residual))) = (mark, first_failure) {
            return Err(solver_failed(at, status, residual, failed, m));
        }
        Ok(out)
    }

    /// The backbone of the single joint row `rows` under the row model `fkm` (no time
    /// effects), x, y, z a point, in the measuring frame.
    pub(super) fn backbone_points(&self, fkm: &RowModel, rows: &Rows) -> Result<Vec<f64>, Error> {
        self.check_joints(rows, "q")?;
        let (tip, points) = fkm
            .solver()
            .backbone(rows.row(0))
            .map_err(|e| Error::new(Location::file("q"), fkm.row_error(e)))?;
        if tip.status != Status::Converged {
            return Err(solver_failed(
                Location::file("q"),
                tip.status,
                tip.residual_per_mm,
                1,
                1,
            ));
        }
        Ok(points.into_iter().flatten().collect())
    }

    /// The tip Jacobians of `rows` under the row model `fkm` (per file unit,
    /// [`RowModel::tip_jacobian`]), each row-major 6 x `2 n`.
    pub(super) fn jacobians(
        &self,
        fkm: &RowModel,
        rows: &Rows,
        threads: usize,
    ) -> Result<Vec<f64>, Fail> {
        self.check_joints(rows, "q")?;
        let jacobians = map_rows(
            rows.rows,
            MAP_BLOCK_ROWS,
            threads,
            || (),
            |(), i| fkm.tip_jacobian(rows.row(i)),
        );
        let mut data = Vec::with_capacity(rows.rows * 6 * self.n_joints());
        for (i, j) in jacobians.into_iter().enumerate() {
            let j = j.map_err(|e| match e {
                JacobianError::TimeEffect { .. } => Fail::Input(format!("{}: {e}", self.source)),
                JacobianError::NoSolution => {
                    Fail::Solver(format!("{}: {e}", errors::at("q", i, rows.batched)))
                }
            })?;
            for r in 0..6 {
                data.extend(j.iter().map(|column| column[r]));
            }
        }
        Ok(data)
    }

    /// Inverse kinematics of `targets` (rows of 3 or 7): without `q0` as `ctr-cli ik`
    /// solves a target file (warm along the rows in chunks of `chunk_rows`, 0 = one
    /// chunk, or `cold`); from one start `q0` a single trajectory in order; with one
    /// start per target (`cold`) each target on its own.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn inverse(
        &self,
        model: Model,
        options: IkOptions,
        targets: &Rows,
        q0: Option<&Rows>,
        cold: bool,
        chunk_rows: usize,
        threads: usize,
    ) -> Result<Inverse, Fail> {
        let targets: Vec<IkTarget> = Robot::targets(targets)?;
        if let Some(rows) = q0 {
            self.check_joints(rows, "q0")?;
        }
        let built;
        let ik = if options == cli_ik_options() {
            self.solver(model)?
        } else {
            built = self.build_ik(model, options).map_err(Fail::Input)?;
            &built
        };
        let results: Vec<IkResult> = match q0 {
            // the CLI's modes: warm along the rows in chunks, or cold
            None => {
                let batch = IkBatchOptions {
                    threads,
                    chunk_rows: if chunk_rows == 0 {
                        targets.len().max(1)
                    } else {
                        chunk_rows
                    },
                    warm: !cold,
                };
                let mut all = Vec::with_capacity(targets.len());
                batch_ik(ik, &targets, &batch, &(), |_, r| {
                    all.extend(r);
                    true
                });
                all
            }
            // a trajectory from a known start: one chain, in order
            Some(start) if !cold => ik
                .clone()
                .solve_trajectory(&targets, Some(&ik.from_file_units(start.row(0)))),
            // independent targets, each from its start
            Some(start) => {
                let starts: Vec<Vec<f64>> = (0..start.rows)
                    .map(|i| ik.from_file_units(start.row(i)))
                    .collect();
                map_rows(
                    targets.len(),
                    MAP_BLOCK_ROWS,
                    threads,
                    || ik.clone(),
                    |ik, i| ik.solve(&targets[i], Some(&starts[i.min(starts.len() - 1)])),
                )
            }
        };
        let mut out = Inverse {
            q: Vec::with_capacity(self.n_joints() * results.len()),
            residuals: Vec::with_capacity(results.len()),
            statuses: Vec::with_capacity(results.len()),
        };
        for r in &results {
            out.q.extend(ik.to_file_units(&r.q));
            out.residuals.push(r.residual_mm);
            out.statuses.push(r.status.name());
        }
        Ok(out)
    }
}
