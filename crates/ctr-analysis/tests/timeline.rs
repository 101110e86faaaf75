//! `latency` and its composition with friction follow the conventions of the shared
//! recordings: with the true values the model explains them down to the noise floor.
use ctr_analysis::model::ModelSpec;
use ctr_analysis::timeline::{actual_joints, TimeEffects};
use ctr_core::Model;
use ctr_formats::RobotSpec;

mod common;
use common::shared;

/// One run: times, commanded joints (file order), measured tips.
type Run = (Vec<f64>, Vec<Vec<f64>>, Vec<[f64; 3]>);

struct Rec {
    runs: Vec<Run>,
}

fn read(id: &str, n: usize) -> (Rec, f64) {
    let dir = shared().join("recordings");
    let mut rdr = csv::Reader::from_path(dir.join(format!("{id}.csv"))).unwrap();
    let header: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let mut runs: Vec<(String, Run)> = Vec::new();
    for r in rdr.records() {
        let r = r.unwrap();
        let f = |name: &str| r[col(name)].parse::<f64>().unwrap();
        let label = r[col("run")].to_string();
        if runs.last().map(|x| x.0 != label).unwrap_or(true) {
            runs.push((label, (vec![], vec![], vec![])));
        }
        let run = &mut runs.last_mut().unwrap().1;
        run.0.push(f("t_s"));
        run.1.push(
            (1..=n)
                .flat_map(|i| [f(&format!("s{i}_mm")), f(&format!("theta{i}_deg"))])
                .collect(),
        );
        run.2.push([f("x_mm"), f("y_mm"), f("z_mm")]);
    }
    // the one number needed from the truth file, without a JSON dependency
    let truth = std::fs::read_to_string(dir.join(format!("{id}.truth.json"))).unwrap();
    let key = "\"noise_floor_rms_mm\":";
    let at = truth.find(key).unwrap() + key.len();
    let floor: f64 = truth[at..]
        .trim_start()
        .split([',', '\n', '}'])
        .next()
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    (
        Rec {
            runs: runs.into_iter().map(|r| r.1).collect(),
        },
        floor,
    )
}

fn rms(rec: &Rec, robot: &RobotSpec, effects: &TimeEffects) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for (t, q, p) in &rec.runs {
        for (actual, measured) in actual_joints(t, q, effects).iter().zip(p) {
            let tip = ModelSpec::plain(&robot.robot, Model::Torsion)
                .fk(actual)
                .unwrap()
                .position;
            sum += (0..3).map(|k| (tip[k] - measured[k]).powi(2)).sum::<f64>();
            count += 1;
        }
    }
    (sum / count as f64).sqrt()
}

#[test]
fn latency_convention() {
    let robot = RobotSpec::from_path(&shared().join("robots/liu2023.toml")).unwrap();
    let (rec, floor) = read("dev-latency", 2);
    let mut effects = TimeEffects::none(2);
    let without = rms(&rec, &robot, &effects);
    effects.latency_s = 0.75;
    let with = rms(&rec, &robot, &effects);
    eprintln!("latency: {with:.4} mm with, {without:.4} without, floor {floor:.4}");
    assert!(with <= 1.02 * floor);
    assert!(without > 3.0 * floor);
}

#[test]
fn friction_through_the_timeline() {
    let robot = RobotSpec::from_path(&shared().join("robots/liu2023.toml")).unwrap();
    let (rec, floor) = read("dev-friction", 2);
    let mut effects = TimeEffects::none(2);
    effects.rotation_play_deg = vec![8.0];
    let with = rms(&rec, &robot, &effects);
    eprintln!("friction: {with:.4} mm with, floor {floor:.4}");
    assert!(with <= 1.02 * floor);
}
