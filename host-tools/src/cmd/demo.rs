//! `dollop demo` (not yet implemented).

/// Arguments of `dollop demo`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `dollop demo`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`dollop demo` is not implemented yet")
}
