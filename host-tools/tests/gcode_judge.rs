//! The G-code exported from the executor's run, judged as a conventional firmware runs it
//! (`gcode_judge`: trapezoids at the configured acceleration, full stops at junctions it
//! would not take at speed, `M42` in sequence, valves and pastes on the reference plant).
//! Goals: boundaries within 0.1 mm at the 95th percentile and the bead section within 5 %
//! over every 0.2 mm, on 1 mm and 5 mm chessboards and small versions of the bundled
//! designs, with real valves (10 ms dead time, 30/20 ms rise/decay) and with ideal ones.
//! Each case prints its figures; `dollop bench --only gcode` runs the full-size designs.

use dollop::config::Config;
use dollop_host::fixtures::{chessboard_design, designs_dir};
use dollop_host::slicer::gcode_dialect::{Dialect, Kind};
use dollop_host::slicer::gcode_exec::{self, RunExport};
use dollop_host::slicer::gcode_judge::{self, Setup, Verdict};
use dollop_host::slicer::image::ImageOptions;
use dollop_host::slicer::{self, gcode, PathOptions, SliceOptions, Sliced};
use std::path::Path;

fn config(ideal: bool) -> Config {
    let mut c = slicer::load_config(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/seed-paper-valves.toml"),
    )
    .unwrap();
    if ideal {
        for i in c.inlets.iter_mut() {
            i.valve_open_delay_ms = 0.0;
            i.valve_close_delay_ms = 0.0;
            i.pressure_rise_ms = 0.0;
            i.pressure_decay_ms = 0.0;
        }
    }
    c
}

/// The test designs, small enough for seconds: (label, sliced job).
fn designs(c: &Config) -> Vec<(String, Sliced)> {
    let m = slicer::validate(Path::new("config"), c).unwrap();
    let mut out = Vec::new();
    for square in [1.0, 5.0] {
        let d = chessboard_design(10.0, square, c.channel.line_pitch_mm as f64);
        out.push((
            format!("10 mm chessboard, {square} mm squares"),
            slicer::slice_design(&d, c, &m, &PathOptions::default()).unwrap(),
        ));
    }
    let dir = designs_dir();
    let small = |w: f64| SliceOptions {
        image: ImageOptions {
            width_mm: Some(w),
            ..Default::default()
        },
        ..Default::default()
    };
    for (label, files, opts) in [
        ("logo.png at 16 mm", vec![dir.join("logo.png")], small(16.0)),
        (
            "chessboard.png at 12 mm",
            vec![dir.join("chessboard.png")],
            small(12.0),
        ),
        (
            "cube, 12 layers",
            vec![dir.join("cube-shell.stl"), dir.join("cube-ball.stl")],
            SliceOptions {
                layers: Some(12),
                ..Default::default()
            },
        ),
    ] {
        out.push((label.into(), slicer::slice_files(&files, c, &opts).unwrap()));
    }
    out
}

fn judge(label: &str, c: &Config, s: &Sliced, text: &str) -> Verdict {
    let start = s.header.start_um.map(|v| v as f64 * 1e-3);
    let setup = Setup::new(c, s.header.initial_material, start);
    let init = s.header.initial_material;
    let design = gcode_judge::design_boundaries(&s.commands, s.header.start_um, init);
    let v = gcode_judge::judge(text, &setup, &design).unwrap();
    eprintln!(
        "{label}: boundaries {} designed / {} landed ({} off the beads), p95 {:.4} mm, worst {:.4} mm (mean {:.4}); section {:.4}..{:.4} over {} windows (worst at {:.2?}); {} full stops; {:.1} s; {} bytes",
        v.boundaries, v.landed, v.changes_off_path, v.p95_mm, v.worst_mm, v.mean_mm, v.section_range.0, v.section_range.1, v.windows, v.worst_section_at, v.full_stops, v.time_s, text.len()
    );
    v
}

fn run_export(c: &Config, s: &Sliced, kind: Kind) -> String {
    let opt = RunExport {
        dialect: Dialect::new(kind),
        ..RunExport::default()
    };
    let init = s.header.initial_material;
    gcode_exec::export(c, &s.commands, s.header.start_um, init, &[], &opt)
        .unwrap()
        .0
}

#[test]
fn run_gcode_meets_the_goals_with_real_valves() {
    let c = config(false);
    for (label, s) in designs(&c) {
        let g = run_export(&c, &s, Kind::Plain);
        let v = judge(&format!("real valves, {label}"), &c, &s, &g);
        assert!(v.boundaries > 0, "{label}");
        assert!(v.landed >= v.boundaries, "{label}: {v:?}");
        assert!(v.p95_mm <= 0.1, "{label}: {v:?}");
        assert!(v.worst_section <= 0.05, "{label}: {v:?}");
        assert_eq!(v.full_stops, 0, "{label}");
    }
}

/// Worst bead section over 0.2 mm when the firmware itself prints `s` (the executor
/// against the reference plant): what the machine's acceleration allows.
fn firmware_section(c: &Config, s: &Sliced) -> f64 {
    let job = dollop_sim::Job {
        start_um: s.header.start_um,
        initial_material: s.header.initial_material,
        commands: s.commands.clone(),
    };
    let r = dollop_sim::run::<f32>(c, &job, &Default::default(), |_| {}).unwrap();
    let (lo, hi) = r.metrics.section_long_range;
    (1.0 - lo).max(hi - 1.0)
}

#[test]
fn run_gcode_with_ideal_valves_meets_the_goals_where_the_firmware_itself_does_not() {
    // With ideal valves the flow jumps at a switch (the head from 10 to 22 mm/s on this
    // machine) faster than 2000 mm/s^2 lets any head follow. The firmware ramps through
    // such jumps at 0.95 of the limit (RAMP_SHARE), sized to the worst one, and strays
    // 0.088 to 0.112 of S. The G-code is sampled from a run without those ramps and each jump is put
    // half-way through the firmware planner's own ramp at the full limit: dv^2 / 8a of
    // bead short before it and over after, within the goal.
    let c = config(true);
    for (label, s) in designs(&c) {
        let g = run_export(&c, &s, Kind::Plain);
        let v = judge(&format!("ideal valves, {label}"), &c, &s, &g);
        let own = firmware_section(&c, &s);
        eprintln!("  the firmware's own worst section over 0.2 mm: {own:.4}");
        assert!(v.landed >= v.boundaries, "{label}: {v:?}");
        assert!(v.p95_mm <= 0.1, "{label}: {v:?}");
        assert!(
            v.worst_section <= 0.05,
            "{label}: {v:?} (firmware {own:.4})"
        );
        assert_eq!(v.full_stops, 0, "{label}");
    }
}

#[test]
fn dialects_reprap_klipper_and_marlin_print_as_plain_and_marlin_m42s_stops_show() {
    let c = config(false);
    let (label, s) = designs(&c).swap_remove(0);
    let plain = judge("plain", &c, &s, &run_export(&c, &s, Kind::Plain));
    let rrf_text = run_export(&c, &s, Kind::RepRap);
    assert!(rrf_text.contains("M670 P0:1 T0") && rrf_text.contains(" P2\n"));
    let rrf = judge("reprap", &c, &s, &rrf_text);
    assert!((rrf.p95_mm - plain.p95_mm).abs() < 1e-3, "{label}");
    assert!(
        (rrf.worst_section - plain.worst_section).abs() < 2e-3,
        "{label}"
    );
    // Klipper's SET_PIN is scheduled with the moves: the same timing as plain M42, judged
    // with Klipper's corner rule (square_corner_velocity 5 mm/s).
    let k_text = run_export(&c, &s, Kind::Klipper);
    assert!(k_text.contains("SET_PIN PIN=dollop_valve1 VALUE=1\n") && !k_text.contains("M42"));
    let start = s.header.start_um.map(|v| v as f64 * 1e-3);
    let mut setup = Setup::new(&c, s.header.initial_material, start);
    setup.firmware = setup.firmware.with_square_corner_velocity(5.0);
    let design =
        gcode_judge::design_boundaries(&s.commands, s.header.start_um, s.header.initial_material);
    let k = gcode_judge::judge(&k_text, &setup, &design).unwrap();
    eprintln!(
        "klipper: p95 {:.4} mm, worst section {:.4}, {} full stops",
        k.p95_mm, k.worst_section, k.full_stops
    );
    assert!((k.p95_mm - plain.p95_mm).abs() < 1e-3, "{label}");
    assert!(
        (k.worst_section - plain.worst_section).abs() < 2e-3,
        "{label}"
    );
    assert_eq!(k.full_stops, 0, "{label}");
    // Marlin's synchronous fans are queued with the moves: the same timing as plain M42.
    let m_text = run_export(&c, &s, Kind::Marlin);
    assert!(m_text.contains("M106 P1 S255\n") && m_text.contains("M107 P0\n"));
    assert!(!m_text.contains("M42") && !m_text.contains("M400\nM106"));
    let m = judge("marlin", &c, &s, &m_text);
    assert!((m.p95_mm - plain.p95_mm).abs() < 1e-3, "{label}");
    assert!(
        (m.worst_section - plain.worst_section).abs() < 2e-3,
        "{label}"
    );
    assert_eq!(m.full_stops, plain.full_stops, "{label}");
    // Marlin's M400 before each M42 stops the head at every switch while the paste flows:
    // the judge must see the bulge.
    let m42 = judge("marlin-m42", &c, &s, &run_export(&c, &s, Kind::MarlinM42));
    assert!(
        m42.worst_section > plain.worst_section + 0.1,
        "{label}: {} vs {}",
        m42.worst_section,
        plain.worst_section
    );
}

#[test]
fn the_judge_fails_the_older_feed_rate_export_with_real_valves() {
    // The older export leads each valve by its dead time but keeps a feed rate through the
    // pressure transients: the judge must find it outside the goals where the run export
    // is inside them.
    let c = config(false);
    let m = slicer::validate(Path::new("c"), &c).unwrap();
    let (label, s) = designs(&c).swap_remove(0);
    let init = s.header.initial_material;
    let (old, _) = gcode::export(
        &s.commands,
        s.header.start_um,
        init,
        &m,
        &[],
        gcode::Style::default(),
    )
    .unwrap();
    let v = judge(&format!("older fine, {label}"), &c, &s, &old);
    assert!(v.p95_mm > 0.1 && v.worst_section > 0.05, "{v:?}");
}

#[test]
fn the_judge_sees_a_valve_switched_late() {
    // Valves switched at the boundary itself (no lead): the change lands about one
    // advance distance late.
    let c = config(true);
    let m = slicer::validate(Path::new("c"), &c).unwrap();
    let g = "G0 Z0.8 F1200\nG0 X10 Y10 F4800\nM42 P0 S1\nG1 X20 F600\nM42 P0 S0\nM42 P1 S1\nG1 X30 F600\nM42 P1 S0\nG4 P500\n";
    let setup = Setup::new(&c, 0, [10.0, 10.0, 0.8]);
    let design = [gcode_judge::DesignBoundary {
        at: [20.0, 10.0, 0.8],
        material: 1,
    }];
    let v = gcode_judge::judge(g, &setup, &design).unwrap();
    let l_adv = m.v_transit().mm3::<f64>() / m.bead_area;
    assert!(v.worst_mm > 0.5 * l_adv, "{} vs {l_adv}", v.worst_mm);
}
