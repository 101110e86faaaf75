//! Robot TOML, joint CSV, tip CSV and atomic output.

use ctr_core::{Model, Status};
use ctr_formats::{canonical_quaternion, AnyRobot, ErrorKind, FkResult};
use ctr_formats::{
    format_float, tip_header, AtomicFile, Effects, JointTable, ModelKind, RobotFile, RobotSpec,
    TipWriter, TubeLimits,
};
use std::io::Write;
use std::path::{Path, PathBuf};

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../data")
        .join(rel)
}

fn liu2023() -> RobotSpec {
    RobotSpec::from_path(&data("robots/liu2023.toml")).unwrap()
}

/// A two-tube robot file with named tubes (the error tests name its lines and columns).
const BASE: &str = include_str!("fixtures/base-robot.toml");

fn err(text: &str) -> String {
    RobotSpec::from_toml_str(text, "robot.toml")
        .unwrap_err()
        .to_string()
}

#[test]
fn project_robots_load_with_their_tube_counts() {
    for (name, n) in [("liu2023", 2), ("nitinol2", 2), ("nitinol3", 3)] {
        let spec = RobotSpec::from_path(&data(&format!("robots/{name}.toml"))).unwrap();
        assert_eq!(spec.robot.n_tubes(), n, "{name}");
        assert_eq!(spec.name.as_deref(), Some(name));
        assert_eq!(spec.model, Model::Torsion, "no [model] means torsion");
        assert_eq!(spec.limits, None);
    }
}

#[test]
fn robot_round_trips_through_toml_bit_for_bit() {
    for name in ["liu2023", "nitinol2", "nitinol3"] {
        let spec = RobotSpec::from_path(&data(&format!("robots/{name}.toml"))).unwrap();
        let text = spec.to_toml();
        let back = RobotSpec::from_toml_str(&text, "back.toml").unwrap();
        assert_eq!(back, spec, "{name}:\n{text}");
        // and the text is stable
        assert_eq!(back.to_toml(), text);
    }
}

#[test]
fn fitted_robot_with_model_and_limits_round_trips() {
    let mut spec = liu2023();
    let mut params = spec.robot.tube_params();
    params[0].youngs_modulus_mpa = 151.234_567_890_123_4;
    params[1].curvature_radius_mm = Some(0.1 + 0.2);
    params[1].bending_stiffness_nmm2 = Some(1.0e-7 / 3.0);
    spec.robot = AnyRobot::new(&params).unwrap();
    spec.model = Model::Rigid;
    spec.limits = Some(vec![
        TubeLimits {
            s_mm: Some([20.0, 70.0]),
            increment_mm: None,
            theta_deg: Some([-180.0, 180.0]),
        },
        TubeLimits {
            s_mm: None,
            increment_mm: Some([25.0, 95.0]),
            theta_deg: None,
        },
    ]);
    let text = spec.to_toml();
    assert!(text.contains("[model]"), "{text}");
    assert!(text.contains("kind = \"rigid\""), "{text}");
    assert!(text.contains("[[limits.tube]]"), "{text}");
    let back = RobotSpec::from_toml_str(&text, "fitted.toml").unwrap();
    assert_eq!(back, spec, "{text}");
}

#[test]
fn robot_file_with_effects_round_trips_as_a_file() {
    let text = format!(
        "{BASE}\n[model]\nkind = \"rigid\"\n\n[model.effects]\nlatency = {{ tau_s = 0.1 }}\n\
         friction = {{ rotation_play_deg = [2.0] }}\nclearance = {{ max_deflection_deg = [2.5], peak_deg = [205.0] }}\n\
         registration = {{ translation_mm = [1.0, 2.0, 3.0], rotation_axis = [0.0, 1.0, 0.0], rotation_deg = 2.0 }}\n\
         stiffness = {{ factor = [1.0, 1.2] }}\nsensor_offset = {{ offset_mm = [0.0, 0.0, -2.0] }}\n"
    );
    let file = RobotFile::parse(&text, "r.toml").unwrap();
    let model = file.model.as_ref().unwrap();
    assert_eq!(model.kind, ModelKind::Rigid);
    assert_eq!(
        model.effects.present(),
        [
            "latency",
            "friction",
            "clearance",
            "stiffness",
            "sensor_offset",
            "registration"
        ]
    );
    let again = RobotFile::parse(&file.to_toml(), "again.toml").unwrap();
    assert_eq!(again, file);
    let spec = file.validate("r.toml").unwrap();
    assert_eq!(spec.effects, model.effects);
    let back = RobotSpec::from_toml_str(&spec.to_toml(), "fitted.toml").unwrap();
    assert_eq!(back, spec);
    assert!(Effects::default().is_empty());
    // gravity without densities is refused with its key
    let g = format!("{BASE}\n[model.effects]\ngravity = {{ direction_W = [-1.0, 0.0, 0.0] }}\n");
    let file = RobotFile::parse(&g, "r.toml").unwrap();
    assert_eq!(
        file.model.unwrap().effects.gravity.unwrap().g_m_s2,
        9.81,
        "default g"
    );
}

#[test]
fn model_kind_is_read() {
    let spec =
        RobotSpec::from_toml_str(&format!("{BASE}\n[model]\nkind = \"rigid\"\n"), "r").unwrap();
    assert_eq!(spec.model, Model::Rigid);
    let spec = RobotSpec::from_toml_str(&format!("{BASE}\n[model]\n"), "r").unwrap();
    assert_eq!(spec.model, Model::Torsion);
}

#[test]
fn robot_errors_name_file_line_column_and_field() {
    assert_eq!(
        err(&BASE.replace("outer_diameter_mm = 4.5", "outer_diameter_mm = 5.0")),
        "robot.toml:15:21: tube 2: outer_diameter_mm = 5 does not fit inside tube 1's inner_diameter_mm = 4.9"
    );
    assert!(err(&BASE.replace("youngs_modulus_mpa = 150.0", "youngs_modulus = 150.0"))
        .starts_with("robot.toml:10:1: tube 1: unknown field `youngs_modulus`, expected one of `name`, `outer_diameter_mm`"));
    assert_eq!(
        err(&BASE.replace("length_mm = 174.0\n", "")),
        "robot.toml:13:1: tube 2: missing field `length_mm`"
    );
    assert_eq!(
        err(&BASE.replace("poisson_ratio = 0.41\n\n", "poisson_ratio = \"x\"\n\n")),
        "robot.toml:11:17: tube 1: poisson_ratio: invalid type: string \"x\", expected f64"
    );
    assert_eq!(
        err(&format!(
            "{BASE}\n[model.effects]\ngravity = {{ direction_W = [0.0, 0.0, -1.0] }}\n"
        )),
        "robot.toml:24:11: model.effects.gravity: every tube needs density_kg_m3 to weigh it"
    );
    assert_eq!(
        err(&format!("{BASE}\n[model.effects]\nfriction = {{ rotation_play_deg = [1.0, 2.0] }}\n")),
        "robot.toml:24:34: model.effects.friction.rotation_play_deg: 2 values, wanted 1 (one per neighbouring pair of tubes)"
    );
    assert_eq!(
        err(&format!(
            "{BASE}\n[model.effects.stiffness]\nfactor = [1.0, -2.0]\n"
        )),
        "robot.toml:24:10: model.effects.stiffness.factor: -2 must be positive"
    );
    assert_eq!(
        err(&format!(
            "{BASE}\n[[limits.tube]]\ns_mm = [1.0, 2.0, 3.0]\n[[limits.tube]]\n"
        )),
        "robot.toml:24:8: limits.tube 1: s_mm: invalid length 3, expected an array of 2 numbers"
    );
    assert_eq!(
        err("tube = []\n"),
        "robot.toml: a robot has 1 to 4 tubes, not 0"
    );
    // file-level validation has no text to point into
    let file = RobotFile::parse(&BASE.replace("= 0.41", "= 0.6"), "r.toml").unwrap();
    assert_eq!(
        file.validate("r.toml").unwrap_err().to_string(),
        "r.toml: tube 1: poisson_ratio = 0.6 must lie in [0, 0.5)"
    );
}

#[test]
fn limits_violation() {
    let l = TubeLimits {
        s_mm: None,
        increment_mm: Some([25.0, 95.0]),
        theta_deg: Some([-90.0, 90.0]),
    };
    assert_eq!(l.violation(50.0, 0.0, 30.0), Some(("increment_mm", 20.0)));
    assert_eq!(l.violation(60.0, 91.0, 30.0), Some(("theta_deg", 91.0)));
    assert_eq!(l.violation(60.0, 90.0, 30.0), None);
}

fn read(csv: &str) -> Result<JointTable, ctr_formats::Error> {
    JointTable::read(csv.as_bytes(), "j.csv", &liu2023().robot)
}

#[test]
fn joint_table_keeps_raw_fields_and_parses_trimmed_numbers() {
    let t = read("label, s1_mm ,theta1_deg,s2_mm,theta2_deg,note\n\"a, b\", 30.50 ,-0,80,1e1,\"say \"\"hi\"\"\"\n\nc,40,90,100,-45,\n").unwrap();
    assert_eq!(t.len(), 2);
    assert_eq!(t.n_tubes(), 2);
    assert_eq!(t.header()[1], " s1_mm ");
    assert_eq!(t.line(0), 2);
    assert_eq!(t.line(1), 4, "blank lines count");
    assert_eq!(
        t.fields(0).collect::<Vec<_>>(),
        ["a, b", " 30.50 ", "-0", "80", "1e1", "say \"hi\""]
    );
    assert_eq!(t.joints(0), [30.5, -0.0, 80.0, 10.0]);
    assert_eq!(t.joints(1), [40.0, 90.0, 100.0, -45.0]);
    assert_eq!(t.all_joints().len(), 8);
}

#[test]
fn joint_columns_may_come_in_any_order() {
    let t = read("theta2_deg,s2_mm,theta1_deg,s1_mm\n1,80,2,30\n").unwrap();
    assert_eq!(t.joints(0), [30.0, 2.0, 80.0, 1.0]);
}

#[test]
fn header_only_is_an_empty_table() {
    let t = read("s1_mm,theta1_deg,s2_mm,theta2_deg\n").unwrap();
    assert!(t.is_empty());
}

#[test]
fn joint_table_errors() {
    let e = |csv: &str| read(csv).unwrap_err().to_string();
    assert_eq!(
        e(""),
        "j.csv: empty file, expected a header with s1_mm,theta1_deg,s2_mm,theta2_deg"
    );
    assert_eq!(
        e("s1_mm,theta1_deg,s2mm,theta2_deg\n"),
        "j.csv:1: missing column s2_mm (found \"s2mm\": did you mean s2_mm?)"
    );
    assert_eq!(
        e("s1_mm,theta1_deg,s2_mm,theta2_deg\n30,0,80,0\n30,0,80,abc\n"),
        "j.csv:3: column theta2_deg: \"abc\" is not a number"
    );
    assert_eq!(
        e("s1_mm,theta1_deg,s2_mm,theta2_deg\n30,nan,80,0\n"),
        "j.csv:2: column theta1_deg: \"nan\" is not a finite number"
    );
    assert_eq!(
        e("s1_mm,theta1_deg,s2_mm,theta2_deg\r\n\r\n30,0,20,0\r\n"),
        "j.csv:3: s2_mm = 20 must be >= s1_mm = 30 (inner tubes reach at least as far as outer ones)"
    );
    assert_eq!(
        e("s1_mm,theta1_deg,s2_mm,theta2_deg\n30,0,80\n"),
        "j.csv:2: row has 3 fields, the header has 4"
    );
    assert_eq!(
        e("s1_mm,theta1_deg,s2_mm,theta2_deg,theta3_deg\n30,0,80,0,0\n"),
        "j.csv:1: column theta3_deg: the robot has 2 tubes"
    );
}

#[test]
fn tip_header_refuses_clashes() {
    let h: Vec<String> = ["s1_mm", "status"].map(String::from).to_vec();
    assert!(tip_header(&h, false).is_ok());
    assert!(matches!(
        tip_header(&h, true),
        Err(ErrorKind::OutputColumnClash { name }) if name == "status"
    ));
}

#[test]
fn tip_writer_floats_parse_back_bit_for_bit() {
    let values = [
        0.1 + 0.2,
        -0.0,
        1e-300,
        f64::MAX,
        f64::MIN_POSITIVE,
        std::f64::consts::PI,
        -123456.789e10,
        5e-324,
    ];
    for v in values {
        let back: f64 = format_float(v).parse().unwrap();
        assert_eq!(back.to_bits(), v.to_bits(), "{v:e}");
    }
    let fk = FkResult {
        position: [values[0], values[1], values[2]],
        quaternion: [values[3], values[4], values[5], values[6]],
        status: Status::IterationLimit,
        residual_per_mm: values[7],
        iterations: 30,
        softest_mode: 0.5,
        stability_margin: 0.5,
    };
    let header = tip_header(&["label".into()], true).unwrap();
    let mut w = TipWriter::new(Vec::new(), &header, true).unwrap();
    w.write_row(["a \"quoted\", label"], &fk).unwrap();
    let out = String::from_utf8(w.finish().unwrap()).unwrap();
    let mut rdr = csv::Reader::from_reader(out.as_bytes());
    assert_eq!(
        rdr.headers().unwrap().iter().collect::<Vec<_>>(),
        [
            "label",
            "x_mm",
            "y_mm",
            "z_mm",
            "qw",
            "qx",
            "qy",
            "qz",
            "status",
            "residual_per_mm"
        ]
    );
    let rec = rdr.records().next().unwrap().unwrap();
    assert_eq!(&rec[0], "a \"quoted\", label");
    for (i, v) in values.iter().enumerate().take(7) {
        assert_eq!(rec[i + 1].parse::<f64>().unwrap().to_bits(), v.to_bits());
    }
    assert_eq!(&rec[8], "iteration_limit");
    assert_eq!(rec[9].parse::<f64>().unwrap(), 5e-324);
}

#[test]
fn quaternion_sign_is_canonical() {
    use nalgebra::{Quaternion, UnitQuaternion, Vector3};
    for angle in [0.0, 1.0, 3.0, -3.0, std::f64::consts::PI] {
        let q = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), angle);
        let neg = UnitQuaternion::new_unchecked(-q.into_inner());
        let a = canonical_quaternion(&q);
        assert_eq!(a, canonical_quaternion(&neg), "{angle}");
        assert!(a[0] >= 0.0);
    }
    let q = UnitQuaternion::new_unchecked(Quaternion::new(0.0, 0.0, -1.0, 0.0));
    assert_eq!(canonical_quaternion(&q), [0.0, 0.0, 1.0, 0.0]);
}

#[test]
fn atomic_file_replaces_only_on_commit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tips.csv");
    std::fs::write(&path, "old\n").unwrap();

    let mut f = AtomicFile::create(&path).unwrap();
    f.write_all(b"half-written").unwrap();
    drop(f); // a failed run
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "temp file removed"
    );

    let mut f = AtomicFile::create(&path).unwrap();
    f.write_all(b"new\n").unwrap();
    f.commit().unwrap();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "new\n");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

    let missing = dir.path().join("nope").join("tips.csv");
    let e = AtomicFile::create(&missing).err().unwrap();
    assert!(matches!(e.kind(), ErrorKind::OutputDirectory { .. }), "{e}");
}
