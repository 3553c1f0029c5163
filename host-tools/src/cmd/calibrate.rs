//! `dollop calibrate` (not yet implemented).

/// Arguments of `dollop calibrate`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `dollop calibrate`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`dollop calibrate` is not implemented yet")
}
