//! Scratch: runs a long job without the plant, for profiling.
fn main() {
    let text = std::fs::read_to_string("configs/seed-paper-valves.toml").unwrap();
    let cfg: dollop::Config = toml::from_str(&text).unwrap();
    let f = dollop_sim::designs::Fill {
        origin_mm: [20.0, 20.0],
        width_mm: 24.0,
        rows: 20,
        pitch_mm: 0.8,
        layers: 3,
        layer_mm: 0.6,
        cell_mm: 0.1,
        prime_mm: 12.0,
    };
    let j = dollop_sim::designs::boustrophedon(&f, dollop_sim::designs::chessboard(0.5));
    let t = std::time::Instant::now();
    let r = dollop_sim::run::<f32>(
        &cfg,
        &j,
        &dollop_sim::RunOptions {
            plant: false,
            ..Default::default()
        },
        |_| {},
    )
    .unwrap();
    eprintln!(
        "{:.0} s simulated in {:.2?}: {:.0}x",
        r.time_s,
        t.elapsed(),
        r.time_s / t.elapsed().as_secs_f64()
    );
}
