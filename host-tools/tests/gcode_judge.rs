//! The G-code exported from the executor's run, judged as a conventional firmware runs it
//! (trapezoids at the configured acceleration, full stops at junctions it would not take at
//! speed, `M42` in sequence) on the reference plant: boundaries within 0.1 mm at the 95th
//! percentile and the bead section within 5 % over every 0.2 mm, with real valves (10 ms
//! dead time, 30/20 ms rise/decay) and ideal ones, on 1 mm and 5 mm chessboards and small
//! versions of the bundled designs. Each case prints its figures.

use dollop_host::cmd::bench::chessboard_design;
use dollop_host::slicer::gcode_dialect::Dialect;
use dollop_host::slicer::gcode_exec::{self, RunExport};
use dollop_host::slicer::gcode_judge::{self, Setup, Verdict};
use dollop_host::slicer::{self, gcode, PathOptions, Sliced};
use std::path::Path;

fn config(ideal: bool) -> dollop::config::Config {
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

fn chessboard(c: &dollop::config::Config, width: f64, square: f64) -> Sliced {
    let m = slicer::validate(Path::new("config"), c).unwrap();
    let d = chessboard_design(width, square, c.channel.line_pitch_mm as f64);
    slicer::slice_design(&d, c, &m, &PathOptions::default()).unwrap()
}

fn judge(
    label: &str,
    c: &dollop::config::Config,
    s: &Sliced,
    text: &str,
    ports: Vec<u32>,
) -> Verdict {
    let start = s.header.start_um.map(|v| v as f64 * 1e-3);
    let mut setup = Setup::new(c, s.header.initial_material, start);
    setup.ports = ports;
    let design =
        gcode_judge::design_boundaries(&s.commands, s.header.start_um, s.header.initial_material);
    let v = gcode_judge::judge(text, &setup, &design).unwrap();
    eprintln!(
        "{label}: boundaries {} designed / {} landed, p95 {:.4} mm, worst {:.4} mm (mean {:.4}); section {:.4}..{:.4} over {} windows (worst at {:?}); {} full stops; off path {:.4} mm^3; {:.1} s; {} bytes",
        v.boundaries, v.landed, v.p95_mm, v.worst_mm, v.mean_mm, v.section_range.0, v.section_range.1, v.windows, v.worst_section_at, v.full_stops, v.off_path_mm3, v.time_s, text.len()
    );
    v
}

fn run_export(c: &dollop::config::Config, s: &Sliced, dialect: Dialect) -> String {
    gcode_exec::export(
        c,
        &s.commands,
        s.header.start_um,
        s.header.initial_material,
        &[],
        &RunExport {
            dialect,
            ..RunExport::default()
        },
    )
    .unwrap()
    .0
}

#[test]
fn explore() {
    for ideal in [false, true] {
        let c = config(ideal);
        for square in [1.0, 5.0] {
            let s = chessboard(&c, 10.0, square);
            let label = format!(
                "{} valves, {square} mm squares",
                if ideal { "ideal" } else { "real" }
            );
            let g = run_export(&c, &s, Dialect::default());
            if let Ok(dir) = std::env::var("DUMP") {
                std::fs::write(format!("{dir}/{}-{square}.gcode", ideal), &g).unwrap();
            }
            judge(&format!("{label}, run/plain"), &c, &s, &g, vec![0, 1]);
            let m = slicer::validate(Path::new("c"), &c).unwrap();
            let (old, _) = gcode::export(
                &s.commands,
                s.header.start_um,
                s.header.initial_material,
                &m,
                &[],
                gcode::Style::default(),
            )
            .unwrap();
            judge(&format!("{label}, old fine"), &c, &s, &old, vec![0, 1]);
        }
    }
}
