//! Fuzzes the G-code importer's parser and modal machine (`host-tools/src/gcode_in/`,
//! compiled here alone: those files use nothing else of the host crate): any text must
//! give a job or a typed error, never a panic, and a job must stay inside the travel.
#![no_main]

use libfuzzer_sys::fuzz_target;

// The importer's files refer to each other as `super::..`: declared at the crate root,
// `super` is the root, as `gcode_in` is in the host crate.
#[allow(dead_code)]
#[path = "../../host-tools/src/gcode_in/arcs.rs"]
mod arcs;
#[allow(dead_code)]
#[path = "../../host-tools/src/gcode_in/emit.rs"]
mod emit;
#[allow(dead_code)]
#[path = "../../host-tools/src/gcode_in/error.rs"]
mod error;
#[allow(dead_code)]
#[path = "../../host-tools/src/gcode_in/lexer.rs"]
mod lexer;
#[allow(dead_code)]
#[path = "../../host-tools/src/gcode_in/modal.rs"]
mod modal;
#[allow(dead_code)]
#[path = "../../host-tools/src/gcode_in/purge.rs"]
mod purge;
#[allow(dead_code)]
#[path = "../../host-tools/src/gcode_in/sections.rs"]
mod sections;
#[allow(dead_code)]
#[path = "../../host-tools/src/gcode_in/tools.rs"]
mod tools;

use dollop::Command;
use emit::CountLimits;
use modal::{Modal, Settings};
use tools::ToolMap;

fuzz_target!(|data: &[u8]| {
    let Some((&flags, rest)) = data.split_first() else {
        return;
    };
    let text = String::from_utf8_lossy(rest);
    let set = Settings {
        tools: ToolMap::identity(2),
        chord_mm: if flags & 1 == 0 { 0.01 } else { 0.5 },
        strip_purge: flags & 2 != 0,
        min_mm: [0.0; 3],
        max_mm: [200.0, 200.0, 100.0],
        limits: CountLimits {
            max_segments: 100_000,
            max_commands: 400_000,
        },
        filament_mm: None,
        volumetric: flags & 4 != 0,
    };
    let Ok(mut m) = Modal::new(set) else { return };
    if m.run(&text).is_err() {
        return;
    }
    let unit = m.e_unit();
    let Ok((cmds, start, _, _)) = m.out.finish(None, 0.4, unit) else {
        return;
    };
    let mut at = [start[0] as i64, start[1] as i64];
    for c in cmds {
        match c {
            Command::Travel { x, y, z } => {
                assert!((0..=200_000).contains(&x) && (0..=200_000).contains(&y));
                assert!((0..=100_000).contains(&z));
                at = [x as i64, y as i64];
            }
            Command::Print { dx, dy, material } => {
                assert!(material < 2);
                at = [at[0] + dx as i64, at[1] + dy as i64];
                assert!((-1..=200_001).contains(&at[0]) && (-1..=200_001).contains(&at[1]));
            }
            // Every section within what the executor takes of a 0.4 mm^2 machine.
            Command::Section { um2 } => assert!((400_000..=3_200_000).contains(&um2)),
            _ => {}
        }
    }
});
