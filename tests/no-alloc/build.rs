//! Build script of the firmware check:
//!
//! - puts `memory.x` (the mps2-an386 memory map) where cortex-m-rt's `link.x` finds it
//!   and links the binary with `link.x`;
//! - writes `reference_data.rs` into `OUT_DIR`: the tubes of the shared robot file
//!   `robots/nitinol3.toml` and the joints of its reference tables
//!   `reference/nitinol3-{rigid,torsion,gravity}.csv`, as Rust constants written in
//!   shortest round-trip form, so the firmware solves exactly the `f64` inputs the host
//!   (`ctr-cli fk` on the same files) solves.
//!
//! The data are read from `tests/data/shared` (or `$CTR_SHARED_DATA`, as the tests).
//! A file that cannot be read or a line that cannot be parsed stops the build with the
//! file, line and field named.

use std::env;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

/// The robot whose reference tables the firmware solves (3 tubes).
const ROBOT: &str = "nitinol3";
/// The reference tables solved, by model (file `reference/<robot>-<model>.csv`).
const MODELS: [&str; 3] = ["rigid", "torsion", "gravity"];
/// Tubes of the robot (the firmware's solver is built for this count).
const N_TUBES: usize = 3;
/// The tube fields the core takes, in `TubeRow` order, and whether each is required.
const TUBE_FIELDS: [(&str, bool); 10] = [
    ("outer_diameter_mm", true),
    ("inner_diameter_mm", true),
    ("length_mm", true),
    ("curved_length_mm", true),
    ("youngs_modulus_mpa", true),
    ("poisson_ratio", true),
    ("curvature_radius_mm", false),
    ("bending_stiffness_nmm2", false),
    ("torsional_stiffness_nmm2", false),
    ("density_kg_m3", false),
];

fn main() {
    let manifest = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let out = PathBuf::from(env::var("OUT_DIR").expect("set by cargo"));

    // the memory map for cortex-m-rt's link.x
    fs::copy(manifest.join("memory.x"), out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    if env::var("TARGET").is_ok_and(|t| t.starts_with("thumb")) {
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
    }

    println!("cargo:rerun-if-env-changed=CTR_SHARED_DATA");
    let shared = env::var_os("CTR_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| manifest.join("../data/shared"));
    let mut code = String::new();
    let robot = shared.join(format!("robots/{ROBOT}.toml"));
    write_tubes(&mut code, &robot);
    let mut tables = String::new();
    for model in MODELS {
        let csv = shared.join(format!("reference/{ROBOT}-{model}.csv"));
        let name = format!("JOINTS_{}", model.to_uppercase());
        write_joints(&mut code, &name, &csv);
        let _ = writeln!(tables, "    Table {{ model: {model:?}, joints: &{name} }},");
    }
    let _ = writeln!(code, "/// The reference tables, one a model.");
    let _ = writeln!(
        code,
        "pub const TABLES: [Table; {}] = [\n{tables}];",
        MODELS.len()
    );
    fs::write(out.join("reference_data.rs"), code).expect("write reference_data.rs");
}

/// Fails the build naming the file (and line).
fn fail(file: &Path, line: Option<usize>, message: &str) -> ! {
    match line {
        Some(l) => panic!("{}:{l}: {message}", file.display()),
        None => panic!("{}: {message}", file.display()),
    }
}

fn read(file: &Path) -> String {
    println!("cargo:rerun-if-changed={}", file.display());
    fs::read_to_string(file).unwrap_or_else(|e| fail(file, None, &format!("cannot read: {e}")))
}

/// The `[[tube]]` tables of a robot file (flat `key = value` lines; the reference robots
/// are written so). Any other table but `[limits]`-style metadata would change the
/// model the host solves, so `[model...]` tables stop the build.
fn write_tubes(code: &mut String, file: &Path) {
    let text = read(file);
    let mut tubes: Vec<Vec<Option<f64>>> = Vec::new();
    let mut in_tube = false;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        if line.starts_with('[') {
            in_tube = line == "[[tube]]";
            if in_tube {
                tubes.push(vec![None; TUBE_FIELDS.len()]);
            } else if line.starts_with("[model") {
                fail(
                    file,
                    Some(i + 1),
                    "the firmware check solves the plain mechanics: no [model] tables",
                );
            }
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            fail(file, Some(i + 1), "expected `key = value`");
        };
        let key = key.trim();
        let Some(field) = TUBE_FIELDS.iter().position(|(k, _)| *k == key) else {
            continue; // name, or a top-level key
        };
        if !in_tube {
            continue;
        }
        let v: f64 = value.trim().parse().unwrap_or_else(|_| {
            fail(
                file,
                Some(i + 1),
                &format!("{key}: {:?} is not a number", value.trim()),
            )
        });
        if let Some(tube) = tubes.last_mut() {
            tube[field] = Some(v);
        }
    }
    if tubes.len() != N_TUBES {
        fail(
            file,
            None,
            &format!("{} tubes, the firmware expects {N_TUBES}", tubes.len()),
        );
    }
    let _ = writeln!(
        code,
        "/// The tubes of `{}`, outermost first.",
        file.display()
    );
    let _ = writeln!(code, "pub const TUBES: [TubeRow; {N_TUBES}] = [");
    for (t, tube) in tubes.iter().enumerate() {
        let _ = write!(code, "    TubeRow {{");
        for ((key, required), value) in TUBE_FIELDS.iter().zip(tube) {
            let v = match (value, required) {
                (Some(v), true) => format!("{v:?}"),
                (Some(v), false) => format!("Some({v:?})"),
                (None, false) => "None".to_owned(),
                (None, true) => fail(file, None, &format!("tube {}: {key} is missing", t + 1)),
            };
            let _ = write!(code, " {key}: {v},");
        }
        let _ = writeln!(code, " }},");
    }
    let _ = writeln!(code, "];");
}

/// The joint columns `s1_mm,theta1_deg,...` of a reference table, as `[f64; 2 N]` rows.
fn write_joints(code: &mut String, name: &str, file: &Path) {
    let text = read(file);
    let mut lines = text.lines().enumerate();
    let header: Vec<&str> = lines
        .next()
        .map_or(Vec::new(), |(_, h)| h.split(',').collect());
    let columns: Vec<usize> = (1..=N_TUBES)
        .flat_map(|i| [format!("s{i}_mm"), format!("theta{i}_deg")])
        .map(|c| {
            header
                .iter()
                .position(|h| h.trim() == c)
                .unwrap_or_else(|| fail(file, Some(1), &format!("no column {c}")))
        })
        .collect();
    let mut rows = String::new();
    let mut count = 0;
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').collect();
        rows.push_str("    [");
        for &c in &columns {
            let cell = cells.get(c).map_or("", |s| s.trim());
            let v: f64 = cell.parse().unwrap_or_else(|_| {
                fail(
                    file,
                    Some(i + 1),
                    &format!("column {}: {cell:?} is not a number", header[c]),
                )
            });
            let _ = write!(rows, "{v:?}, ");
        }
        rows.push_str("],\n");
        count += 1;
    }
    let _ = writeln!(code, "/// The joints of `{}`.", file.display());
    let _ = writeln!(
        code,
        "pub const {name}: [[f64; {}]; {count}] = [\n{rows}];",
        2 * N_TUBES
    );
}
