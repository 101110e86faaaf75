//! `calibrate` identifies the bending stiffness from tip deflections under known hung
//! weights (the seed paper's identification, recording columns `fx_n,fy_n,fz_n`).

use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
mod common;

use common::{robot, shared};
use ctr_diagnosis::{calibrate, EffectId, Holdout, Options};
use ctr_formats::{Recording, Stiffness};
use std::fmt::Write;

#[test]
fn stiffness_from_hung_weights() {
    let spec = robot("liu2023");
    let user = ModelSpec::from_spec(&spec);
    let mut world = user.clone();
    let truth = [0.8, 1.3];
    world.effects.stiffness = Some(Stiffness {
        factor: truth.to_vec(),
    });
    // runs: a few configurations, each loaded with weights of 0, 2, 5, 10 g along -x
    let mut csv =
        String::from("run,s1_mm,theta1_deg,s2_mm,theta2_deg,x_mm,y_mm,z_mm,fx_n,fy_n,fz_n\n");
    let grams = [0.0, 2.0, 5.0, 10.0];
    let mut k = 0;
    for s1 in [25.0, 45.0, 65.0] {
        for inc in [30.0, 60.0, 90.0] {
            for theta2 in [0.0, 90.0, 180.0] {
                for g in grams {
                    let f = -g * 1e-3 * 9.81;
                    writeln!(csv, "c{k},{s1},0,{},{theta2},0,0,0,{f},0,0", s1 + inc).unwrap();
                }
                k += 1;
            }
        }
    }
    let rec = Recording::read(csv.as_bytes(), "weights.csv", 2).unwrap();
    let runs: Vec<usize> = (0..rec.runs.len()).collect();
    let p = predict(&world, &rec, &runs).unwrap();
    assert_eq!(p.failed, 0);
    let mut rec = rec;
    for (r, p) in rec.rows.iter_mut().zip(&p.p) {
        r.p = *p;
    }
    // the weights move the tip by millimetres: the data can tell the stiffness
    let plain = predict(&user, &rec, &runs).unwrap();
    let moved = rec
        .rows
        .iter()
        .zip(&plain.p)
        .map(|(r, p)| (0..3).map(|a| (r.p[a] - p[a]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    assert!(moved > 1.0, "{moved}");
    let held: Vec<String> = (0..rec.runs.len())
        .step_by(4)
        .map(|i| rec.runs[i].label.clone())
        .collect();
    let opt = Options {
        holdout: Holdout::Runs(held),
        ..Options::default()
    };
    let d = calibrate(&user, &rec, &[EffectId::Stiffness], &opt).unwrap();
    let got = &d.fitted.effects.stiffness.as_ref().unwrap().factor;
    eprintln!(
        "stiffness factors {got:?} (truth {truth:?}); held out {:.2e} mm",
        d.report.final_.heldout_rms_mm
    );
    for i in 0..2 {
        assert!((got[i] - truth[i]).abs() < 1e-3 * truth[i], "{got:?}");
    }
    assert!(d.report.final_.heldout_rms_mm < 1e-3);
}

#[test]
fn clearance_table_from_a_recording() {
    // the seed's "database": the kink as a table over the relative angle, here recovered
    // from the shared clearance recording (truth: a cosine profile, 2.5 deg peak at 205 deg)
    let dir = shared().join("recordings");
    let spec = robot("liu2023");
    let rec = Recording::from_path(&dir.join("dev-clearance.csv"), 2).unwrap();
    let opt = Options {
        clearance_table: Some(24),
        ..Options::default()
    };
    let d = calibrate(
        &ModelSpec::from_spec(&spec),
        &rec,
        &[EffectId::Clearance],
        &opt,
    )
    .unwrap();
    let t = &d.fitted.effects.clearance.as_ref().unwrap().table_deg[0];
    assert_eq!(t.len(), 24);
    let truth = |phi: f64| 2.5 * (1.0 + (phi - 205f64).to_radians().cos()) / 2.0;
    let worst = t
        .iter()
        .enumerate()
        .map(|(k, v)| (v - truth(15.0 * k as f64)).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "table {t:.2?}\nworst {worst:.3} deg; held out {:.3} mm",
        d.report.final_.heldout_rms_mm
    );
    assert!(worst < 0.2, "{worst}");
    let floor = 0.3478;
    assert!(d.report.final_.heldout_rms_mm < 1.05 * floor);
}
