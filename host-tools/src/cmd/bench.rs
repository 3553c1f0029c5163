//! `dollop bench` (not yet implemented).

/// Arguments of `dollop bench`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `dollop bench`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`dollop bench` is not implemented yet")
}
