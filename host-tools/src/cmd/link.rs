//! `dollop send|status|pause|resume|abort|jog|valve` (not yet implemented).

/// Serial port selection.
#[derive(clap::Args, Debug)]
pub struct PortArgs {
    /// Serial port of the board (default: auto-detect by USB VID/PID).
    #[arg(long)]
    pub port: Option<String>,
}

/// Arguments of `dollop send`.
#[derive(clap::Args, Debug)]
pub struct SendArgs {
    /// Job file (.dlp).
    pub job: std::path::PathBuf,
    #[command(flatten)]
    pub port: PortArgs,
}

/// Arguments of `dollop jog`.
#[derive(clap::Args, Debug)]
pub struct JogArgs {
    #[command(flatten)]
    pub port: PortArgs,
}

/// Arguments of `dollop valve`.
#[derive(clap::Args, Debug)]
pub struct ValveArgs {
    #[command(flatten)]
    pub port: PortArgs,
}

fn todo() -> anyhow::Result<()> {
    anyhow::bail!("the USB link commands are not implemented yet")
}
/// `dollop send`.
pub fn send(_a: SendArgs) -> anyhow::Result<()> {
    todo()
}
/// `dollop status`.
pub fn status(_a: PortArgs) -> anyhow::Result<()> {
    todo()
}
/// `dollop pause`.
pub fn pause(_a: PortArgs) -> anyhow::Result<()> {
    todo()
}
/// `dollop resume`.
pub fn resume(_a: PortArgs) -> anyhow::Result<()> {
    todo()
}
/// `dollop abort`.
pub fn abort(_a: PortArgs) -> anyhow::Result<()> {
    todo()
}
/// `dollop jog`.
pub fn jog(_a: JogArgs) -> anyhow::Result<()> {
    todo()
}
/// `dollop valve`.
pub fn valve(_a: ValveArgs) -> anyhow::Result<()> {
    todo()
}
