//! `dollop config`: prints the commented example machine config (`--example`) or checks a
//! config file and prints what the core derives from it (`--check`). The config types and
//! their validation are the core's.

use crate::slicer;
use std::path::PathBuf;

/// Arguments of `dollop config`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example:\n  dollop config --example > machine.toml\n  dollop config --check machine.toml"
)]
pub struct Args {
    /// Print a complete, commented example config (every key explained) to stdout.
    #[arg(long, conflicts_with = "check")]
    pub example: bool,
    /// Validate a config file and print the derived machine constants.
    #[arg(long, value_name = "MACHINE.toml")]
    pub check: Option<PathBuf>,
}

/// The example config `--example` prints. Parses and validates (tested).
pub const EXAMPLE: &str = include_str!("example-config.toml");

/// Runs `dollop config`.
pub fn run(a: Args) -> anyhow::Result<()> {
    if a.example {
        print!("{EXAMPLE}");
        return Ok(());
    }
    let Some(path) = a.check else {
        anyhow::bail!("give --example (print an example config) or --check MACHINE.toml");
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
    for (i, (inlet, c)) in m.inlets.iter().zip(config.inlets.iter()).enumerate() {
        println!(
            "  inlet {i} ({}): supply {:.2} kPa",
            c.material,
            inlet.supply_pa / 1e3
        );
    }
    Ok(())
}
