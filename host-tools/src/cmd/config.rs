//! `dollop config`: prints the commented example machine config (`--example`), checks a
//! config file and prints what the core derives from it (`--check`), or applies a fragment
//! that `calibrate` or `inspect` wrote (`--apply`). The config types and their validation
//! are the core's; applying a fragment is `config_apply`'s.

use crate::config_apply::{self, InletRef};
use crate::slicer;
use std::path::{Path, PathBuf};

/// Arguments of `dollop config`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example:\n  dollop config --example > machine.toml\n  dollop config --check machine.toml\n  dollop config --apply rheology.toml machine.toml --inlet 1"
)]
pub struct Args {
    /// Print a complete, commented example config (every key explained) to stdout.
    #[arg(long, conflicts_with = "check")]
    pub example: bool,
    /// Validate a config file and print the derived machine constants.
    #[arg(long, value_name = "MACHINE.toml", conflicts_with = "apply")]
    pub check: Option<PathBuf>,
    /// Apply a fragment written by `calibrate` or `inspect --suggest` to MACHINE.toml (in
    /// place unless --out), keeping its comments; prints each change and checks the result.
    #[arg(long, value_name = "FRAGMENT.toml", requires = "machine")]
    pub apply: Option<PathBuf>,
    /// The machine config `--apply` changes.
    #[arg(value_name = "MACHINE.toml")]
    pub machine: Option<PathBuf>,
    /// The inlet(s) a fragment's bare keys go to (rheology, lag, syringe fragments): index
    /// from 0 or material name, comma-separated for several (a syringe goes to every inlet).
    /// With a fragment's `[[inlet]]` tables (flow), one per table in order; without, they
    /// are matched by material.
    #[arg(long, value_name = "N|MATERIAL", requires = "apply")]
    pub inlet: Option<String>,
    /// Write the changed config here instead of over MACHINE.toml.
    #[arg(long, value_name = "NEW.toml", requires = "apply")]
    pub out: Option<PathBuf>,
}

/// The example config `--example` prints. Parses and validates (tested).
pub const EXAMPLE: &str = crate::fixtures::EXAMPLE_CONFIG;

/// Runs `dollop config`.
pub fn run(a: Args) -> anyhow::Result<()> {
    if a.example {
        print!("{EXAMPLE}");
        return Ok(());
    }
    if let (Some(fragment), Some(machine)) = (&a.apply, &a.machine) {
        let inlets = a
            .inlet
            .as_deref()
            .map(InletRef::parse_list)
            .unwrap_or_default();
        return apply(fragment, machine, &inlets, a.out.as_deref());
    }
    let Some(path) = a.check else {
        anyhow::bail!(
            "give --example (print an example config), --check MACHINE.toml, or --apply FRAGMENT.toml MACHINE.toml"
        );
    };
    let config = slicer::load_config(&path)?;
    let m = slicer::validate(&path, &config)?;
    let s = m.bead_area;
    let transit = slicer::toolpath::transit_mm(&m);
    println!("{}: valid", path.display());
    println!("  bead section S          {s:.4} mm^2");
    println!(
        "  channel volume V_s      {:.4} mm^3",
        m.v_channel.mm3::<f64>()
    );
    println!(
        "  hanging filament        {:.4} mm^3",
        m.v_hang.mm3::<f64>()
    );
    println!(
        "  advance distance L_adv  {transit:.3} mm (priming bead at least {:.1} mm)",
        2.0 * transit
    );
    println!(
        "  fastest flow-driven     {:.2} mm/s (cap {} mm/s)",
        m.v_flow_max, config.motion.print_speed_max_mm_s
    );
    println!("  corner radius           {:.3} mm", m.corner_radius);
    let a_xy = config.motion.max_accel_mm_s2[0].min(config.motion.max_accel_mm_s2[1]) as f64;
    if m.flow_step > 0.0 && m.ramp_offset_mm <= 0.0 {
        // Pressure changes faster than the limit, but none at once: the window is what
        // their first-order responses need (`config::ramp_window`).
        println!(
            "  worst flow change       {:.2} mm/s, faster than the X/Y limit of {a_xy} mm/s^2 follows (pressure rise/decay): speed ramps {:.1} ms, section bound {:.1} % over {} mm",
            m.flow_step,
            m.ramp_cycles as f64 * m.period_us as f64 * 1e-3,
            m.section_bound() * 100.0,
            dollop::config::SECTION_WINDOW_MM,
        );
    } else if m.flow_step > 0.0 {
        // What the worst step's ramp needs to keep the section, and the X/Y limit that
        // gives it that (ramps share the limit with corners).
        let need = dollop::config::section_accel(m.flow_step);
        let cost = m.section_bound();
        println!(
            "  worst flow step         {:.2} mm/s at once: keeping the section within {:.0} % over {} mm needs {:.0} mm/s^2 of ramp, an X/Y limit of {:.0} mm/s^2",
            m.flow_step,
            dollop::config::SECTION_TOLERANCE * 100.0,
            dollop::config::SECTION_WINDOW_MM,
            need,
            need / dollop::config::RAMP_SHARE
        );
        println!(
            "  speed ramps             {:.1} ms at the X/Y limit of {a_xy} mm/s^2: section up to {:.1} % off over {} mm{}",
            m.ramp_cycles as f64 * m.period_us as f64 * 1e-3,
            cost * 100.0,
            dollop::config::SECTION_WINDOW_MM,
            if need / dollop::config::RAMP_SHARE > a_xy {
                " (the machine's acceleration is the limit)"
            } else {
                ""
            }
        );
    } else {
        println!(
            "  worst flow step         none: the flow changes the head speed at most {:.0} mm/s^2, within the X/Y limit of {a_xy} mm/s^2",
            m.flow_accel
        );
    }
    let turns = slicer::row_turns::RowTurns::of(&config, &m);
    println!("  row-end U-turns         {}", turns.figure("mm/s^2"));
    if let Some(advice) = turns.advice() {
        println!("  note: {advice}");
    }
    for (i, (inlet, c)) in m.inlets.iter().zip(config.inlets.iter()).enumerate() {
        println!(
            "  inlet {i} ({}): supply {:.2} kPa",
            c.material,
            inlet.supply_pa / 1e3
        );
    }
    Ok(())
}

/// `--apply`: reads both files (size-checked before reading), applies, validates as `--check`
/// does, then writes atomically; on any error nothing is written.
fn apply(
    fragment: &Path,
    machine: &Path,
    inlets: &[InletRef],
    out: Option<&Path>,
) -> anyhow::Result<()> {
    let read = |p: &Path| -> anyhow::Result<String> {
        let bytes = std::fs::metadata(p)
            .map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?
            .len();
        if bytes > config_apply::MAX_TEXT_BYTES as u64 {
            anyhow::bail!(
                "{}: {bytes} bytes; a config or fragment is at most {} bytes: is this the right file?",
                p.display(),
                config_apply::MAX_TEXT_BYTES
            );
        }
        std::fs::read_to_string(p).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))
    };
    let applied =
        config_apply::apply(&read(machine)?, &read(fragment)?, inlets).map_err(|e| match e {
            config_apply::ApplyError::NeedInlet { .. } => {
                anyhow::anyhow!(
                    "{}: {e}: add --inlet N (or --inlet MATERIAL)",
                    fragment.display()
                )
            }
            _ => anyhow::anyhow!("{}: {e}", fragment.display()),
        })?;
    let dest = out.unwrap_or(machine);
    slicer::validate(dest, &applied.config)?;
    println!("{} applied to {}:", fragment.display(), machine.display());
    for c in &applied.changes {
        println!("  {c}");
    }
    slicer::output::write_bytes(dest, applied.text.as_bytes())?;
    println!("wrote {} (valid)", dest.display());
    Ok(())
}
