//! Scratch: replays the M4 bench job on the host and prints what happens at given ticks.
fn main() {
    let text = std::fs::read_to_string("configs/seed-paper-valves.toml").unwrap();
    let cfg: dollop::Config = toml::from_str(&text).unwrap();
    let f = dollop_sim::designs::Fill {
        origin_mm: [20.0, 20.0],
        width_mm: 8.0,
        rows: 6,
        pitch_mm: 0.8,
        layers: 2,
        layer_mm: 0.6,
        cell_mm: 0.1,
        prime_mm: 6.0,
    };
    let j = dollop_sim::designs::boustrophedon(&f, dollop_sim::designs::chessboard(1.0));
    let want: Vec<u64> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let m = cfg.validate::<f32, 4>().unwrap();
    let mut ex: dollop::Executor<f32> = dollop::Executor::new(m);
    ex.begin(j.start_um, j.initial_material).unwrap();
    let mut out = dollop::RecordingOutputs::default();
    let mut next = 0;
    for k in 0..200_000u64 {
        while next < j.commands.len() && ex.room() > 0 {
            if ex.push(j.commands[next]).is_ok() {
                next += 1
            } else {
                break;
            }
        }
        let before = ex.report_snapshot();
        let r = ex.tick(k * 100, &mut out).unwrap();
        if want.contains(&(k + 1)) || want.contains(&k) {
            eprintln!(
                "tick {} (k={k}): {:?} -> {:?}, idx {} -> {}, valves {:b} -> {:b}, pos {:?}",
                k + 1,
                before.state,
                r.state,
                before.command_index,
                r.command_index,
                before.valves,
                r.valves,
                r.position
            );
        }
        if r.state == dollop::RunState::Done {
            break;
        }
    }
}
