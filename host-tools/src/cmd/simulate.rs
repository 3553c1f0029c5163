//! `dollop simulate` (not yet implemented).

/// Arguments of `dollop simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `dollop simulate`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`dollop simulate` is not implemented yet")
}
