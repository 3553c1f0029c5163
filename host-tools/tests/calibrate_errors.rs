//! Bad input for `dollop calibrate`: empty and one-row CSVs, non-numeric cells, negative
//! shear rates, short rows, missing files, unclear columns and unusable options each give
//! a typed error whose one-line message names the file (and line and column).

mod calibrate_common;

use calibrate_common::*;
use dollop_host::calibrate::rheology::{calibrate, Options};
use dollop_host::calibrate::CalError;

fn rheology_error(text: &str) -> (CalError, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "data.csv", text);
    let e = calibrate(&path, Options::default()).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("data.csv"), "{msg}");
    assert_eq!(msg.lines().count(), 1, "{msg}");
    (e, msg)
}

#[test]
fn an_empty_file_has_no_data_rows() {
    let (e, _) = rheology_error("");
    assert!(matches!(e, CalError::Empty { .. }));
    let (e, _) = rheology_error("shear_rate_1_s,shear_stress_pa\n# nothing yet\n");
    assert!(matches!(e, CalError::Empty { .. }));
}

#[test]
fn one_row_is_too_few() {
    let (e, msg) = rheology_error("shear_rate_1_s,shear_stress_pa\n1,10\n");
    assert!(matches!(e, CalError::TooFewRows { rows: 1, .. }), "{msg}");
}

#[test]
fn a_non_numeric_cell_names_line_and_column() {
    let (e, msg) = rheology_error("shear_rate_1_s,shear_stress_pa\n1,10\n2,19\n3,abc\n4,35\n");
    assert!(matches!(e, CalError::NotNumeric { line: 4, .. }), "{msg}");
    assert!(
        msg.ends_with("data.csv: line 4, column 2 (shear_stress_pa): \"abc\" is not a number"),
        "{msg}"
    );
}

#[test]
fn a_negative_shear_rate_is_refused() {
    let (e, msg) = rheology_error("shear_rate_1_s,shear_stress_pa\n1,10\n-2,19\n3,27\n4,35\n");
    assert!(matches!(e, CalError::OutOfRange { line: 3, .. }), "{msg}");
    assert!(
        msg.contains("line 3, column 1 (shear_rate_1_s): -2 must be above zero"),
        "{msg}"
    );
}

#[test]
fn a_short_row_is_refused() {
    let (e, msg) = rheology_error("1,10\n2,19\n3\n4,35\n");
    assert!(matches!(e, CalError::MissingCells { line: 3, .. }), "{msg}");
}

#[test]
fn a_header_that_does_not_say_what_it_is_asks_for_kind() {
    let (e, msg) = rheology_error("x,y\n1,10\n2,19\n3,27\n");
    // The library names no flag: `dollop calibrate` says `--kind`, the dashboard points
    // at its kind list.
    assert!(matches!(e, CalError::KindUnclear { .. }), "{msg}");
    assert!(
        msg.contains("rotational or oscillatory") && !msg.contains("--"),
        "{msg}"
    );
}

#[test]
fn a_missing_file_is_a_read_error() {
    let e = calibrate(
        std::path::Path::new("/nonexistent/rheo.csv"),
        Options::default(),
    )
    .unwrap_err();
    assert!(matches!(e, CalError::Read { .. }));
    assert!(
        e.to_string()
            .starts_with("/nonexistent/rheo.csv: cannot read"),
        "{e}"
    );
}

#[test]
fn every_subcommand_reports_a_bad_file_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let bad = write(dir.path(), "bad.csv", "a,b\n1,x\n");
    let empty = write(dir.path(), "empty.csv", "");
    let cfg = root().join("configs/seed-paper.toml");
    for args in [
        vec!["rheology", bad.to_str().unwrap()],
        vec![
            "flow",
            empty.to_str().unwrap(),
            "--config",
            cfg.to_str().unwrap(),
        ],
        vec!["lag", bad.to_str().unwrap()],
        vec![
            "syringe",
            "--diameter",
            "10",
            "--lead",
            "1",
            "--lag",
            empty.to_str().unwrap(),
        ],
    ] {
        let e = run(&args).unwrap_err().to_string();
        assert!(
            e.contains("bad.csv") || e.contains("empty.csv"),
            "{args:?}: {e}"
        );
    }
}

#[test]
fn a_config_that_does_not_validate_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let seed = std::fs::read_to_string(root().join("configs/seed-paper.toml")).unwrap();
    let cfg = write(
        dir.path(),
        "machine.toml",
        &seed.replace("nozzle_diameter_mm = 0.8", "nozzle_diameter_mm = -0.8"),
    );
    let e = run(&[
        "flow",
        data().join("flow-two-pastes.csv").to_str().unwrap(),
        "--density",
        "1.05",
        "--config",
        cfg.to_str().unwrap(),
    ])
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("machine.toml: channel.nozzle_diameter_mm"),
        "{e}"
    );
}

#[test]
fn out_into_a_missing_folder_is_a_write_error() {
    let e = run(&[
        "rheology",
        data().join("rheology-puree.csv").to_str().unwrap(),
        "--out",
        "/nonexistent/dir/frag.toml",
    ])
    .unwrap_err();
    assert!(matches!(e, CalError::Write { .. }), "{e}");
    assert!(e.to_string().contains("/nonexistent/dir/frag.toml"));
}

#[test]
fn the_command_names_its_flags_where_the_library_names_options() {
    let dir = tempfile::tempdir().unwrap();
    let header = write(dir.path(), "x.csv", "x,y\n1,10\n2,19\n3,27\n");
    let mass = write(
        dir.path(),
        "mass.csv",
        "pressure_kpa,flow_g_min,material\n1,0.1,a\n2,0.2,a\n3,0.3,a\n",
    );
    let cases: [(Vec<&str>, &str); 6] = [
        (
            vec!["syringe", "--diameter", "10"],
            "--diameter and --lead go together (syringe bore and lead screw)",
        ),
        (
            vec!["syringe", "--mg-per-step", "0.1"],
            "--mg-per-step needs --density (g/ml) to become a volume",
        ),
        (
            vec!["syringe"],
            "give the syringe geometry (--diameter and --lead) or a measurement (--mg-per-step and --density)",
        ),
        (
            vec!["syringe", "--diameter", "10", "--lead=-1"],
            "--lead -1 must be above zero",
        ),
        (
            vec!["rheology", header.to_str().unwrap()],
            "say --kind rotational or --kind oscillatory",
        ),
        (
            vec!["flow", mass.to_str().unwrap()],
            "flows are in g/min: say --density G_PER_ML to turn them into volume",
        ),
    ];
    for (args, want) in cases {
        let e = run(&args).unwrap_err().to_string();
        assert!(e.contains(want), "{args:?}: {e}");
    }
}
