//! The split of the rows into fit and held-out parts: contiguous blocks of every run, or
//! whole runs by label, never random rows (neighbouring samples share their errors). A
//! static configuration set (`ctr_formats::poses`) is split by poses, a pose's frames
//! together: its neighbouring rows are other configurations.

use crate::error::DiagnoseError;
use ctr_formats::Recording;

/// Fewest rows in a block of the split.
const MIN_BLOCK_ROWS: usize = 10;
/// Blocks per run (at most) in the split.
const BLOCKS_PER_RUN: usize = 8;

/// How the rows are split into fit and held-out parts.
#[derive(Clone, Debug, PartialEq)]
pub enum Holdout {
    /// Each run in contiguous blocks (up to 8, at least 10 rows each); every `every`-th
    /// block is held out, staggered from run to run. Runs too short for two blocks are
    /// fitted whole; where every run is, one run in `every` is held out whole (the last
    /// when there are fewer). A static set: one pose in `every` (in file order, its
    /// frames together), whatever its runs' lengths.
    Blocks {
        /// one block in `every` is held out (>= 2)
        every: usize,
    },
    /// These runs (labels) are held out whole.
    Runs(Vec<String>),
}

impl std::str::FromStr for Holdout {
    type Err = String;

    /// `blocks:K` (K >= 2) or `runs:LABEL[,LABEL...]`, as `--holdout` takes it.
    ///
    /// ```
    /// use ctr_diagnosis::Holdout;
    /// assert_eq!("blocks:3".parse(), Ok(Holdout::Blocks { every: 3 }));
    /// assert_eq!("runs: a ,b".parse(), Ok(Holdout::Runs(vec!["a".into(), "b".into()])));
    /// assert!("blocks:1".parse::<Holdout>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self, String> {
        let want = "wanted blocks:K (K >= 2) or runs:LABEL[,LABEL...]";
        match s.split_once(':') {
            Some(("blocks", k)) => match k.parse::<usize>() {
                Ok(every) if every >= 2 => Ok(Holdout::Blocks { every }),
                _ => Err(format!("{s:?}: {want}")),
            },
            Some(("runs", labels)) if !labels.trim().is_empty() => Ok(Holdout::Runs(
                labels.split(',').map(|l| l.trim().to_owned()).collect(),
            )),
            _ => Err(format!("{s:?}: {want}")),
        }
    }
}

impl Default for Holdout {
    fn default() -> Self {
        Holdout::Blocks { every: 4 }
    }
}

/// Holds out one run in `every` of `rec` (the last when there are fewer) in `held`:
/// the default split where no run is long enough for blocks. The split in words.
fn whole_runs(rec: &Recording, every: usize, held: &mut [bool]) -> String {
    let n = rec.runs.len();
    let chosen: Vec<usize> = if n < every {
        vec![n - 1]
    } else {
        (0..n).filter(|i| i % every == every - 1).collect()
    };
    for &i in &chosen {
        held[rec.runs[i].rows.clone()]
            .iter_mut()
            .for_each(|h| *h = true);
    }
    let labels: Vec<&str> = chosen.iter().map(|&i| rec.runs[i].label.as_str()).collect();
    format!(
        "runs {} held out whole: every run is shorter than two blocks of {MIN_BLOCK_ROWS} rows, \
         so one run in {every} (the last when there are fewer) is held out instead of blocks",
        labels.join(", ")
    )
}

/// Which rows are held out.
pub fn split(rec: &Recording, holdout: &Holdout) -> Result<(Vec<bool>, String), DiagnoseError> {
    let mut held = vec![false; rec.rows.len()];
    let method = match holdout {
        Holdout::Blocks { every } if rec.is_static() => {
            let every = (*every).max(2);
            let poses = rec.poses.as_deref().unwrap_or_default();
            for (j, pose) in poses.iter().enumerate() {
                if j % every == every - 1 {
                    held[pose.rows.clone()].iter_mut().for_each(|h| *h = true);
                }
            }
            format!(
                "a static configuration set: one pose in {every} held out (in file order, a \
                 pose's frames together; its neighbouring rows are other configurations, so \
                 not blocks of rows)"
            )
        }
        Holdout::Blocks { every } => {
            let every = (*every).max(2);
            for (i, run) in rec.runs.iter().enumerate() {
                let len = run.rows.len();
                let blocks = (len / MIN_BLOCK_ROWS).min(BLOCKS_PER_RUN);
                if blocks < 2 {
                    continue;
                }
                for b in 0..blocks {
                    if (b + i) % every == every - 1 {
                        let start = run.rows.start + b * len / blocks;
                        let end = run.rows.start + (b + 1) * len / blocks;
                        held[start..end].iter_mut().for_each(|h| *h = true);
                    }
                }
            }
            if !held.contains(&true) && rec.runs.len() >= 2 {
                whole_runs(rec, every, &mut held)
            } else {
                format!(
                    "each run in up to {BLOCKS_PER_RUN} contiguous blocks of at least \
                     {MIN_BLOCK_ROWS} rows; one block in {every} held out, staggered between runs"
                )
            }
        }
        Holdout::Runs(labels) => {
            for l in labels {
                if !rec.runs.iter().any(|r| &r.label == l) {
                    return Err(DiagnoseError::Split(format!(
                        "--holdout: no run labelled {l} in {} (runs: {})",
                        rec.file,
                        rec.runs
                            .iter()
                            .map(|r| r.label.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )));
                }
            }
            for run in &rec.runs {
                if labels.contains(&run.label) {
                    held[run.rows.clone()].iter_mut().for_each(|h| *h = true);
                }
            }
            format!("runs {} held out whole", labels.join(", "))
        }
    };
    let n_held = held.iter().filter(|h| **h).count();
    if n_held == 0 || n_held == held.len() {
        return Err(DiagnoseError::Split(format!(
            "the split ({method}) leaves {} fit rows and {n_held} held-out rows; both must \
             be non-empty (--holdout chooses another)",
            held.len() - n_held,
        )));
    }
    Ok((held, method))
}
