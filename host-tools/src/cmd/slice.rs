//! `dollop slice` (not yet implemented).

/// Arguments of `dollop slice`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `dollop slice`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`dollop slice` is not implemented yet")
}
