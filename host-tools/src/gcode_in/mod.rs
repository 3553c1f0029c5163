//! G-code in, the Klipper way: the host reads a slicer's G-code (moves, arcs, tool changes
//! and valve commands through a tool-to-inlet map, G92/G20/G91/M83 and friends) and makes
//! dollop's compact job, where the executor keys the valves to volume so every region
//! starts in its own material. This file ties the pieces together: size check, modal
//! machine, priming bead, job header, summary. It knows nothing of clap or axum; the
//! command line (`cmd/slice.rs`) maps its flags onto [`ImportOptions`].
//!
//! The lexer, modal machine, arcs, purge, tool map, emitter and errors use nothing from
//! the rest of the crate, so the fuzz target compiles them alone (`as_written`, the
//! firmware baseline the slicer tests compare with, does not).

pub mod arcs;
pub mod as_written;
pub mod emit;
pub mod error;
pub mod lexer;
pub mod modal;
pub mod purge;
pub mod sections;
pub mod tools;

pub use error::{GcodeInError, ImportError};

use crate::slicer::toolpath::{transit_mm, PathStats};
use crate::slicer::{job_file, Sliced};
use dollop::config::Config;
use dollop::Machine;
use dollop_sim::um;
use emit::{BodyStats, CountLimits};
use modal::{Counts, Modal, Settings};
use std::fmt;
use std::path::Path;
use tools::ToolMap;

/// Largest G-code file read by default, bytes (a day-long print from PrusaSlicer is about
/// 100 MB; the file is held in memory while it is read).
pub const DEFAULT_MAX_BYTES: u64 = 512 << 20;

/// Whether `path` names a G-code file (by extension).
pub fn is_gcode(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| ["gcode", "gco", "g", "nc"].contains(&e.to_ascii_lowercase().as_str()))
}

/// How to import.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportOptions {
    /// `--tools`: inlet of tool 0, tool 1, .. [default: tool i on inlet i].
    pub tools: Option<String>,
    /// Largest distance between an arc and its segments, mm.
    pub chord_mm: f64,
    /// Drop wipe towers / prime towers instead of refusing the file.
    pub strip_purge: bool,
    /// Priming bead length, mm (0: none) [default: as the raster slicer's].
    pub prime_mm: Option<f64>,
    /// Largest file read, bytes.
    pub max_bytes: u64,
    /// Print segments and commands.
    pub limits: CountLimits,
    /// `--filament-mm`: filament diameter E is measured in [default: the slicer's
    /// `filament_diameter` setting in the file, else 1.75].
    pub filament_mm: Option<f64>,
    /// `--volumetric`: E is volume, mm^3, from the start (as after `M200 D<d>`).
    pub volumetric: bool,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            tools: None,
            chord_mm: 0.01,
            strip_purge: false,
            prime_mm: None,
            max_bytes: DEFAULT_MAX_BYTES,
            limits: CountLimits {
                max_segments: crate::slicer::Limits::default().max_segments,
                max_commands: 4 * crate::slicer::Limits::default().max_segments,
            },
            filament_mm: None,
            volumetric: false,
        }
    }
}

/// Where the priming bead went.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prime {
    /// Start, mm (X, Y, Z).
    pub start_mm: [f64; 3],
    /// Length (along +X), mm.
    pub len_mm: f64,
    /// Below the part (else above it).
    pub below: bool,
    /// Its material (the first the G-code prints).
    pub material: u8,
}

/// What the import did, for the summary.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Counts from reading.
    pub counts: Counts,
    /// Counts of the job body (the priming bead excluded).
    pub body: BodyStats,
    /// The priming bead, if one was laid.
    pub prime: Option<Prime>,
    /// Chord error the arcs were cut to, mm.
    pub chord_mm: f64,
    /// Paste the dropped purge blocks would have used at dollop's bead section, mm^3.
    pub purge_mm3: f64,
    /// The beads' sections from E.
    pub sections: sections::SectionStats,
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = &self.counts;
        writeln!(
            f,
            "G-code: {} lines, {} moves, {} arcs as {} segments (chord error <= {} mm), {} tool/valve changes, {} dwells, {} E-only moves as travel",
            c.lines, c.moves, c.arcs, c.arc_segments, self.chord_mm, c.tool_changes, c.dwells, c.e_only
        )?;
        let total: u64 = c.skipped.values().sum();
        let mut by: Vec<_> = c.skipped.iter().collect();
        by.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        let list: Vec<String> = by
            .iter()
            .take(12)
            .map(|(k, v)| format!("{k} x{v}"))
            .collect();
        let more = if by.len() > 12 {
            format!(", and {} other kinds", by.len() - 12)
        } else {
            String::new()
        };
        writeln!(
            f,
            "skipped {total} commands (temperatures, fans, homing, progress and the like): {}{more}",
            if list.is_empty() { "none".to_string() } else { list.join(", ") }
        )?;
        match &self.prime {
            Some(p) => writeln!(
                f,
                "priming bead: {:.1} mm of material {} from ({:.2}, {:.2}) to ({:.2}, {:.2}) at Z {:.2}, {} the part",
                p.len_mm,
                p.material,
                p.start_mm[0],
                p.start_mm[1],
                p.start_mm[0] + p.len_mm,
                p.start_mm[1],
                p.start_mm[2],
                if p.below { "below" } else { "above" }
            )?,
            None => writeln!(f, "no priming bead (--prime-mm 0)")?,
        }
        if c.purge.blocks > 0 {
            writeln!(
                f,
                "--strip-purge: dropped {} purge block(s), {:.0} mm of bead, {:.1} mm^3 of paste at dollop's bead section",
                c.purge.blocks, c.purge.print_mm, self.purge_mm3
            )?;
        }
        write!(f, "{}", self.sections)
    }
}

/// An imported job and what the import did.
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    /// The job, as the raster slicer's.
    pub sliced: Sliced,
    /// The summary.
    pub summary: Summary,
}

/// Refuses a file of `bytes` over `limit` (from its size, before reading it).
pub fn check_size(bytes: u64, limit: u64) -> Result<(), GcodeInError> {
    if bytes > limit {
        return Err(GcodeInError::FileTooLarge { bytes, limit });
    }
    Ok(())
}

/// Reads and imports a G-code file for `config`.
pub fn import_file(
    path: &Path,
    opts: &ImportOptions,
    config: &Config,
    machine: &Machine<f64, 4>,
) -> Result<Imported, ImportError> {
    let read = |source| ImportError::Read {
        path: path.to_path_buf(),
        source,
    };
    let gcode = |source| ImportError::Gcode {
        path: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(read)?;
    check_size(meta.len(), opts.max_bytes).map_err(gcode)?;
    let bytes = std::fs::read(path).map_err(read)?;
    // The size may have grown since the check.
    check_size(bytes.len() as u64, opts.max_bytes).map_err(gcode)?;
    // G-code is ASCII; a stray Latin-1 byte in a comment is not worth refusing the file.
    let text = String::from_utf8_lossy(&bytes);
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    import_text(&text, &name, opts, config, machine).map_err(gcode)
}

/// Imports G-code held in memory (`name` names it in the summary).
pub fn import_text(
    text: &str,
    name: &str,
    opts: &ImportOptions,
    config: &Config,
    machine: &Machine<f64, 4>,
) -> Result<Imported, GcodeInError> {
    let inlets = machine.inlet_count();
    let tools = match &opts.tools {
        Some(t) => ToolMap::parse(t, inlets)?,
        None => ToolMap::identity(inlets),
    };
    let chord_mm = if opts.chord_mm.is_finite() && opts.chord_mm > 0.0 {
        opts.chord_mm
    } else {
        return Err(GcodeInError::BadArc {
            line: 0,
            reason: format!("--chord-mm {} must be a positive length", opts.chord_mm),
        });
    };
    let mut m = Modal::new(Settings {
        tools,
        chord_mm,
        strip_purge: opts.strip_purge,
        min_mm: machine.motion.min_mm,
        max_mm: machine.motion.max_mm,
        limits: opts.limits,
        filament_mm: match opts.filament_mm {
            Some(d) if d.is_finite() && d > 0.0 && d < 100.0 => Some(d),
            Some(d) => return Err(GcodeInError::BadFilament { value: d }),
            None => None,
        },
        volumetric: opts.volumetric,
    })?;
    m.run(text)?;
    let Some((lo, hi, z)) = m.out.extent() else {
        return Err(GcodeInError::NoExtrusion);
    };
    let material = m.out.first_material().unwrap_or(0);
    let prime = place_prime(opts.prime_mm, lo, hi, z, material, config, machine)?;
    let counts = std::mem::take(&mut m.counts);
    let unit = m.e_unit();
    let (commands, start_um, body, sections) = m.out.finish(
        prime.map(|p| {
            let s = [um(p.start_mm[0]), um(p.start_mm[1]), um(p.start_mm[2])];
            (s, um(p.start_mm[0] + p.len_mm))
        }),
        machine.bead_area,
        unit,
    )?;
    let (header, job_body) = job_file::encode(&commands, start_um, material, config);
    let prime_mm = prime.map_or(0.0, |p| p.len_mm);
    let stats = PathStats {
        layers: body.layers as usize,
        beads: body.beads as usize + usize::from(prime.is_some()),
        print_segments: body.print_segments as usize + usize::from(prime.is_some()),
        travels: body.travels as usize + usize::from(prime.is_some()),
        print_mm: body.print_mm + prime_mm,
        travel_mm: body.travel_mm,
        prime_mm,
        switches: body.switches as usize,
    };
    let purge_mm3 = counts.purge.print_mm * machine.bead_area;
    Ok(Imported {
        sliced: Sliced {
            header,
            commands,
            body: job_body,
            name: name.to_string(),
            size_mm: [(hi[0] - lo[0]) as f64 * 1e-3, (hi[1] - lo[1]) as f64 * 1e-3],
            stats,
        },
        summary: Summary {
            counts,
            body,
            prime,
            chord_mm,
            purge_mm3,
            sections,
        },
    })
}

/// The priming bead: along +X from the part's left edge, a gap below the part (above it
/// when the travel leaves no room below), at the first layer's height. It prints the
/// first material, so the channel is full and flowing before the part begins; dollop's
/// switches need no purge, this is only the start of the flow.
fn place_prime(
    len: Option<f64>,
    lo: [i32; 2],
    hi: [i32; 2],
    z_um: i32,
    material: u8,
    config: &Config,
    machine: &Machine<f64, 4>,
) -> Result<Option<Prime>, GcodeInError> {
    let transit = transit_mm(machine);
    let len = match len {
        Some(0.0) => return Ok(None),
        Some(l) if l.is_finite() && l > 0.0 => l,
        Some(l) => return Err(GcodeInError::BadPrime { value: l }),
        None => (2.5 * transit).ceil().max(5.0),
    };
    let pitch = config.channel.line_pitch_mm as f64;
    let gap = (3.0 * pitch).max(2.0);
    let (min, max) = (machine.motion.min_mm, machine.motion.max_mm);
    let half = pitch / 2.0;
    let lo = [lo[0] as f64 * 1e-3, lo[1] as f64 * 1e-3];
    let hi = [hi[0] as f64 * 1e-3, hi[1] as f64 * 1e-3];
    if max[0] - min[0] < len + pitch {
        return Err(GcodeInError::NoRoomForPrime { len });
    }
    let x0 = lo[0].clamp(min[0] + half, max[0] - half - len);
    let z = z_um as f64 * 1e-3;
    let (y, below) = if lo[1] - gap >= min[1] + half {
        (lo[1] - gap, true)
    } else if hi[1] + gap <= max[1] - half {
        (hi[1] + gap, false)
    } else {
        return Err(GcodeInError::NoRoomForPrime { len });
    };
    Ok(Some(Prime {
        start_mm: [x0, y, z],
        len_mm: len,
        below,
        material,
    }))
}
