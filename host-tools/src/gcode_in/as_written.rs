//! The baseline dollop is measured against: a job run "as written", as a G-code firmware
//! runs a slicer's multi-material file on a single-nozzle paste head. The valve of the
//! active tool opens where its extrusion starts and closes for travel; a tool change
//! switches valves at the `T` itself, so each new region first pushes out the old paste
//! the channel holds. Rendered as G-code for `slicer::gcode_judge` (the firmware model on
//! the reference plant), heads at the speed a full channel's flow gives (`v = Q / S`, S
//! each bead's own section).

use crate::slicer::gcode::Head;
use dollop::{Command, Machine};
use std::fmt::Write as _;

/// The job's commands as a firmware would run them: `M42 P<inlet> S1/S0` at each bead's
/// start, each material change and each bead's end, moves at each material's full-channel
/// speed.
pub fn gcode(
    commands: &[Command],
    start_um: [i32; 3],
    initial: u8,
    machine: &Machine<f64, 4>,
) -> String {
    let head = Head::new(machine, initial);
    // The bead's own section (`Command::Section`), the config's until the first.
    let mut section = machine.bead_area;
    let feed = |m: u8, s: f64| head.flow_full(m) / s * 60.0;
    let travel_f = machine.motion.max_speed[0].min(machine.motion.max_speed[1]) * 60.0;
    let mm = |v: i64| v as f64 * 1e-3;
    let mut at = start_um.map(|v| v as i64);
    let mut open: Option<u8> = None;
    let mut out = String::with_capacity(commands.len() * 32);
    let close = |out: &mut String, open: &mut Option<u8>| {
        if let Some(o) = open.take() {
            let _ = writeln!(out, "M42 P{o} S0");
        }
    };
    for c in commands {
        match *c {
            Command::Print { dx, dy, material } => {
                if open != Some(material) {
                    close(&mut out, &mut open);
                    let _ = writeln!(out, "M42 P{material} S1");
                    open = Some(material);
                }
                at[0] += dx as i64;
                at[1] += dy as i64;
                let _ = writeln!(
                    out,
                    "G1 X{:.3} Y{:.3} F{:.1}",
                    mm(at[0]),
                    mm(at[1]),
                    feed(material, section)
                );
            }
            Command::Travel { x, y, z } => {
                close(&mut out, &mut open);
                at = [x as i64, y as i64, z as i64];
                let _ = writeln!(
                    out,
                    "G0 X{:.3} Y{:.3} Z{:.3} F{travel_f:.0}",
                    mm(at[0]),
                    mm(at[1]),
                    mm(at[2])
                );
            }
            Command::Layer { z } => {
                close(&mut out, &mut open);
                at[2] = z as i64;
                let _ = writeln!(out, "G0 Z{:.3} F{travel_f:.0}", mm(at[2]));
            }
            Command::Dwell { ms } => {
                close(&mut out, &mut open);
                let _ = writeln!(out, "G4 P{ms}");
            }
            Command::End => close(&mut out, &mut open),
            Command::Section { um2 } => section = um2 as f64 * 1e-6,
        }
    }
    out
}
