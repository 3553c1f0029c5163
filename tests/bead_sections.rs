//! Per-bead sections (job format 2, issue 26): a job whose beads ask their own section
//! (`Command::Section` between beads) lands every material where the design has it and
//! lays each bead at its own section, measured on the reference plant against that bead's
//! S; bad sections are refused with their typed error; version 1 job files still decode.

mod common;
use common::*;
use dollop::command::{section_limits, CommandError};
use dollop::executor::{Executor, PushError};
use dollop::job::{self, BodyDecoder};
use dollop::{Command, Fault};
use dollop_sim::designs::chessboard;

/// The job with `Section`s after each travel that starts a bead, cycling through `ratios`
/// of the config's section `s`. Returns the job and the sections inserted.
fn with_sections(j: &dollop_sim::designs::Job, s: f64, ratios: &[f64]) -> (Vec<Command>, usize) {
    let mut out = Vec::with_capacity(j.commands.len() * 2);
    let mut k = 0;
    for (i, c) in j.commands.iter().enumerate() {
        out.push(*c);
        let starts_bead = matches!(c, Command::Travel { .. } | Command::Layer { .. })
            && matches!(j.commands.get(i + 1), Some(Command::Print { .. }));
        if starts_bead {
            let um2 = (s * ratios[k % ratios.len()] * 1e6).round() as u32;
            out.push(Command::Section { um2 });
            k += 1;
        }
    }
    (out, k)
}

#[test]
fn beads_of_their_own_sections_land_their_materials_at_their_own_section() {
    for name in ["seed-paper.toml", "seed-paper-valves.toml"] {
        let cfg = config(name);
        let m = cfg.validate::<f64, 4>().unwrap();
        let f = fill(6.0, 6, 2);
        let mut j = job(&f, chessboard(2.0));
        // One bead per layer after the priming bead (rows joined): the priming bead at
        // 1.25 times the config's section, the layers at 1.5 times it and at it; the
        // wider beads print slower at the same flow, the valve cursor keyed to volume
        // across them.
        let (cmds, n) = with_sections(&j, m.bead_area, &[1.25, 1.5, 1.0]);
        assert_eq!(n, 3, "{name}: {n} sections");
        j.commands = cmds;
        let r = run(&cfg, &j);
        summary(name, &r);
        assert_landed(name, &r, 10);
        // Measured against each bead's own S: an executor laying the config's section
        // everywhere would be 20 % and 33 % off on the wider beads.
        let (section, bound) = if m.ramp_cycles > 1 {
            (r.metrics.worst_section_long(), section_bound(&m))
        } else {
            (r.metrics.worst_section(), 0.01)
        };
        assert!(
            section <= bound,
            "{name}: section off by {:.3} % (bound {:.3} %)",
            section * 100.0,
            bound * 100.0
        );
    }
}

fn refused(cmds: &[Command]) -> Option<Fault> {
    let cfg = config("seed-paper-valves.toml");
    let m = cfg.validate::<f32, 4>().unwrap();
    let mut e: Executor<f32> = Executor::new(m);
    e.begin([20_000, 20_000, 600], 0).unwrap();
    for c in cmds {
        if let Err(PushError::Rejected(f)) = e.push(*c) {
            return Some(f);
        }
    }
    None
}

#[test]
fn zero_absurd_or_mid_bead_sections_are_refused_by_name() {
    let cfg = config("seed-paper-valves.toml");
    let s = cfg.validate::<f64, 4>().unwrap().bead_area;
    let (lo, hi) = section_limits(s);
    let travel = Command::Travel {
        x: 20_000,
        y: 20_000,
        z: 600,
    };
    let print = Command::Print {
        dx: 1000,
        dy: 0,
        material: 0,
    };
    for um2 in [0, lo - 1, hi + 1, u32::MAX] {
        let f = refused(&[travel, Command::Section { um2 }, print]);
        assert_eq!(
            f,
            Some(Fault::InvalidCommand(CommandError::SectionOutOfRange {
                um2,
                min_um2: lo,
                max_um2: hi
            })),
            "{um2}"
        );
        let text = CommandError::SectionOutOfRange {
            um2,
            min_um2: lo,
            max_um2: hi,
        }
        .to_string();
        assert!(text.contains("bead_area_mm2"), "{text}");
    }
    for um2 in [lo, hi] {
        assert_eq!(refused(&[travel, Command::Section { um2 }, print]), None);
    }
    // Mid-bead (issue 26's per-segment sections): taken inside the range, refused by
    // name outside it.
    assert_eq!(
        refused(&[travel, print, Command::Section { um2: hi }, print]),
        None
    );
    assert_eq!(
        refused(&[travel, print, Command::Section { um2: hi + 1 }, print]),
        Some(Fault::InvalidCommand(CommandError::SectionOutOfRange {
            um2: hi + 1,
            min_um2: lo,
            max_um2: hi
        }))
    );
}

/// A job file written before per-bead sections (committed for the firmware-in-the-loop
/// test): it reads as version 1, all of its commands decode, and none is a section.
#[test]
fn a_version_1_job_file_still_decodes() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/host-tools/tests/data/fil-chessboard.dlp"
    );
    let bytes = std::fs::read(path).unwrap();
    let (h, n) = job::decode_preamble(&bytes).unwrap();
    assert_eq!(h.format_version, 1);
    let mut d = BodyDecoder::new(&h);
    let mut cmds = Vec::new();
    d.feed(&bytes[n..], |c| -> Result<(), ()> {
        cmds.push(c);
        Ok(())
    })
    .unwrap()
    .unwrap();
    d.finish().unwrap();
    assert_eq!(cmds.len() as u32, h.commands);
    assert_eq!(cmds.last(), Some(&Command::End));
    assert!(!cmds.iter().any(|c| matches!(c, Command::Section { .. })));
    assert_eq!(job::version_for(&cmds), job::FORMAT_VERSION);
}
