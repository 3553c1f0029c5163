//! `dollop slice` and `dollop config` from the command line: outputs written and readable,
//! `--help` on each, the example config complete and valid.

use dollop::config::Config;
use dollop_host::fixtures::EXAMPLE_CONFIG as EXAMPLE;
use dollop_host::slicer::job_file::read_job;
mod cli_common;

use cli_common::{dollop, manifest};

#[test]
fn slice_writes_job_gcode_and_preview() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (code, out, err) = dollop(
        d,
        &[
            "slice",
            &manifest("designs/logo.png"),
            "--config",
            &manifest("../configs/seed-paper.toml"),
            "--width-mm",
            "30",
            "--rotate",
            "90",
            "--mirror",
            "x",
            "--gcode",
            "logo.gcode",
            "--preview",
            "logo-preview.png",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("wrote logo.dlp") && out.contains("bytes per print segment"),
        "{out}"
    );
    let (h, cmds) = read_job(&d.join("logo.dlp")).unwrap();
    assert_eq!(h.commands as usize, cmds.len());
    assert!(h.bounds_max_um[0] - h.bounds_min_um[0] < 40_000);
    let g = std::fs::read_to_string(d.join("logo.gcode")).unwrap();
    assert!(g.contains("M42 P0 S1") && g.contains("M42 P1 S1") && g.contains("G1 X"));
    let img = image::open(d.join("logo-preview.png")).unwrap();
    assert!(img.width() > 100 && img.height() > 100);
    // Nothing else (no temporary files) in the directory.
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 3);
}

#[test]
fn stl_pair_slices_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let (code, out, err) = dollop(
        dir.path(),
        &[
            "slice",
            &manifest("designs/cube-shell.stl"),
            &manifest("designs/cube-ball.stl"),
            "--config",
            &manifest("../configs/seed-paper.toml"),
            "--layers",
            "5",
            "--out",
            "cube.dlp",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("5 layer(s)"), "{out}");
}

#[test]
fn every_subcommand_of_mine_has_help() {
    let dir = tempfile::tempdir().unwrap();
    for sub in ["slice", "config", "bench"] {
        let (code, out, _) = dollop(dir.path(), &[sub, "--help"]);
        assert_eq!(code, 0, "{sub}");
        assert!(out.contains("Usage: dollop"), "{sub}: {out}");
    }
}

#[test]
fn example_config_prints_parses_and_validates() {
    let dir = tempfile::tempdir().unwrap();
    let (code, out, _) = dollop(dir.path(), &["config", "--example"]);
    assert_eq!(code, 0);
    assert_eq!(out, EXAMPLE);
    let c: Config = toml::from_str(&out).unwrap();
    c.validate::<f64, 4>().unwrap();
    std::fs::write(dir.path().join("m.toml"), &out).unwrap();
    let (code, out, err) = dollop(dir.path(), &["config", "--check", "m.toml"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("advance distance L_adv  2.723 mm"), "{out}");
}

/// Every key the config types have appears in the example, explained (on a comment line
/// or set on a line of its own).
#[test]
fn example_config_documents_every_key() {
    let mut c: Config = toml::from_str(EXAMPLE).unwrap();
    // Fill the optional parts so that serialising shows their keys too.
    c.channel.bead_area_mm2 = Some(0.48);
    c.pause.park_position_mm = Some([0.0, 0.0]);
    c.inlets[0].syringe = Some(dollop::config::SyringeConfig {
        steps_per_mm3: 1.0,
        lag_k: 1.0,
        lag_n: 1.0,
    });
    let v: toml::Value = toml::from_str(&toml::to_string(&c).unwrap()).unwrap();
    let mut keys = Vec::new();
    fn walk(v: &toml::Value, keys: &mut Vec<String>) {
        match v {
            toml::Value::Table(t) => {
                for (k, x) in t {
                    keys.push(k.clone());
                    walk(x, keys);
                }
            }
            toml::Value::Array(a) => a.iter().for_each(|x| walk(x, keys)),
            _ => {}
        }
    }
    walk(&v, &mut keys);
    for variant in [
        "power_law",
        "herschel_bulkley",
        "consistency_pa_sn",
        "flow_index",
        "yield_stress_pa",
    ] {
        keys.push(variant.into());
    }
    assert!(keys.len() > 30, "{keys:?}");
    for k in keys {
        assert!(EXAMPLE.contains(&k), "example config does not mention {k}");
    }
}

#[test]
fn config_without_a_flag_says_what_to_give() {
    let dir = tempfile::tempdir().unwrap();
    let (code, _, err) = dollop(dir.path(), &["config"]);
    assert_eq!(code, 1);
    assert!(err.contains("--example"), "{err}");
}

#[test]
fn markers_are_added_to_a_single_layer_job_and_recognised() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let config = manifest("../configs/seed-paper.toml");
    let logo = manifest("designs/logo.png");
    let args = ["slice", &logo, "--config", &config, "--width-mm", "30"];
    let (code, _, err) = dollop(d, &[&args[..], &["--out", "plain.dlp"]].concat());
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = dollop(
        d,
        &[&args[..], &["--out", "marked.dlp", "--markers"]].concat(),
    );
    assert_eq!(code, 0, "{err}");
    let (_, plain) = read_job(&d.join("plain.dlp")).unwrap();
    let (h, marked) = read_job(&d.join("marked.dlp")).unwrap();
    assert_eq!(h.commands as usize, marked.len());
    // Four beads of two segments each, after the design.
    assert_eq!(marked.len(), plain.len() + 12, "{out}");
    // The design unchanged; the markers after its last bead, before the lift that ends it.
    let last = plain
        .iter()
        .rposition(|c| matches!(c, dollop::Command::Print { .. }))
        .unwrap();
    assert_eq!(marked[..=last], plain[..=last]);
    assert_eq!(marked[last + 13..], plain[last + 1..]);
    let plan = |c: &[dollop::Command]| dollop_host::inspect::design::plan(c, h.start_um, 0.8, 0.0);
    let (p, m) = (plan(&plain), plan(&marked));
    assert!(p.markers.is_none() && m.markers.is_some());
    assert_eq!(p.beads.len(), m.beads.len());
    assert_eq!(p.boundaries, m.boundaries);
    // Several layers: refused in one line, nothing written.
    let (code, _, err) = dollop(
        d,
        &[
            &args[..],
            &["--out", "two.dlp", "--markers", "--layers", "2"],
        ]
        .concat(),
    );
    assert_ne!(code, 0);
    assert!(
        err.contains("--markers") && err.contains("single-layer"),
        "{err}"
    );
    assert!(!d.join("two.dlp").exists());
}

#[test]
fn the_calibration_pattern_is_written_with_markers() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let config = manifest("../configs/seed-paper-valves.toml");
    let (code, out, err) = dollop(d, &["slice", "--calibration-pattern", "--config", &config]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("wrote calibration.dlp"), "{out}");
    let (h, cmds) = read_job(&d.join("calibration.dlp")).unwrap();
    let plan = dollop_host::inspect::design::plan(&cmds, h.start_um, 0.8, 0.0);
    assert!(plan.markers.is_some());
    // Two materials: 7 rows each way plus the row handing over from one to the other,
    // each its own bead; two switches a row but one in the hand-over.
    assert_eq!(plan.beads.len(), 15);
    assert_eq!(plan.boundaries.len(), 29);
    let dirs = |from: u8| plan.boundaries.iter().filter(|b| b.from == from).count();
    assert_eq!((dirs(0), dirs(1)), (15, 14));
    // The first switches lie at seven distances from their rows' starts.
    let mut firsts: Vec<i64> = plan
        .beads
        .iter()
        .filter(|b| b.runs.len() == 3)
        .map(|b| (b.runs[1].0 * 100.0).round() as i64)
        .collect();
    firsts.sort_unstable();
    firsts.dedup();
    assert_eq!(firsts.len(), 7, "{firsts:?}");
    // A design as well is refused.
    let (code, _, err) = dollop(
        d,
        &[
            "slice",
            &manifest("designs/logo.png"),
            "--calibration-pattern",
            "--config",
            &config,
        ],
    );
    assert_ne!(code, 0);
    assert!(err.contains("--calibration-pattern"), "{err}");
}

/// A design filled at a speed its row-end U-turns cannot take within the machine's share
/// (`slicer::row_turns`) is sliced, with a note saying what would; a bundled machine's
/// design gets no such note.
#[test]
fn slicing_too_fast_for_the_row_end_u_turns_says_what_would_do() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read_to_string(manifest("../configs/soft-food-pastes.toml")).unwrap();
    let fast = text.replace("print_speed_mm_s = 10.0", "print_speed_mm_s = 12.0");
    assert_ne!(fast, text);
    std::fs::write(d.join("fast.toml"), fast).unwrap();
    let slice = |config: &str| {
        dollop(
            d,
            &[
                "slice",
                &manifest("designs/random.png"),
                "--config",
                config,
                "--width-mm",
                "38.4",
                "--out",
                "random.dlp",
            ],
        )
    };
    let (code, out, err) = slice("fast.toml");
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("wrote random.dlp"), "{out}");
    // 12^2 / 0.4 = 360 mm/s^2, 72 % of 500; sqrt(0.6 * 500 * 0.4) = 10.95 mm/s.
    assert!(
        err.contains("dollop: note: the row-end U-turns (0.40 mm radius, half the 0.80 mm pitch) take 72 % of the X/Y limit at 12.0 mm/s")
            && err.contains("print_speed_mm_s at most 11.0, or an X/Y limit of at least 600 mm/s^2"),
        "{err}"
    );
    let (code, _, err) = slice(&manifest("../configs/soft-food-pastes.toml"));
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("U-turns"), "{err}");
}
