//! What a newcomer trips over, end to end (issue 28): pictures framed with axes and a key,
//! the 3D preview showing every material, an out-of-range layer refused, an image without a
//! size and an overwritten output noted, `simulate --heatmap` saying what it wrote, the
//! G-code's print-host header, layers, progress and start/end G-code, and fragments
//! applied by `dollop config --apply`.

mod cli_common;

use cli_common::{dollop, manifest};

/// Pixels of exactly this colour.
fn count(img: &image::RgbImage, c: [u8; 3]) -> usize {
    img.pixels().filter(|p| p.0 == c).count()
}

const BROWN: [u8; 3] = [122, 72, 36];
const YELLOW: [u8; 3] = [236, 190, 70];

#[test]
fn the_cube_preview_shows_both_materials_and_a_bad_layer_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = |extra: &[&'static str]| {
        let mut v = vec![
            "slice".to_string(),
            manifest("designs/cube-shell.stl"),
            manifest("designs/cube-ball.stl"),
            "--config".into(),
            manifest("../configs/seed-paper.toml"),
            "--out".into(),
            "cube.dlp".into(),
            "--preview".into(),
            "cube.png".into(),
        ];
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let run = |extra: &[&'static str]| {
        let a = args(extra);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        dollop(d, &a)
    };
    let (code, out, err) = run(&[]);
    assert_eq!(code, 0, "{err}");
    let img = image::open(d.join("cube.png")).unwrap().to_rgb8();
    // The ball is inside the shell: only a grid of layers shows it.
    assert!(count(&img, YELLOW) > 1000, "ball not visible: {out}");
    assert!(count(&img, BROWN) > 1000);
    // Dark axis and label pixels around the plates (the plate background is light).
    assert!(count(&img, [0, 0, 0]) > 500);

    let (code, out, err) = run(&["--preview-layer", "99"]);
    assert_ne!(code, 0, "{out}");
    assert!(
        err.contains("--preview-layer 99: the job has") && err.contains("numbered 0 to"),
        "{err}"
    );
    // Refused before anything was written over the first run's files.
    assert!(out.is_empty(), "{out}");

    let (code, out, err) = run(&["--preview-layer", "0"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("(replaced the file that was there)"), "{out}");
}

#[test]
fn an_image_without_a_size_says_how_big_it_prints() {
    let dir = tempfile::tempdir().unwrap();
    let (code, _, err) = dollop(
        dir.path(),
        &[
            "slice",
            &manifest("designs/chessboard.png"),
            "--config",
            &manifest("../configs/seed-paper.toml"),
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("no --width-mm or --height-mm") && err.contains(" mm; give --width-mm"),
        "{err}"
    );
    let (code, _, err) = dollop(
        dir.path(),
        &[
            "slice",
            &manifest("designs/chessboard.png"),
            "--config",
            &manifest("../configs/seed-paper.toml"),
            "--width-mm",
            "12",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("--width-mm"), "{err}");
}

#[test]
fn gcode_carries_what_print_hosts_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("start.gcode"), "G28 ; home all\nG1 Z5 F600\n").unwrap();
    std::fs::write(d.join("end.gcode"), "M84 ; motors off\n").unwrap();
    let (code, out, err) = dollop(
        d,
        &[
            "slice",
            &manifest("designs/cube-shell.stl"),
            &manifest("designs/cube-ball.stl"),
            "--config",
            &manifest("../configs/seed-paper.toml"),
            "--layers",
            "3",
            "--gcode",
            "cube.gcode",
            "--gcode-start",
            "start.gcode",
            "--gcode-end",
            "end.gcode",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("3 layer(s)"), "{out}");
    let g = std::fs::read_to_string(d.join("cube.gcode")).unwrap();
    let lines: Vec<&str> = g.lines().collect();
    let time: u64 = lines
        .iter()
        .find_map(|l| l.strip_prefix(";TIME:"))
        .expect("a ;TIME: line")
        .parse()
        .unwrap();
    assert!(
        g.contains("; estimated printing time (normal mode) = "),
        "{}",
        &g[..400]
    );
    assert!(g.contains(";LAYER_COUNT:3"));
    let layers: Vec<&str> = lines
        .iter()
        .filter(|l| l.starts_with(";LAYER:"))
        .copied()
        .collect();
    assert_eq!(layers, [";LAYER:0", ";LAYER:1", ";LAYER:2"]);
    // Progress rises to 100 %, its time left falls to 0 from about the header's total.
    let m73: Vec<(u32, u64)> = lines
        .iter()
        .filter_map(|l| {
            let rest = l.strip_prefix("M73 P")?;
            let (p, r) = rest.split_once(" R")?;
            Some((p.parse().ok()?, r.parse().ok()?))
        })
        .collect();
    assert!(m73.len() > 50, "{}", m73.len());
    assert!(m73.windows(2).all(|w| w[0].0 < w[1].0 && w[0].1 >= w[1].1));
    assert_eq!(m73[0], (0, time.div_ceil(60)));
    assert_eq!(*m73.last().unwrap(), (100, 0));
    // The user's start G-code before the first move, the end G-code before the end.
    let at = |s: &str| g.find(s).unwrap_or_else(|| panic!("{s} missing"));
    assert!(at("G28 ; home all") < at("G21\nG90"));
    assert!(at("M73 P100 R0") < at("M84 ; motors off"));
    assert!(at("M84 ; motors off") < at("; end of job"));

    // A start file that is not text, or too large, is refused before anything is written.
    std::fs::write(d.join("bin.gcode"), [0xff, 0xfe, 0x00, 0x80]).unwrap();
    std::fs::write(d.join("big.gcode"), "G4 P1\n".repeat(20_000)).unwrap();
    for (file, needle) in [
        ("bin.gcode", "not text"),
        ("big.gcode", "at most 65536 bytes"),
    ] {
        let (code, _, err) = dollop(
            d,
            &[
                "slice",
                &manifest("designs/chessboard.png"),
                "--config",
                &manifest("../configs/seed-paper.toml"),
                "--width-mm",
                "12",
                "--out",
                "x.dlp",
                "--gcode",
                "x.gcode",
                "--gcode-start",
                file,
            ],
        );
        assert_ne!(code, 0);
        assert!(err.contains(needle), "{err}");
        assert!(!d.join("x.dlp").exists() && !d.join("x.gcode").exists());
    }
}

#[test]
fn simulate_says_what_it_wrote_and_the_heatmap_has_its_scale() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = manifest("../configs/seed-paper.toml");
    let (code, _, err) = dollop(
        d,
        &[
            "slice",
            &manifest("designs/chessboard.png"),
            "--config",
            &cfg,
            "--width-mm",
            "6",
            "--out",
            "c.dlp",
        ],
    );
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = dollop(
        d,
        &[
            "simulate",
            "c.dlp",
            "--config",
            &cfg,
            "--heatmap",
            "plate.png",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.trim(), "wrote plate.png", "{out}");
    let img = image::open(d.join("plate.png")).unwrap().to_rgb8();
    // The error scale's ends (green at 0, red at 0.05 mm) and both materials' swatches.
    let near = |c: [u8; 3]| {
        img.pixels()
            .filter(|p| (0..3).all(|k| (p.0[k] as i32 - c[k] as i32).abs() <= 8))
            .count()
    };
    assert!(near([0, 190, 40]) >= 22, "no green end of the scale");
    assert!(near([255, 0, 40]) >= 22, "no red end of the scale");
    assert!(count(&img, BROWN) > 100 && count(&img, YELLOW) > 100);
}

#[test]
fn a_fragment_is_applied_keeping_comments_and_a_bad_one_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let machine = d.join("machine.toml");
    let original = std::fs::read_to_string(manifest("../configs/seed-paper.toml")).unwrap();
    std::fs::write(&machine, &original).unwrap();
    let (code, _, err) = dollop(
        d,
        &[
            "calibrate",
            "rheology",
            &manifest("data/calibration/rheology-puree.csv"),
            "--out",
            "rheology.toml",
        ],
    );
    assert_eq!(code, 0, "{err}");
    // Without --inlet: the message says what to add; nothing changes.
    let (code, _, err) = dollop(d, &["config", "--apply", "rheology.toml", "machine.toml"]);
    assert_ne!(code, 0);
    assert!(err.contains("add --inlet N"), "{err}");
    assert_eq!(std::fs::read_to_string(&machine).unwrap(), original);
    let (code, out, err) = dollop(
        d,
        &[
            "config",
            "--apply",
            "rheology.toml",
            "machine.toml",
            "--inlet",
            "1",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("inlet[1]") && out.contains(".rheology: ") && out.contains(" -> { power_law"),
        "{out}"
    );
    let after = std::fs::read_to_string(&machine).unwrap();
    for comment in original.lines().filter(|l| l.trim_start().starts_with('#')) {
        assert!(after.contains(comment), "lost: {comment}");
    }
    let config: dollop::config::Config = toml::from_str(&after).unwrap();
    assert!(matches!(
        config.inlets[1].rheology,
        dollop::rheology::Rheology::PowerLaw { .. }
    ));
    // A fragment that would make the config invalid: refused, the file untouched.
    std::fs::write(d.join("bad.toml"), "[motion]\nprint_speed_mm_s = -3.0\n").unwrap();
    let (code, _, err) = dollop(d, &["config", "--apply", "bad.toml", "machine.toml"]);
    assert_ne!(code, 0);
    assert!(err.contains("print_speed_mm_s"), "{err}");
    assert_eq!(std::fs::read_to_string(&machine).unwrap(), after);
}
