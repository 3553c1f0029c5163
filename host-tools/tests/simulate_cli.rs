//! `dollop simulate` end to end: trace CSV format and sampling, heatmap, report, and bad
//! input (missing or corrupt job, invalid config) refused with one line, nothing left.

use dollop_host::slicer::job_file;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn dollop() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dollop"))
}

/// A small two-material job written as a .dlp for the seed printhead with real valves.
fn write_job(dir: &Path) -> (PathBuf, PathBuf) {
    let cfg_path = repo().join("configs/seed-paper-valves.toml");
    let cfg: dollop::Config = toml::from_str(&std::fs::read_to_string(&cfg_path).unwrap()).unwrap();
    let fill = dollop_sim::designs::Fill {
        origin_mm: [20.0, 20.0],
        width_mm: 6.0,
        rows: 3,
        pitch_mm: 0.8,
        layers: 1,
        layer_mm: 0.6,
        cell_mm: 0.1,
        prime_mm: 8.0,
    };
    let job = dollop_sim::designs::boustrophedon(&fill, dollop_sim::designs::stripes(1.5));
    let body = job_file::encode_body(&job.commands);
    let header = job_file::header_for(
        &job.commands,
        &body,
        job.start_um,
        job.initial_material,
        &cfg,
    );
    let path = dir.join("stripes.dlp");
    job_file::write_job(&path, &header, &body).unwrap();
    (path, cfg_path)
}

#[test]
fn trace_heatmap_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let (job, cfg) = write_job(dir.path());
    let trace = dir.path().join("trace.csv");
    let heat = dir.path().join("plate.png");
    let out = dollop()
        .args(["simulate"])
        .arg(&job)
        .arg("--config")
        .arg(&cfg)
        .arg("--trace")
        .arg(&trace)
        .arg("--heatmap")
        .arg(&heat)
        .arg("--report")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for key in [
        "print time",
        "material switches",
        "boundaries",
        "bead section",
        "peak step rate",
    ] {
        assert!(stdout.contains(key), "report lacks {key}: {stdout}");
    }
    let worst: f64 = stdout
        .lines()
        .find(|l| l.starts_with("boundaries"))
        .and_then(|l| l.split("worst ").nth(1))
        .and_then(|w| w.split(' ').next())
        .and_then(|w| w.parse().ok())
        .expect("worst boundary figure");
    assert!(worst <= 0.05, "{stdout}");

    let csv = std::fs::read_to_string(&trace).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("t_s,x_mm,y_mm,z_mm,valve_mask"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect())
        .collect();
    assert!(rows.len() > 1000);
    let mut masks = std::collections::BTreeSet::new();
    for w in rows.windows(2) {
        assert_eq!(w[0].len(), 5);
        let gap = w[1][0] - w[0][0];
        assert!(gap > 0.0 && gap <= 0.001 + 1e-9, "rows {gap} s apart");
        masks.insert(w[1][4] as u32);
    }
    assert!(masks.contains(&0b01) && masks.contains(&0b10) && masks.contains(&0));

    let img = image::open(&heat).unwrap().to_rgb8();
    assert!(img.width() > 100 && img.height() > 20);
    // Both materials' colours are on the plate.
    let has = |c: [u8; 3]| img.pixels().any(|p| p.0 == c);
    assert!(
        has(dollop_host::cmd::simulate::PALETTE[0]) && has(dollop_host::cmd::simulate::PALETTE[1])
    );
}

#[test]
fn bad_inputs_are_refused_in_one_line_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (job, cfg) = write_job(dir.path());
    let trace = dir.path().join("trace.csv");
    let check = |args: &[&std::ffi::OsStr], needle: &str| {
        let out = dollop().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "accepted: {args:?}");
        assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
        assert!(err.contains(needle), "{err} should name {needle}");
        assert!(!trace.exists(), "a trace was left behind");
    };
    let missing = dir.path().join("nope.dlp");
    check(
        &[
            "simulate".as_ref(),
            missing.as_os_str(),
            "--config".as_ref(),
            cfg.as_os_str(),
            "--trace".as_ref(),
            trace.as_os_str(),
        ],
        "nope.dlp",
    );
    let corrupt = dir.path().join("corrupt.dlp");
    let mut bytes = std::fs::read(&job).unwrap();
    let n = bytes.len();
    bytes[n - 3] ^= 0x55;
    std::fs::write(&corrupt, bytes).unwrap();
    check(
        &[
            "simulate".as_ref(),
            corrupt.as_os_str(),
            "--config".as_ref(),
            cfg.as_os_str(),
            "--trace".as_ref(),
            trace.as_os_str(),
        ],
        "corrupt.dlp",
    );
    let bad_cfg = dir.path().join("bad.toml");
    let text = std::fs::read_to_string(&cfg)
        .unwrap()
        .replace("nozzle_diameter_mm = 0.8", "nozzle_diameter_mm = 0");
    std::fs::write(&bad_cfg, text).unwrap();
    check(
        &[
            "simulate".as_ref(),
            job.as_os_str(),
            "--config".as_ref(),
            bad_cfg.as_os_str(),
            "--trace".as_ref(),
            trace.as_os_str(),
        ],
        "nozzle_diameter_mm",
    );
}
