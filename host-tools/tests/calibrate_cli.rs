//! `dollop calibrate` end to end on the example data bundled in host-tools/data/calibration:
//! the README's worked example, every subcommand's report, fragment (written atomically
//! and accepted by the core) and plot (a PNG that decodes).

mod calibrate_common;

use calibrate_common::*;

fn arg(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn worked_example_rheology() {
    let dir = tempfile::tempdir().unwrap();
    let (out, png) = (dir.path().join("puree.toml"), dir.path().join("puree.png"));
    let text = run(&[
        "rheology",
        arg(&data().join("rheology-puree.csv")),
        "--out",
        arg(&out),
        "--plot",
        arg(&png),
    ])
    .unwrap();
    assert!(text.contains("verdict: power law fits best"), "{text}");
    // The noise pulls the free fit's yield stress below 0; it is held at the bound.
    assert!(
        text.contains("tau_y = 0 [0, 0.406] Pa")
            && text.contains("yield stress held at 0: the data want -0.583 Pa"),
        "{text}"
    );
    let fragment = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains(&fragment));
    let (config, _) = merge_into_seed(&fragment).unwrap();
    let dollop::rheology::Rheology::PowerLaw {
        consistency_pa_sn,
        flow_index,
    } = config.inlets[0].rheology
    else {
        panic!("{fragment}")
    };
    // Generated with K = 12, n = 0.62 and 3 % noise.
    assert!(rel(consistency_pa_sn as f64, 12.0) < 0.05);
    assert!((flow_index as f64 - 0.62).abs() < 0.02);
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (900, 840));
}

#[test]
fn bundled_rheology_files_pick_their_models() {
    for (file, model) in [
        ("rheology-hummus.csv", "Herschel-Bulkley fits best"),
        ("rheology-gel-oscillatory.csv", "weak gel fits best"),
    ] {
        let text = run(&["rheology", arg(&data().join(file))]).unwrap();
        assert!(text.contains(model), "{file}: {text}");
    }
}

#[test]
fn bundled_flow_lag_camera_and_syringe() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = root().join("configs/seed-paper.toml");
    let o = |n: &str| dir.path().join(n);

    let text = run(&[
        "flow",
        arg(&data().join("flow-two-pastes.csv")),
        "--density",
        "1.05",
        "--config",
        arg(&cfg),
        "--out",
        arg(&o("flow.toml")),
        "--plot",
        arg(&o("flow.png")),
    ])
    .unwrap();
    assert!(
        text.contains("puree: power law") && text.contains("custard: Newtonian"),
        "{text}"
    );
    merge_into_seed(&std::fs::read_to_string(o("flow.toml")).unwrap()).unwrap();

    let text = run(&[
        "lag",
        arg(&data().join("lag-valve.csv")),
        "--out",
        arg(&o("lag.toml")),
        "--plot",
        arg(&o("lag.png")),
    ])
    .unwrap();
    assert!(text.contains("t_lag = 60"), "{text}");
    merge_into_seed(&std::fs::read_to_string(o("lag.toml")).unwrap()).unwrap();

    let text = run(&[
        "camera",
        arg(&data().join("camera")),
        "--fps",
        "30",
        "--mm-per-px",
        "0.02",
        "--target-width",
        "1.2",
        "--config",
        arg(&cfg),
        "--out",
        arg(&o("camera.toml")),
        "--plot",
        arg(&o("camera.png")),
    ])
    .unwrap();
    // Rendered at 4.5 px/frame and 48 px: 2.7 mm/s and 0.96 mm.
    assert!(text.contains("V_ex = 2.70"), "{text}");
    assert!(text.contains("D_ex = 0.96"), "{text}");
    merge_into_seed(&std::fs::read_to_string(o("camera.toml")).unwrap()).unwrap();

    let text = run(&[
        "syringe",
        "--diameter",
        "14.5",
        "--lead",
        "2",
        "--config",
        arg(&cfg),
        "--out",
        arg(&o("syringe.toml")),
    ])
    .unwrap();
    assert!(text.contains("defaults lag_k = 20"), "{text}");
    merge_into_seed_all(&std::fs::read_to_string(o("syringe.toml")).unwrap()).unwrap();

    for png in ["flow.png", "lag.png", "camera.png"] {
        image::open(o(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
    }
    // Atomic writes leave no temporary files behind.
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    assert_eq!(names.len(), 7, "{names:?}");
}

#[test]
fn out_without_a_fragment_says_why_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cam.toml");
    let e = run(&[
        "camera",
        arg(&data().join("camera")),
        "--fps",
        "30",
        "--mm-per-px",
        "0.02",
        "--out",
        arg(&out),
    ])
    .unwrap_err();
    assert!(e.to_string().contains("--target-width"), "{e}");
    assert!(!out.exists());
}

#[test]
fn a_smoothing_window_that_cannot_smooth_is_refused() {
    for w in ["0", "1", "4", "103", "seven"] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_dollop"))
            .args(["calibrate", "camera", arg(&data().join("camera"))])
            .args(["--fps", "30", "--mm-per-px", "0.02", "--window", w])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "--window {w} was accepted");
        assert!(err.contains("odd number of frames from 3 to 101"), "{err}");
    }
}
