mod common;
use common::*;
use dollop_sim::designs::{chessboard, stripes};
use dollop_sim::RunOptions;

#[test]
#[ignore]
fn debug_stripes() {
    let cfg = config(&std::env::var("CFG").unwrap_or("seed-paper-valves.toml".into()));
    let j = job(&fill(12.0, 8, 2), chessboard(3.0));
    let _ = stripes(1.0);
    let mut n = 0u64;
    let opts = RunOptions { max_time_s: 40.0, ..Default::default() };
    let mut last = [0.0f64; 2];
    let r = dollop_sim::run::<f32>(&cfg, &j, &opts, |c| {
        n += 1;
        let p = [c.report.position[0] as f64, c.report.position[1] as f64];
        let ds = ((p[0]-last[0]).powi(2) + (p[1]-last[1]).powi(2)).sqrt();
        if c.report.state == dollop::RunState::Printing && ds > 1e-9 {
            let ratio = c.landed_volume / (ds * 0.48);
            if (ratio - 1.0).abs() > 0.01 {
                eprintln!("t {:.4} pos {:?} ratio {:.4} exec dv {:.6} plant {:.6} ds {:.6} valves {:b} idx {}", c.t_s, p, ratio, c.report.dv.mm3::<f64>(), c.landed_volume, ds, c.report.valves, c.report.command_index);
            }
        }
        last = p;
    });
    eprintln!("{:?}", r.map(|r| (r.state, r.fault)));
}
