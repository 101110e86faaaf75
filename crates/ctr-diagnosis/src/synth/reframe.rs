//! Re-framed recordings: concealed effects whose true change to the model is exact.
//!
//! A recording turned into another frame, with an encoder's zero moved or its commands
//! shifted in time, is the same robot: the true model of the new recording is the old
//! one's with one effect changed by a known amount ([`Reframe::change`]). A diagnosis
//! must recover that change and keep the rest of its account: it must commute with
//! the transformation. Glitches, runs in another order and rows thinned change nothing
//! of the model. These are the proof the diagnosis owes on real data, where no other
//! truth is known (`scripts/reframe.sh` runs a seeded family of them on a real
//! recording), and on generated data beside it (`tests/invariance.rs`).
//!
//! ```
//! use ctr_diagnosis::synth::Reframe;
//! use ctr_formats::Recording;
//! let text = "t_s,run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\n0,a,10,0,1,0,10\n1,a,12,30,2,0,12\n";
//! let rec = Recording::read(text.as_bytes(), "rec.csv", 1)?;
//! let zero = Reframe::EncoderZero { tube: 0, feed_mm: 1.5, rotation_deg: 6.0 };
//! let moved = zero.apply(&rec)?.recording;
//! assert_eq!(moved.rows[1].q, [13.5, 36.0]);
//! // its joint offset moves by minus that
//! assert_eq!(zero.change(), "joint_offset of tube 1: feed -1.5 mm, rotation -6 deg");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use ctr_analysis::rng::Rng;
use ctr_formats::Recording;
use nalgebra::{Rotation3, UnitQuaternion, Vector3};

/// A transformation of a recording whose effect on the true model is exact (module
/// doc).
#[derive(Clone, Debug, PartialEq)]
pub enum Reframe {
    /// The tracker's frame turned and shifted: every measured tip `p -> R p + t`,
    /// every measured tangent and orientation turned by `R`. The registration
    /// composes: `R R_reg`, `R t_reg + t`.
    Frame {
        /// `R` as a rotation vector (axis times angle), degrees.
        rotation_vector_deg: [f64; 3],
        /// `t`, mm.
        translation_mm: [f64; 3],
    },
    /// An encoder's zero moved: `feed_mm` added to the tube's feed column and
    /// `rotation_deg` to its rotation column. Its joint offset moves by minus these.
    EncoderZero {
        /// The tube, 0-based (0 the outermost).
        tube: usize,
        /// Added to its feed column, mm.
        feed_mm: f64,
        /// Added to its rotation column, degrees.
        rotation_deg: f64,
    },
    /// The joint columns replaced by the joints `shift_s` later, interpolated within
    /// each run (its last rows hold its last joints): the latency grows by `shift_s`.
    TimeShift {
        /// Seconds, at least 0.
        shift_s: f64,
    },
    /// A share of the rows' measured tips jumped by `size_mm` in a random direction:
    /// tracker glitches, which a diagnosis sets aside.
    Glitches {
        /// Share of the rows, 0 to 1.
        fraction: f64,
        /// Size of a jump, mm.
        size_mm: f64,
        /// Seed of the rows and directions.
        seed: u64,
    },
    /// The runs in another order (a seeded shuffle).
    RunsReordered {
        /// Seed of the shuffle.
        seed: u64,
    },
    /// Every other row of each run kept (its first row among them).
    Thinned,
}

/// A re-framed recording.
#[derive(Clone, Debug)]
pub struct Reframed {
    /// The recording transformed.
    pub recording: Recording,
    /// Its rows whose tips were jumped (glitches), ascending.
    pub glitch_rows: Vec<usize>,
}

/// Largest frame turn of [`Reframe::draw`], degrees.
pub const DRAW_MAX_TURN_DEG: f64 = 8.0;
/// Largest frame shift of [`Reframe::draw`], mm per axis.
pub const DRAW_MAX_SHIFT_MM: f64 = 10.0;
/// Largest encoder rotation zero of [`Reframe::draw`], degrees.
pub const DRAW_MAX_ZERO_DEG: f64 = 10.0;
/// Largest encoder feed zero of [`Reframe::draw`], mm.
pub const DRAW_MAX_ZERO_MM: f64 = 3.0;
/// Range of the time shifts of [`Reframe::draw`], s.
pub const DRAW_SHIFT_S: [f64; 2] = [0.05, 0.4];
/// Range of the glitch share of [`Reframe::draw`].
pub const DRAW_GLITCH_SHARE: [f64; 2] = [0.01, 0.02];
/// Size of a glitch of [`Reframe::draw`], mm.
pub const DRAW_GLITCH_MM: f64 = 12.0;

impl Reframe {
    /// `rec` transformed. Fails with a message for a tube the recording does not have,
    /// a time shift on a recording without `t_s` or a negative one.
    pub fn apply(&self, rec: &Recording) -> Result<Reframed, String> {
        let mut out = rec.clone();
        let mut glitch_rows = Vec::new();
        match *self {
            Reframe::Frame {
                rotation_vector_deg,
                translation_mm,
            } => {
                let r = Rotation3::new(Vector3::from(rotation_vector_deg).map(f64::to_radians));
                let t = Vector3::from(translation_mm);
                let q = UnitQuaternion::from_rotation_matrix(&r);
                for row in &mut out.rows {
                    row.p = (r * Vector3::from(row.p) + t).into();
                    if let Some(d) = row.tangent {
                        row.tangent = Some((r * Vector3::from(d)).into());
                    }
                    if let Some(m) = row.quaternion {
                        let turned = q * UnitQuaternion::from_quaternion(
                            nalgebra::Quaternion::new(m[0], m[1], m[2], m[3]),
                        );
                        row.quaternion = Some(ctr_formats::canonical_quaternion(&turned));
                    }
                }
            }
            Reframe::EncoderZero {
                tube,
                feed_mm,
                rotation_deg,
            } => {
                if tube >= rec.n_tubes {
                    return Err(format!(
                        "encoder zero of tube {}: the recording has {} tubes",
                        tube + 1,
                        rec.n_tubes
                    ));
                }
                for row in &mut out.rows {
                    row.q[2 * tube] += feed_mm;
                    row.q[2 * tube + 1] += rotation_deg;
                }
            }
            Reframe::TimeShift { shift_s } => {
                if !rec.has_time || rec.is_static() {
                    return Err("a time shift needs a time series (a t_s column)".into());
                }
                if shift_s.is_nan() || shift_s < 0.0 {
                    return Err(format!("time shift {shift_s} s: wanted at least 0"));
                }
                for run in &rec.runs {
                    let rows = &rec.rows[run.rows.clone()];
                    for (k, row) in out.rows[run.rows.clone()].iter_mut().enumerate() {
                        row.q = joints_at(rows, rows[k].t_s + shift_s);
                    }
                }
            }
            Reframe::Glitches {
                fraction,
                size_mm,
                seed,
            } => {
                let mut rng = Rng::new(seed);
                let n = rec.rows.len();
                let count = ((fraction.clamp(0.0, 1.0) * n as f64).round() as usize).min(n);
                while glitch_rows.len() < count {
                    let r = rng.below(n);
                    if !glitch_rows.contains(&r) {
                        glitch_rows.push(r);
                    }
                }
                glitch_rows.sort_unstable();
                for &r in &glitch_rows {
                    let d = rng.unit_vector();
                    for a in 0..3 {
                        out.rows[r].p[a] += size_mm * d[a];
                    }
                }
            }
            Reframe::RunsReordered { seed } => {
                let mut order: Vec<usize> = (0..rec.runs.len()).collect();
                let mut rng = Rng::new(seed);
                for i in (1..order.len()).rev() {
                    order.swap(i, rng.below(i + 1));
                }
                out = with_runs(rec, &order, |_| true);
            }
            Reframe::Thinned => {
                let all: Vec<usize> = (0..rec.runs.len()).collect();
                out = with_runs(rec, &all, |k| k % 2 == 0);
            }
        }
        Ok(Reframed {
            recording: out,
            glitch_rows,
        })
    }

    /// The true change of the model, in words.
    pub fn change(&self) -> String {
        match *self {
            Reframe::Frame {
                rotation_vector_deg: v,
                translation_mm: t,
            } => format!(
                "registration composed with a turn of ({}, {}, {}) deg and a shift of ({}, {}, {}) mm",
                v[0], v[1], v[2], t[0], t[1], t[2]
            ),
            Reframe::EncoderZero {
                tube,
                feed_mm,
                rotation_deg,
            } => format!(
                "joint_offset of tube {}: feed {} mm, rotation {} deg",
                tube + 1,
                -feed_mm,
                -rotation_deg
            ),
            Reframe::TimeShift { shift_s } => format!("latency {shift_s:+} s"),
            Reframe::Glitches { .. } => "none (glitches: set aside)".into(),
            Reframe::RunsReordered { .. } => "none (runs in another order)".into(),
            Reframe::Thinned => "none (every other row)".into(),
        }
    }

    /// A seeded draw of the family: a frame (any axis, up to [`DRAW_MAX_TURN_DEG`] and
    /// [`DRAW_MAX_SHIFT_MM`] per axis), an encoder zero (any tube, up to
    /// [`DRAW_MAX_ZERO_DEG`] and [`DRAW_MAX_ZERO_MM`], a feed zero only where `valid`
    /// holds every row's moved joints: the feeds' order kept), a time shift in
    /// [`DRAW_SHIFT_S`] (only with `t_s`), glitches of [`DRAW_GLITCH_MM`] on a share
    /// in [`DRAW_GLITCH_SHARE`], the runs reordered, or the rows thinned, each kind as
    /// likely.
    pub fn draw(rng: &mut Rng, rec: &Recording, valid: impl Fn(&[f64]) -> bool) -> Reframe {
        let kinds = if rec.has_time && !rec.is_static() {
            6
        } else {
            5
        };
        let between = |rng: &mut Rng, [lo, hi]: [f64; 2]| lo + (hi - lo) * rng.uniform();
        let signed = |rng: &mut Rng, size: f64| size * (2.0 * rng.uniform() - 1.0);
        match rng.below(kinds) {
            0 => {
                let axis = rng.unit_vector();
                let angle = between(rng, [0.5, DRAW_MAX_TURN_DEG]);
                Reframe::Frame {
                    rotation_vector_deg: axis.map(|a| a * angle),
                    translation_mm: [0; 3].map(|_| signed(rng, DRAW_MAX_SHIFT_MM)),
                }
            }
            1 => {
                let tube = rng.below(rec.n_tubes.max(1));
                let rotation_deg = signed(rng, DRAW_MAX_ZERO_DEG);
                let mut feed_mm = signed(rng, DRAW_MAX_ZERO_MM);
                // the feeds' order and lengths kept: halved (and turned round) until
                // every row stays valid, else no feed at all
                let keeps = |feed_mm: f64| {
                    rec.rows.iter().all(|row| {
                        let mut q = row.q.clone();
                        q[2 * tube] += feed_mm;
                        valid(&q) || !valid(&row.q)
                    })
                };
                let mut tries = 0;
                while !keeps(feed_mm) {
                    tries += 1;
                    feed_mm = if tries > 16 { 0.0 } else { -0.5 * feed_mm };
                }
                Reframe::EncoderZero {
                    tube,
                    feed_mm,
                    rotation_deg,
                }
            }
            2 => Reframe::Glitches {
                fraction: between(rng, DRAW_GLITCH_SHARE),
                size_mm: DRAW_GLITCH_MM,
                seed: rng.next_u64(),
            },
            3 => Reframe::RunsReordered {
                seed: rng.next_u64(),
            },
            4 => Reframe::Thinned,
            _ => Reframe::TimeShift {
                shift_s: between(rng, DRAW_SHIFT_S),
            },
        }
    }
}

/// Tolerances of a recovered change (issue 40): a frame within 1 deg and 2 mm.
pub const FRAME_TOLERANCE: [f64; 2] = [1.0, 2.0];
/// An encoder zero within 1 deg and 0.4 mm.
pub const ZERO_TOLERANCE: [f64; 2] = [1.0, 0.4];
/// A time shift within 0.03 s.
pub const SHIFT_TOLERANCE_S: f64 = 0.03;
/// The held-out RMS and every other finding's contribution to it within 5 % of the
/// unmodified diagnosis's.
pub const ACCOUNT_TOLERANCE: f64 = 0.05;

/// What a diagnosis of a re-framed recording recovered, against the diagnosis of the
/// recording as it was ([`Reframe::recovered`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Recovered {
    /// How far the change found is from the true one: a frame's turn (deg) and shift
    /// (mm), an encoder zero's rotation (deg) and feed (mm), a time shift's (s, twice);
    /// `None` for a kind that changes nothing, or where the effect was not found.
    pub error: Option<[f64; 2]>,
    /// The grade of the effect changed, where it was found.
    pub grade: Option<crate::report::Grade>,
    /// The held-out RMS over that of the unmodified diagnosis (tracker outliers aside).
    pub heldout_ratio: f64,
    /// The effects found other than the one changed, where they differ from the
    /// unmodified diagnosis's: (gained, lost).
    pub others_differ: (Vec<&'static str>, Vec<&'static str>),
    /// The effects found in both, other than the one changed, whose grade differs.
    pub grades_differ: Vec<&'static str>,
    /// The largest relative change of another finding's contribution to the predicted
    /// tips (the RMS over every row of the change its removal makes).
    pub worst_other: f64,
    /// Of the glitch rows, how many the report flags as outliers.
    pub glitches_flagged: Option<(usize, usize)>,
}

impl Recovered {
    /// Whether it meets the tolerances of the module (the change within
    /// [`FRAME_TOLERANCE`], [`ZERO_TOLERANCE`] or [`SHIFT_TOLERANCE_S`]; every glitch
    /// flagged; the same other findings; the held-out RMS and the other findings'
    /// contributions within [`ACCOUNT_TOLERANCE`]).
    pub fn holds(&self, reframe: &Reframe) -> bool {
        let within = |tol: [f64; 2]| self.error.is_some_and(|e| e[0] <= tol[0] && e[1] <= tol[1]);
        let change = match reframe {
            Reframe::Frame { .. } => within(FRAME_TOLERANCE),
            Reframe::EncoderZero { .. } => within(ZERO_TOLERANCE),
            Reframe::TimeShift { .. } => within([SHIFT_TOLERANCE_S; 2]),
            _ => true,
        };
        let flagged = self.glitches_flagged.is_none_or(|(f, all)| f == all);
        change
            && flagged
            && self.others_differ.0.is_empty()
            && self.others_differ.1.is_empty()
            && (self.heldout_ratio - 1.0).abs() <= ACCOUNT_TOLERANCE
            && self.worst_other <= ACCOUNT_TOLERANCE
    }
}

impl Reframe {
    /// The effect whose true value the transformation changes, if any.
    pub fn changed(&self) -> Option<crate::EffectId> {
        match self {
            Reframe::Frame { .. } => Some(crate::EffectId::Registration),
            Reframe::EncoderZero { .. } => Some(crate::EffectId::JointOffset),
            Reframe::TimeShift { .. } => Some(crate::EffectId::Latency),
            _ => None,
        }
    }

    /// What the diagnosis `moved` of the transformed recording `moved_rec`
    /// (`glitch_rows` its jumped rows, as [`Reframe::apply`] gave them) recovered
    /// against `base`, the diagnosis of `base_rec`, the recording as it was.
    pub fn recovered(
        &self,
        base: &crate::Diagnosis,
        base_rec: &Recording,
        moved: &crate::Diagnosis,
        moved_rec: &Recording,
        glitch_rows: &[usize],
    ) -> Recovered {
        use crate::report::Finding;
        let changed = self.changed();
        let find = |r: &'_ crate::Report, c: crate::EffectId| -> Option<Finding> {
            r.findings.iter().find(|f| f.effect == c).cloned()
        };
        let (rb, rm) = (&base.report, &moved.report);
        // the change as the fitted models hold it (the tracker's frame is in the model
        // also where it is no finding)
        let error = changed
            .filter(|&c| find(rm, c).is_some())
            .map(|_| self.error_of(&base.fitted, &moved.fitted));
        let grade = changed.and_then(|c| find(rm, c)).map(|f| f.grade);
        let others = |r: &crate::Report| -> Vec<&'static str> {
            let mut v: Vec<&'static str> = r
                .findings
                .iter()
                .filter(|f| Some(f.effect) != changed)
                .map(|f| f.effect.as_str())
                .collect();
            v.sort_unstable();
            v
        };
        let (ob, om) = (others(rb), others(rm));
        let gained = om.iter().filter(|e| !ob.contains(e)).copied().collect();
        let lost = ob.iter().filter(|e| !om.contains(e)).copied().collect();
        let mut grades_differ = Vec::new();
        let mut worst_other: f64 = 0.0;
        for f in rb.findings.iter().filter(|f| Some(f.effect) != changed) {
            if let Some(g) = find(rm, f.effect) {
                if g.grade != f.grade {
                    grades_differ.push(f.effect.as_str());
                }
                let before = contribution(&base.fitted, base_rec, f.effect);
                let after = contribution(&moved.fitted, moved_rec, f.effect);
                let ratio = after / before;
                if ratio.is_finite() {
                    worst_other = worst_other.max((ratio - 1.0).abs());
                }
            }
        }
        let inliers = |r: &crate::Report| r.final_inliers.heldout_rms_mm;
        let glitches_flagged = (!glitch_rows.is_empty()).then(|| {
            let lines: Vec<usize> = glitch_rows
                .iter()
                .map(|&r| moved_rec.rows[r].line)
                .collect();
            let flagged = lines
                .iter()
                .filter(|l| rm.outlier_lines.contains(l))
                .count();
            (flagged, lines.len())
        });
        Recovered {
            error,
            grade,
            heldout_ratio: inliers(rm) / inliers(rb),
            others_differ: (gained, lost),
            grades_differ,
            worst_other,
            glitches_flagged,
        }
    }

    /// How far the change from `base` to `moved` (the fitted models) is from the true
    /// one, in what the data identify. A turn of every tube about W's z axis (the
    /// insertion axis) moves the tip as the frame turned about it does, so with both in
    /// a model only their sum is identified: the frame is compared as `R Rz(o_1)`
    /// (`o_1` the outer tube's rotation offset), and a tube's rotation zero as
    /// `o_i + tau`, `tau` the frame's twist about W's z (`R = S Rz(tau)`).
    fn error_of(
        &self,
        base: &ctr_analysis::model::ModelSpec,
        moved: &ctr_analysis::model::ModelSpec,
    ) -> [f64; 2] {
        use crate::EffectId;
        let n = base.robot.n_tubes();
        let frame = |m: &ctr_analysis::model::ModelSpec| -> (Rotation3<f64>, Vector3<f64>) {
            let x = EffectId::Registration.read(m);
            let r = Rotation3::new(Vector3::new(x[3], x[4], x[5]).map(f64::to_radians));
            (r, Vector3::new(x[0], x[1], x[2]))
        };
        let offsets = |m: &ctr_analysis::model::ModelSpec| EffectId::JointOffset.read(m);
        // the frame's twist about W's z: R = S Rz(tau)
        let twist_deg = |r: &Rotation3<f64>| {
            let q = UnitQuaternion::from_rotation_matrix(r);
            (2.0 * q.k.atan2(q.w)).to_degrees()
        };
        match *self {
            Reframe::Frame {
                rotation_vector_deg,
                translation_mm,
            } => {
                let composite = |m: &ctr_analysis::model::ModelSpec| {
                    let (r, t) = frame(m);
                    let turn =
                        Rotation3::from_axis_angle(&Vector3::z_axis(), offsets(m)[n].to_radians());
                    (r * turn, t)
                };
                let (rb, tb) = composite(base);
                let (rm, tm) = composite(moved);
                let rt = Rotation3::new(Vector3::from(rotation_vector_deg).map(f64::to_radians));
                let want_r = rt * rb;
                let want_t = rt * tb + Vector3::from(translation_mm);
                [
                    (rm * want_r.inverse()).angle().to_degrees(),
                    (tm - want_t).norm(),
                ]
            }
            Reframe::EncoderZero {
                tube,
                feed_mm,
                rotation_deg,
            } => {
                let effective = |m: &ctr_analysis::model::ModelSpec| {
                    offsets(m)[n + tube] + twist_deg(&frame(m).0)
                };
                let d_rot = effective(moved) - effective(base);
                let d_feed = offsets(moved)[tube] - offsets(base)[tube];
                let wrapped = (d_rot + rotation_deg + 180.0).rem_euclid(360.0) - 180.0;
                [wrapped.abs(), (d_feed + feed_mm).abs()]
            }
            Reframe::TimeShift { shift_s } => {
                let tau = |m: &ctr_analysis::model::ModelSpec| EffectId::Latency.read(m)[0];
                [(tau(moved) - tau(base) - shift_s).abs(); 2]
            }
            _ => [0.0; 2],
        }
    }
}

/// What effect `c` adds to the tips `model` predicts on every row of `rec`: the RMS of
/// the change its removal makes, mm (NaN where either cannot be simulated).
fn contribution(
    model: &ctr_analysis::model::ModelSpec,
    rec: &Recording,
    c: crate::EffectId,
) -> f64 {
    let all: Vec<usize> = (0..rec.runs.len()).collect();
    let mut without = model.clone();
    c.remove(&mut without);
    let predict = |m| ctr_analysis::simulate::predict(m, rec, &all).ok();
    let (Some(a), Some(b)) = (predict(model), predict(&without)) else {
        return f64::NAN;
    };
    let sum: f64 =
        a.p.iter()
            .zip(&b.p)
            .map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>())
            .sum();
    (sum / rec.rows.len().max(1) as f64).sqrt()
}

/// The joints of a run's rows `rows` at time `t`, linear between the rows around it
/// (the last row's past its end).
fn joints_at(rows: &[ctr_formats::RecordedRow], t: f64) -> Vec<f64> {
    let last = rows.len() - 1;
    let k = rows.partition_point(|r| r.t_s <= t);
    if k == 0 {
        return rows[0].q.clone();
    }
    if k > last {
        return rows[last].q.clone();
    }
    let (a, b) = (&rows[k - 1], &rows[k]);
    let span = b.t_s - a.t_s;
    let w = if span > 0.0 { (t - a.t_s) / span } else { 0.0 };
    a.q.iter().zip(&b.q).map(|(x, y)| x + w * (y - x)).collect()
}

/// `rec` with its runs in the order `order`, of each run the rows `keep` takes (by
/// their index within the run), the lines numbered again in the new order (a static
/// set's poses follow their rows; a pose none of whose rows is kept goes).
fn with_runs(rec: &Recording, order: &[usize], keep: impl Fn(usize) -> bool) -> Recording {
    let mut out = Recording {
        rows: Vec::with_capacity(rec.rows.len()),
        runs: Vec::with_capacity(order.len()),
        ..rec.clone()
    };
    let mut moved = vec![None; rec.rows.len()];
    for &i in order {
        let run = &rec.runs[i];
        let start = out.rows.len();
        for (k, row) in rec.rows[run.rows.clone()].iter().enumerate() {
            if keep(k) {
                let mut r = row.clone();
                r.run = out.runs.len();
                r.line = out.rows.len() + 2;
                moved[run.rows.start + k] = Some(out.rows.len());
                out.rows.push(r);
            }
        }
        out.runs.push(ctr_formats::Run {
            label: run.label.clone(),
            rows: start..out.rows.len(),
        });
    }
    out.poses = rec.poses.as_ref().map(|poses| {
        let mut kept: Vec<ctr_formats::Pose> = poses
            .iter()
            .filter_map(|p| {
                let rows: Vec<usize> = p.rows.clone().filter_map(|r| moved[r]).collect();
                Some(ctr_formats::Pose {
                    label: p.label.clone(),
                    rows: *rows.first()?..rows.last()? + 1,
                })
            })
            .collect();
        kept.sort_by_key(|p| p.rows.start);
        kept
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn recording() -> Recording {
        let mut text = String::from("t_s,run,s1_mm,theta1_deg,x_mm,y_mm,z_mm,tx,ty,tz\n");
        for (run, t0) in [("a", 0.0), ("b", 10.0)] {
            for k in 0..5 {
                let t = t0 + k as f64;
                text.push_str(&format!(
                    "{t},{run},{},{},{},0,{},0,0,1\n",
                    10.0 + k as f64,
                    3.0 * t,
                    t,
                    10.0 + t
                ));
            }
        }
        Recording::read(text.as_bytes(), "rec.csv", 1).unwrap()
    }

    #[test]
    fn a_frame_turns_tips_and_tangents() {
        let rec = recording();
        let f = Reframe::Frame {
            rotation_vector_deg: [0.0, 0.0, 90.0],
            translation_mm: [1.0, 2.0, 3.0],
        };
        let out = f.apply(&rec).unwrap().recording;
        let (p, q) = (rec.rows[3].p, out.rows[3].p);
        assert!((q[0] - (-p[1] + 1.0)).abs() < 1e-12 && (q[1] - (p[0] + 2.0)).abs() < 1e-12);
        assert!((q[2] - (p[2] + 3.0)).abs() < 1e-12);
        assert_eq!(out.rows[3].tangent, Some([0.0, 0.0, 1.0]));
    }

    #[test]
    fn a_time_shift_takes_the_joints_later_within_each_run() {
        let rec = recording();
        let out = Reframe::TimeShift { shift_s: 0.5 }
            .apply(&rec)
            .unwrap()
            .recording;
        assert_eq!(out.rows[0].q, [10.5, 1.5]);
        // the last row of a run holds its last joints
        assert_eq!(out.rows[4].q, rec.rows[4].q);
        assert_eq!(out.rows[5].q, [10.5, 31.5]);
        assert!(Reframe::TimeShift { shift_s: -1.0 }.apply(&rec).is_err());
    }

    #[test]
    fn runs_reordered_and_thinned_keep_every_run_whole() {
        let rec = recording();
        let out = Reframe::RunsReordered { seed: 3 }
            .apply(&rec)
            .unwrap()
            .recording;
        let labels: Vec<&str> = out.runs.iter().map(|r| r.label.as_str()).collect();
        assert_eq!(labels.len(), 2);
        for run in &out.runs {
            assert!(out.rows[run.rows.clone()]
                .iter()
                .all(|r| out.runs[r.run].label == run.label));
        }
        let thin = Reframe::Thinned.apply(&rec).unwrap().recording;
        assert_eq!(thin.rows.len(), 6);
        assert_eq!(thin.rows[1].t_s, 2.0);
    }

    #[test]
    fn glitches_jump_the_rows_they_name() {
        let rec = recording();
        let g = Reframe::Glitches {
            fraction: 0.2,
            size_mm: 12.0,
            seed: 5,
        }
        .apply(&rec)
        .unwrap();
        assert_eq!(g.glitch_rows.len(), 2);
        for (r, (a, b)) in rec.rows.iter().zip(&g.recording.rows).enumerate() {
            let d = (0..3)
                .map(|k| (a.p[k] - b.p[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            let jumped = g.glitch_rows.contains(&r);
            assert!((jumped && (d - 12.0).abs() < 1e-9) || (!jumped && d == 0.0));
        }
    }
}
