//! Simulates a bundled two-material job (a chessboard on the seed paper's printhead with
//! real valves) through the executor and the reference plant, and prints its report.
//! `dollop demo` does the same from a sliced picture once the host tools are built.

fn main() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/seed-paper-valves.toml");
    let text = std::fs::read_to_string(path).expect("bundled config");
    let cfg: dollop::Config = toml::from_str(&text).expect("bundled config parses");
    let fill = dollop_sim::designs::Fill {
        origin_mm: [20.0, 20.0],
        width_mm: 16.0,
        rows: 12,
        pitch_mm: 0.8,
        layers: 2,
        layer_mm: 0.6,
        cell_mm: 0.1,
        prime_mm: 12.0,
    };
    let job = dollop_sim::designs::boustrophedon(&fill, dollop_sim::designs::chessboard(2.0));
    let t = std::time::Instant::now();
    let r = dollop_sim::run::<f32>(&cfg, &job, &dollop_sim::RunOptions::default(), |_| {})
        .expect("simulation runs");
    let m = &r.metrics;
    println!("job: {} print segments, chessboard of 2 mm squares, 2 layers", r.segments);
    println!("state: {:?} ({:?})", r.state, r.fault);
    println!("print time: {:.1} s (simulated in {:.2?})", r.time_s, t.elapsed());
    println!("material switches: {}", r.switches);
    println!(
        "boundaries: {} measured, worst {:.4} mm from the design along the path",
        m.boundaries.len(),
        m.worst_boundary()
    );
    println!(
        "bead section: {:.4} .. {:.4} of S",
        m.section_range.0, m.section_range.1
    );
    println!(
        "peak step rate: X {:.0}, Y {:.0}, Z {:.0} steps/s",
        r.peak_step_rate[0], r.peak_step_rate[1], r.peak_step_rate[2]
    );
}
