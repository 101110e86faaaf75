//! `ctr-cli diagnose`, `ctr-cli calibrate` and `ctr-cli evaluate`: a robot file and a
//! recording in, the mismatch report, the fitted robot file, plots and the HTML page
//! out. The numerics, the plots and the page are `ctr_diagnosis`'s; this module reads,
//! prints and writes.

use crate::Failure;
use ctr_analysis::margin::DEFAULT_WARN_MARGIN;
use ctr_analysis::model::ModelSpec;
use ctr_diagnosis::{DiagnoseError, Diagnosis, EffectId, Holdout, Marks, Options, Page};
use ctr_formats::{AtomicFile, Recording, RobotSpec, CLEARANCE_FIT_TABLE_SIZES};
use std::path::{Path, PathBuf};

/// Options of `ctr-cli diagnose`.
#[derive(Debug, clap::Args)]
pub struct DiagnoseArgs {
    /// The model to check: a robot file (its [model] kind and [model.effects]).
    #[arg(long, value_name = "ROBOT.toml")]
    pub robot: PathBuf,
    /// The recording: joint columns, x_mm,y_mm,z_mm, optionally t_s and run.
    #[arg(long, value_name = "REC.csv")]
    pub recording: PathBuf,
    /// Write the mismatch report (JSON) here.
    #[arg(long, value_name = "REPORT.json")]
    pub report: Option<PathBuf>,
    /// Write the fitted model here, as a robot file `ctr-cli fk` reads as is.
    #[arg(long = "out", value_name = "FITTED.toml")]
    pub out: Option<PathBuf>,
    /// Also write the report's empirical term (not physics; only when the recording is
    /// not explained) into the fitted file as [model.empirical], which `ctr-cli fk` adds
    /// to the tip.
    #[arg(long, requires = "out")]
    pub with_empirical: bool,
    /// Write only the established findings into the fitted file, refitted on the fit
    /// rows without the predictive ones (which help prediction but whose form the data
    /// do not establish).
    #[arg(long, requires = "out", conflicts_with = "with_empirical")]
    pub established_only: bool,
    /// Write before/after plots (SVG) into this directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Write the report as one self-contained HTML page (verdict, findings with their
    /// intervals, plots, what is left, the next run, the fitted robot file; inline SVG
    /// and CSS, nothing fetched: it opens offline).
    #[arg(long, value_name = "REPORT.html")]
    pub html: Option<PathBuf>,
    /// Write the run the report suggests recording next (when parameters are poorly
    /// identified) as a joint file `ctr-cli hw run` plays: t_s and the joint columns.
    /// Written only when a run is suggested; otherwise a line on stderr says why not.
    #[arg(long, value_name = "RUN.csv")]
    pub suggest_run: Option<PathBuf>,
    /// How rows are held out: `blocks:K` (each run in contiguous blocks, one in K held
    /// out; default blocks:4) or `runs:LABEL,LABEL` (those runs held out whole).
    #[arg(long, value_name = "SPLIT", value_parser = str::parse::<Holdout>)]
    pub holdout: Option<Holdout>,
    /// Only try these effects (comma separated contract ids; default: all ten).
    #[arg(long, value_name = "IDS", value_delimiter = ',', value_parser = parse_effect)]
    pub effects: Option<Vec<EffectId>>,
    /// Worker threads (default: all cores).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// Mark the rows where the user's or the fitted model has a stability margin below
    /// X (within X of a snap; below 0: on an unstable branch) in the report's stability
    /// and the summary: a jump in the data there is physics, not a tracker glitch.
    /// As `fk --warn-margin`; 0 marks only rows on an unstable branch.
    #[arg(long, value_name = "X", default_value_t = DEFAULT_WARN_MARGIN, value_parser = parse_warn_margin)]
    pub warn_margin: f64,
}

/// Options of `ctr-cli calibrate`.
#[derive(Debug, clap::Args)]
pub struct CalibrateArgs {
    /// The model to calibrate: a robot file.
    #[arg(long, value_name = "ROBOT.toml")]
    pub robot: PathBuf,
    /// The recording (with fx_n,fy_n,fz_n for known tip loads, e.g. hung weights).
    #[arg(long, value_name = "REC.csv")]
    pub recording: PathBuf,
    /// The effects whose parameters are fitted, comma separated contract ids
    /// (e.g. `clearance` or `stiffness`).
    #[arg(long, value_name = "IDS", value_delimiter = ',', required = true, value_parser = parse_effect)]
    pub fit: Vec<EffectId>,
    /// Write the report (JSON) here.
    #[arg(long, value_name = "REPORT.json")]
    pub report: Option<PathBuf>,
    /// Write the calibrated model here, as a robot file.
    #[arg(long = "out", value_name = "FITTED.toml")]
    pub out: Option<PathBuf>,
    /// How rows are held out (as for diagnose).
    #[arg(long, value_name = "SPLIT", value_parser = str::parse::<Holdout>)]
    pub holdout: Option<Holdout>,
    /// With --fit clearance: a smooth table of N values per pair over one turn (the
    /// seed's measured "database", written as table_deg) instead of a cosine profile.
    #[arg(long, value_name = "N", value_parser = table_size_parser())]
    pub table: Option<u16>,
    /// Worker threads (default: all cores).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// Mark the rows near a snap as diagnose does.
    #[arg(long, value_name = "X", default_value_t = DEFAULT_WARN_MARGIN, value_parser = parse_warn_margin)]
    pub warn_margin: f64,
}

/// Options of `ctr-cli evaluate`.
#[derive(Debug, clap::Args)]
pub struct EvaluateArgs {
    /// Models to compare (repeat the option); all must have the recording's tube count.
    #[arg(long, value_name = "ROBOT.toml", required = true)]
    pub robot: Vec<PathBuf>,
    /// The recording.
    #[arg(long, value_name = "REC.csv")]
    pub recording: PathBuf,
    /// Say where a model's stability margin is below X along the recording (within X of
    /// a snap; below 0: on an unstable branch), after the table. As `fk --warn-margin`;
    /// 0 says only where a model is on an unstable branch.
    #[arg(long, value_name = "X", default_value_t = DEFAULT_WARN_MARGIN, value_parser = parse_warn_margin)]
    pub warn_margin: f64,
}

/// `--table`: a size in [`CLEARANCE_FIT_TABLE_SIZES`].
fn table_size_parser() -> clap::builder::RangedI64ValueParser<u16> {
    let (low, high) = CLEARANCE_FIT_TABLE_SIZES.into_inner();
    clap::value_parser!(u16).range(low as i64..=high as i64)
}

fn parse_warn_margin(s: &str) -> Result<f64, String> {
    let x: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    ctr_diagnosis::checked_warn_margin(x)
}

fn parse_effect(s: &str) -> Result<EffectId, String> {
    EffectId::from_id(s)
}

fn threads(t: Option<u16>) -> usize {
    t.map_or(0, usize::from)
}

fn load(robot: &Path, recording: &Path) -> Result<(RobotSpec, Recording), Failure> {
    let spec = RobotSpec::from_path(robot).map_err(|e| Failure::Input(e.to_string()))?;
    let rec = Recording::from_path(recording, spec.robot.n_tubes())
        .map_err(|e| Failure::Input(e.to_string()))?;
    Ok((spec, rec))
}

/// Checks that every output can be written before the work starts.
fn check_outputs(paths: &[&Option<PathBuf>]) -> Result<(), Failure> {
    for p in paths.iter().copied().flatten() {
        AtomicFile::check_path(p).map_err(|e| Failure::Input(e.to_string()))?;
    }
    Ok(())
}

fn write_text(path: &Path, text: &str) -> Result<(), Failure> {
    AtomicFile::write_file(path, text.as_bytes()).map_err(|e| Failure::Input(e.to_string()))
}

/// Where `diagnose` and `calibrate` write.
struct Outputs<'a> {
    report: &'a Option<PathBuf>,
    out: &'a Option<PathBuf>,
    with_empirical: bool,
    established_only: bool,
    plots: Option<&'a Path>,
    html: &'a Option<PathBuf>,
    suggest_run: &'a Option<PathBuf>,
}

fn write_outputs(spec: &RobotSpec, d: &Diagnosis, o: &Outputs<'_>) -> Result<(), Failure> {
    if let Some(path) = o.report {
        let json = serde_json::to_string_pretty(&d.report).expect("a report serializes");
        write_text(path, &(json + "\n"))?;
    }
    if let Some(path) = o.out {
        let fitted = if o.established_only {
            d.established_spec(spec)
        } else if o.with_empirical {
            d.fitted_spec_with_empirical(spec)
        } else {
            d.fitted_spec(spec)
        };
        let findings = d.graded(o.established_only);
        let with_empirical = o.with_empirical && d.empirical.is_some();
        write_text(
            path,
            &ctr_diagnosis::fitted_file(&fitted, &findings, with_empirical),
        )?;
    }
    if let Some(path) = o.suggest_run {
        match &d.suggested_joints {
            Some(run) => write_text(path, &run.to_csv())?,
            None => eprintln!(
                "--suggest-run: no run suggested (every fitted parameter is pinned well, or \
                 no simple run would pin it better); {} not written",
                path.display()
            ),
        }
    }
    Ok(())
}

/// Writes the plots and the HTML page, when asked for.
fn write_drawings(
    spec: &RobotSpec,
    rec: &Recording,
    d: &Diagnosis,
    o: &Outputs<'_>,
) -> Result<(), Failure> {
    if o.plots.is_none() && o.html.is_none() {
        return Ok(());
    }
    let failed = |e: DiagnoseError| Failure::Input(format!("{}: {e}", rec.file));
    let page = Page::new(&d.report, rec, spec, &d.fitted_spec(spec)).map_err(failed)?;
    if let Some(dir) = o.plots {
        std::fs::create_dir_all(dir)
            .map_err(|e| Failure::Input(format!("{}: cannot create: {e}", dir.display())))?;
        for plot in page.plots().map_err(failed)? {
            write_text(&dir.join(&plot.file_name), &plot.svg)?;
        }
    }
    if let Some(path) = o.html {
        write_text(path, &page.to_html().map_err(failed)?)?;
    }
    Ok(())
}

/// The course of `diagnose` and `calibrate`: checks that the outputs can be written,
/// reads the robot and the recording, runs `fit` on the robot's model, writes the
/// outputs (the plots and the page too) and prints the summary.
fn fit_and_write(
    robot: &Path,
    recording: &Path,
    o: &Outputs<'_>,
    fit: impl FnOnce(&ModelSpec, &Recording) -> Result<Diagnosis, DiagnoseError>,
) -> Result<(), Failure> {
    check_outputs(&[o.report, o.out, o.html, o.suggest_run])?;
    let (spec, rec) = load(robot, recording)?;
    let model = ModelSpec::from_spec(&spec);
    let d = fit(&model, &rec).map_err(|e| Failure::Input(format!("{}: {e}", rec.file)))?;
    write_outputs(&spec, &d, o)?;
    write_drawings(&spec, &rec, &d, o)?;
    print!("{}", d.report.summary(&rec.file));
    Ok(())
}

/// `ctr-cli diagnose`.
pub fn diagnose(args: DiagnoseArgs) -> Result<(), Failure> {
    let options = Options {
        holdout: args.holdout.unwrap_or_default(),
        candidates: args.effects.unwrap_or_else(|| EffectId::ALL.to_vec()),
        threads: threads(args.threads),
        clearance_table: None,
        warn_margin: args.warn_margin,
        ..Default::default()
    };
    let outputs = Outputs {
        report: &args.report,
        out: &args.out,
        with_empirical: args.with_empirical,
        established_only: args.established_only,
        plots: args.plots.as_deref(),
        html: &args.html,
        suggest_run: &args.suggest_run,
    };
    fit_and_write(&args.robot, &args.recording, &outputs, |model, rec| {
        ctr_diagnosis::diagnose(model, rec, &options)
    })
}

/// `ctr-cli calibrate`.
pub fn calibrate(args: CalibrateArgs) -> Result<(), Failure> {
    let options = Options {
        holdout: args.holdout.unwrap_or_default(),
        threads: threads(args.threads),
        clearance_table: args.table.map(usize::from),
        warn_margin: args.warn_margin,
        ..Options::default()
    };
    let outputs = Outputs {
        report: &args.report,
        out: &args.out,
        with_empirical: false,
        established_only: false,
        plots: None,
        html: &None,
        suggest_run: &None,
    };
    fit_and_write(&args.robot, &args.recording, &outputs, |model, rec| {
        ctr_diagnosis::calibrate(model, rec, &args.fit, &options)
    })
}

/// `ctr-cli evaluate`.
pub fn evaluate(args: EvaluateArgs) -> Result<(), Failure> {
    let mut models = Vec::new();
    let mut names = Vec::new();
    let mut n_tubes = None;
    for path in &args.robot {
        let spec = RobotSpec::from_path(path).map_err(|e| Failure::Input(e.to_string()))?;
        let n = spec.robot.n_tubes();
        if let Some(first) = n_tubes {
            if first != n {
                return Err(Failure::Input(format!(
                    "{}: {n} tubes, but the first robot has {first}; models compared on one \
                     recording must have the same tubes",
                    path.display()
                )));
            }
        }
        n_tubes = Some(n);
        models.push(ModelSpec::from_spec(&spec));
        names.push(path.file_name().map_or_else(
            || path.display().to_string(),
            |f| f.to_string_lossy().into_owned(),
        ));
    }
    let rec = Recording::from_path(&args.recording, n_tubes.unwrap_or(1))
        .map_err(|e| Failure::Input(e.to_string()))?;
    let table = ctr_diagnosis::evaluate(&models, &rec, args.warn_margin)
        .map_err(|e| Failure::Input(format!("{}: {e}", rec.file)))?;
    let width = table.iter().map(|r| r.run.len()).max().unwrap_or(3).max(3);
    let mut head = format!("{:width$}  {:>5}", "run", "rows");
    for n in &names {
        head += &format!("  {:>22}", format!("{n} mean/max mm"));
    }
    println!("{head}");
    for r in &table {
        let mut line = format!("{:width$}  {:>5}", r.run, r.rows);
        for (mean, max) in r.mean_mm.iter().zip(&r.max_mm) {
            line += &format!("  {:>22}", format!("{mean:.3} / {max:.3}"));
        }
        println!("{line}");
    }
    // where each model is near a snap: the `all` row's ranges
    if let Some(all) = table.last() {
        let marks: Vec<Marks> = all
            .near_snap
            .iter()
            .zip(&all.unstable)
            .map(|(near, unstable)| Marks {
                near_snap: near.clone(),
                unstable: unstable.clone(),
            })
            .collect();
        let names: Vec<String> = names.iter().map(|n| format!("{n} is")).collect();
        let who: Vec<(&str, &Marks)> = names.iter().map(String::as_str).zip(&marks).collect();
        if let Some(words) = ctr_diagnosis::near_snap_words(args.warn_margin, &who) {
            println!("{words}");
        }
    }
    Ok(())
}
