//! A bead's end where the tail of the flow runs out short of it: the head stays where
//! the paste ran out and the job goes on, whatever the bead's last segments are. A
//! slicer's perimeter may end in a move of a few micrometres (PrusaSlicer's Arachne
//! perimeters on the bundled cube shell): shorter than the tail's shortfall, it left the
//! head on the segment before, waiting for paste that never came, and the job never
//! ended (on the board as in `dollop simulate`).

use dollop::config::Config;
use dollop::{Command, RunState};
use dollop_sim::{Job, RunOptions};

fn example() -> Config {
    let path = format!(
        "{}/host-tools/src/example-config.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

/// A 10 mm bead ending in a `tail` (dx, dy) um move, then a second bead after a travel.
fn job(tail: (i32, i32)) -> Job {
    Job {
        start_um: [40_000, 50_000, 600],
        initial_material: 0,
        commands: vec![
            Command::Print {
                dx: 10_000,
                dy: 0,
                material: 0,
            },
            Command::Print {
                dx: tail.0,
                dy: tail.1,
                material: 0,
            },
            Command::Travel {
                x: 40_000,
                y: 52_000,
                z: 600,
            },
            Command::Print {
                dx: 5_000,
                dy: 0,
                material: 0,
            },
            Command::End,
        ],
    }
}

#[test]
fn a_bead_ending_in_a_move_shorter_than_its_tail_still_ends() {
    let cfg = example();
    for tail in [(0, 2), (0, -1), (2, 0), (-3, 1), (0, 20)] {
        for plant in [false, true] {
            let opts = RunOptions {
                plant,
                max_time_s: 60.0,
                ..RunOptions::default()
            };
            let r = dollop_sim::run::<f32>(&cfg, &job(tail), &opts, |_| {})
                .unwrap_or_else(|e| panic!("tail {tail:?}, plant {plant}: {e:?}"));
            eprintln!(
                "tail {tail:?}, plant {plant}: {:?} after {:.2} s",
                r.state, r.time_s
            );
            assert_eq!(r.state, RunState::Done, "tail {tail:?}: {:?}", r.fault);
            // Both beads printed: the second one's 5 mm took its own time.
            assert!(r.time_s > 1.0, "{}", r.time_s);
        }
    }
}
