//! The f32 executor the chip runs against an f64 reference executor on a 10 000-segment
//! job: the plate boundaries they produce agree within 0.01 mm.

mod common;
use common::*;
use dollop_sim::designs::{chessboard, Fill};
use dollop_sim::RunOptions;

#[test]
fn f32_and_f64_executors_agree_on_the_plate_within_0_01_mm_over_10000_segments() {
    let cfg = config("seed-paper-valves.toml");
    let f = Fill {
        cell_mm: 0.1,
        ..fill(24.0, 20, 11)
    };
    let j = job(&f, chessboard(0.5));
    let segments = j.print_segments();
    assert!(segments >= 10_000, "only {segments} segments");
    let opts = RunOptions {
        plant: false,
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let r32 = dollop_sim::run::<f32>(&cfg, &j, &opts, |_| {}).unwrap();
    let wall32 = t0.elapsed();
    let r64 = dollop_sim::run::<f64>(&cfg, &j, &opts, |_| {}).unwrap();
    eprintln!(
        "{segments} segments, {:.0} s printed, f32 run took {:.2?} of wall time",
        r32.time_s, wall32
    );
    summary("f32", &r32);
    summary("f64", &r64);
    assert_eq!(r32.state, dollop::RunState::Done);
    assert_eq!(r64.state, dollop::RunState::Done);
    let (b32, b64) = (&r32.metrics.boundaries, &r64.metrics.boundaries);
    assert!(b32.len() > 5000, "{} boundaries", b32.len());
    assert_eq!(b32.len(), b64.len());
    let mut worst = 0.0f64;
    for (a, b) in b32.iter().zip(b64) {
        assert_eq!((a.point, a.material), (b.point, b.material));
        worst = worst.max((a.s_landed - b.s_landed).abs());
    }
    eprintln!("f32 vs f64: worst difference in landed boundary position {worst:.5} mm");
    assert!(
        worst <= 0.01,
        "f32 and f64 boundaries differ by {worst:.4} mm"
    );
}
