//! `dollop config` (not yet implemented).

/// Arguments of `dollop config`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `dollop config`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`dollop config` is not implemented yet")
}
