//! The report's plain-language summary ([`Report::summary`]): the verdict, the error
//! and where it sits, the findings by grade with their gains and intervals, what is
//! left, the next steps.

use super::{numbers, Finding, Grade, Report, Term, REMOVED};
use numbers::{sig, sig_interval};

impl Report {
    /// The summary's last lines: the rows near a snap, the run to record next, the
    /// empirical term.
    fn next_steps_words(&self) -> String {
        let mut s = String::new();
        if let Some(line) = self.stability.words() {
            s += &line;
            s += "\n";
        }
        if let Some(run) = &self.suggested_run {
            s += &format!(
                "Next run to record: {} ({} rows, one every {} s). Expected: {}.\n",
                run.run,
                run.rows,
                sig(run.sample_period_s),
                run.why
            );
        }
        for c in &self.sessions {
            s += &format!("Sessions disagree: {}.\n", c.statement);
        }
        if let Some(band) = self.empirical.as_ref().and_then(|e| e.band) {
            let emp = self.empirical.as_ref().expect("a band belongs to a term");
            let telling: Vec<String> = emp
                .inputs
                .iter()
                .take(3)
                .map(|i| format!("{} ({:.2})", i.input, i.length_scale))
                .collect();
            s += &format!(
                "A learned discrepancy (not physics: a Gaussian process over the joints and \
                 their history, {} inputs, fitted on the fit rows) leaves {:.3} mm held out \
                 (the physics {:.3} mm); its 95 % band (median half-width {:.3} mm) holds \
                 {:.0} % of the held-out coordinates; the inputs it varies with most (length \
                 scale): {}.{}\n",
                emp.terms,
                emp.heldout_rms_mm,
                self.final_.heldout_rms_mm,
                1.959_963_984_540_054 * band.median_sd_mm,
                100.0 * band.heldout_coverage_95,
                telling.join(", "),
                if emp.heldout_rms_mm >= self.final_.heldout_rms_mm {
                    " It does not predict the held-out rows better than the physics alone: \
                     what is left does not repeat with the joints and their history here \
                     (do not apply it)."
                } else {
                    ""
                }
            );
        } else if let Some(emp) = &self.empirical {
            let not_offered = emp
                .method
                .split_once("; the learned discrepancy")
                .map(|(_, why)| format!(" The learned discrepancy{why}."))
                .unwrap_or_default();
            if emp.terms == 0 {
                s += &format!(
                    "No empirical term beats the physics in cross-validation on the fit \
                     rows.{not_offered}\n"
                );
                return s;
            }
            let terms: Vec<String> = self
                .dominant_terms()
                .map(|t| format!("{} on {} ({:.2} mm)", t.feature, t.axis, t.rms_mm))
                .collect();
            s += &format!(
                "An empirical term (not physics, {} terms chosen by cross-validation on the \
                 fit rows) leaves {:.3} mm held out; its largest terms: {}.{not_offered}\n",
                emp.terms,
                emp.heldout_rms_mm,
                terms.join(", ")
            );
        }
        s
    }

    /// The established findings (physics the data show), in the order added.
    ///
    /// ```
    /// # fn check(r: &ctr_diagnosis::Report) {
    /// let names: Vec<&str> = r.established().map(|f| f.effect.as_str()).collect();
    /// # }
    /// ```
    pub fn established(&self) -> impl Iterator<Item = &Finding> {
        self.findings
            .iter()
            .filter(|f| f.grade == Grade::Established)
    }

    /// The findings by grade in one line each, established first (what the summary
    /// leads with); empty without findings.
    fn graded_words(&self) -> String {
        let of = |g: Grade| -> Vec<&str> {
            self.findings
                .iter()
                .filter(|f| f.grade == g)
                .map(|f| f.effect.as_str())
                .collect()
        };
        let (established, predictive) = (of(Grade::Established), of(Grade::Predictive));
        let mut s = String::new();
        if !established.is_empty() {
            s += &format!("Established: {}.\n", established.join(", "));
        }
        if !predictive.is_empty() {
            s += &format!(
                "Predictive, not established (kept for prediction): {}.\n",
                predictive.join(", ")
            );
        }
        s
    }

    /// The plain-language summary (`ctr-cli diagnose` prints it; `ctr_py` returns it):
    /// the error, where it sits, each finding with its gain, and what is left.
    pub fn summary(&self, recording: &str) -> String {
        let mut s = if !self.noise.rms_mm.is_finite() {
            format!(
                "{recording}: explained: cannot tell: after fitting, {:.3} mm RMS of tip \
                 position is left on held-out rows (all rows counted), and the noise is \
                 unknown ({}).\n",
                self.final_.heldout_rms_mm, self.noise.method
            )
        } else {
            format!(
                "{recording}: explained: {}: after fitting, {:.3} mm RMS of tip position is \
                 left on held-out rows (all rows counted) against {:.3} mm of noise estimated \
                 from the data{}.\n",
                if self.explained { "yes" } else { "no" },
                self.final_.heldout_rms_mm,
                self.noise.rms_mm,
                match (&self.final_.angular, &self.noise.angular) {
                    (Some(a), Some(n)) => format!(
                        "; tip angle {:.2} deg against {:.2} deg of noise",
                        a.heldout_rms_deg, n.rms_deg
                    ),
                    _ => String::new(),
                }
            )
        };
        s += &format!(
            "The model misses the measured tip by {:.3} mm RMS ({:.3} mm on held-out rows, \
             largest {:.3} mm){}.\n",
            self.baseline.rms_mm,
            self.baseline.heldout_rms_mm,
            self.baseline.max_mm,
            self.baseline.angular.map_or(String::new(), |a| format!(
                " and its angle by {:.2} deg RMS ({:.2} deg on held-out rows)",
                a.rms_deg, a.heldout_rms_deg
            ))
        );
        s += &self.graded_words();
        let patterns: Vec<&str> = self
            .located
            .iter()
            .filter(|l| l.kind != "run")
            .take(3)
            .map(|l| l.text.as_str())
            .collect();
        if !patterns.is_empty() {
            s += &format!("Where: the error {}.\n", patterns.join("; "));
        }
        if self.findings.is_empty() {
            s += "No left-out effect explains part of it.\n";
        }
        for grade in [Grade::Established, Grade::Predictive] {
            let mut of_grade = self.findings.iter().filter(|f| f.grade == grade).peekable();
            if of_grade.peek().is_some() {
                s += match grade {
                    Grade::Established => "Established (physics the data show):\n",
                    Grade::Predictive => {
                        "Predictive (each helps prediction on held-out rows, but its form is \
                         not established: it may stand in for something outside the \
                         vocabulary):\n"
                    }
                };
            }
            for f in of_grade {
                s += &finding_words(f);
            }
        }
        for line in &self.identifiability {
            s += &format!("Identifiability: {line}.\n");
        }
        for c in &self.correlated {
            s += &format!(
                "Hard to tell apart: {} and {} (correlation {:.2}).\n",
                c.a, c.b, c.r
            );
        }
        for t in self.tried.iter().filter(|t| t.note.starts_with(REMOVED)) {
            s += &format!(
                "Not physics: {} ({}).\n",
                t.effect.as_str(),
                &t.note[REMOVED.len()..]
            );
        }
        s += &format!(
            "After fitting: {:.3} mm RMS, {:.3} mm held out{}. The {}.\n",
            self.final_.rms_mm,
            self.final_.heldout_rms_mm,
            self.final_.angular.map_or(String::new(), |a| format!(
                " (tip angle {:.2} deg, {:.2} deg held out)",
                a.rms_deg, a.heldout_rms_deg
            )),
            self.unexplained
        );
        s += &self.next_steps_words();
        s
    }

    fn dominant_terms(&self) -> impl Iterator<Item = &Term> {
        self.empirical.iter().flat_map(|e| e.dominant.iter())
    }
}

/// A finding in the summary: what it is, where it shows, its gain on the held-out rows
/// (tip positions, and angles when measured), its intervals, its grade's reason when
/// predictive, and the effects that explain its residual as well.
fn finding_words(f: &Finding) -> String {
    let mut s = format!(
        "{}\n  where: {}\n  without it, the fitted model's held-out RMS would be {:.3} mm \
         instead of {:.3} mm{} (fit rows {:.3} instead of {:.3} mm)\n",
        f.explanation,
        f.where_,
        f.heldout_rms_mm_before,
        f.heldout_rms_mm_after,
        f.heldout_rms_deg.map_or(String::new(), |[a, b]| format!(
            "; tip angle {a:.2} instead of {b:.2} deg"
        )),
        f.rms_mm_before,
        f.rms_mm_after
    );
    let ci = intervals(&f.parameters, &f.ci95);
    if !ci.is_empty() {
        s += &format!("  95 % intervals: {ci}\n");
    }
    if f.grade == Grade::Predictive {
        s += &format!("  why predictive: {}\n", f.grade_reason);
    }
    if !f.equally_explained_by.is_empty() {
        let others: Vec<String> = f
            .equally_explained_by
            .iter()
            .map(|a| {
                format!(
                    "{} ({:.3} mm held out)",
                    a.effect.as_str(),
                    a.heldout_rms_mm
                )
            })
            .collect();
        s += &format!(
            "  equally: {} explain{} this residual as well as {}: the data do not tell them \
             apart (it is named only because the search took it first); a run that moves \
             them differently, or knowledge of the rig, decides\n",
            others.join(", "),
            if others.len() == 1 { "s" } else { "" },
            f.effect.as_str(),
        );
    }
    s
}

/// A finding's parameters with their intervals, in words: `tau_s 0.7500 (0.7412 to
/// 0.7588)`; `identified` combinations after them.
pub(crate) fn intervals(params: &serde_json::Value, ci95: &serde_json::Value) -> String {
    let (parameters, identified) = numbers::intervals(params, ci95);
    let mut parts: Vec<String> = parameters
        .iter()
        .map(|p| {
            if p.lo.is_none() && p.hi.is_none() {
                format!("{} {} (not bounded)", p.name, sig(p.value))
            } else {
                let [v, lo, hi] =
                    sig_interval(p.value, p.lo, p.hi).map(|x| x.unwrap_or("?".into()));
                format!("{} {v} ({lo} to {hi})", p.name)
            }
        })
        .collect();
    for c in &identified {
        let [v, lo, hi] =
            sig_interval(c.value, c.lo, c.hi).map(|x| x.unwrap_or_else(|| sig(f64::NAN)));
        parts.push(format!("identified {} {v} ({lo} to {hi})", c.name));
    }
    parts.join(", ")
}
