//! `dollop serve`: a local web dashboard over the same library code the CLI calls
//! (slicer, dollop-sim, the link client). This file parses the options, builds the shared
//! state, binds the listener and runs axum on tokio; the pages are plain HTML/CSS/JS
//! compiled into the binary (`assets`), the HTTP API is `routes`, the work behind it is
//! `design` (configs, uploads, slicing), `simulate`, `calibrate` and `boards` (one worker thread per
//! board, the simulated board among them through `simlink`).

pub mod assets;
pub mod boards;
pub mod calibrate;
pub mod design;
pub mod error;
pub mod jobs;
pub mod lock;
pub mod routes;
pub mod simlink;
pub mod simulate;
pub mod state;

use anyhow::Context;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

/// Largest upload the server takes (one request: designs, a job or measurements), bytes.
/// Stated on the page; bigger requests are refused with a message naming it.
pub const MAX_UPLOAD: usize = 64 << 20;

/// Arguments of `dollop serve`.
#[derive(clap::Args, Debug, Clone)]
#[command(after_help = "Examples:\n  \
dollop serve --demo\n  \
dollop serve --config machine.toml --board /dev/ttyACM0\n\n\
The dashboard listens on 127.0.0.1 only unless --listen says otherwise. It has no \
authentication: anyone who can reach the address can drive the printer.")]
pub struct Args {
    /// Address and port to listen on (127.0.0.1: this computer only; 0.0.0.0: every
    /// network this computer is on, with no authentication).
    #[arg(long, value_name = "ADDR:PORT", default_value = "127.0.0.1:7125")]
    pub listen: SocketAddr,
    /// Machine config (TOML) offered first on the pages, besides the bundled ones.
    #[arg(long, value_name = "MACHINE.toml")]
    pub config: Option<PathBuf>,
    /// A board's port (serial device, or tcp:HOST:PORT); repeat for several boards.
    /// Without any, the USB boards found by their VID/PID are listed.
    #[arg(long = "board", value_name = "PORT")]
    pub boards: Vec<String>,
    /// Start with a bundled design sliced and ready (the simulated board is always listed).
    #[arg(long)]
    pub demo: bool,
    /// The simulated board runs this many times faster than real time.
    #[arg(long, value_name = "FACTOR", default_value_t = 1.0)]
    pub sim_speed: f64,
    /// Do not look for USB boards (only --board ports and the simulated board).
    #[arg(long)]
    pub no_usb: bool,
    /// Simulated boards to list (a lab's printers without the printers), 1 to 8.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub sim_boards: usize,
}

/// A running server: where it listens, and its state (tests look inside).
pub struct Running {
    /// The bound address (the port chosen when 0 was asked for).
    pub addr: SocketAddr,
    /// Everything the handlers share.
    pub state: Arc<state::AppState>,
}

/// Binds the listener and spawns the server on the current tokio runtime.
pub async fn start(a: Args) -> anyhow::Result<Running> {
    if !(a.sim_speed.is_finite() && (0.1..=1000.0).contains(&a.sim_speed)) {
        anyhow::bail!("--sim-speed {} must be between 0.1 and 1000", a.sim_speed);
    }
    if !(1..=8).contains(&a.sim_boards) {
        anyhow::bail!("--sim-boards {} must be between 1 and 8", a.sim_boards);
    }
    let state = Arc::new(state::AppState::new(&a)?);
    let listener = tokio::net::TcpListener::bind(a.listen)
        .await
        .with_context(|| format!("cannot listen on {}", a.listen))?;
    let addr = listener
        .local_addr()
        .context("the listener has no address")?;
    let app = routes::router(state.clone());
    tokio::spawn(async move {
        if let Err(e) = axum::serve(listener, app).await {
            eprintln!("dollop serve: the server stopped: {e}");
        }
    });
    Ok(Running { addr, state })
}

/// Runs `dollop serve` until Ctrl-C.
pub fn run(a: Args) -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    rt.block_on(async move {
        let exposed = !a.listen.ip().is_loopback();
        let r = start(a).await?;
        println!("dollop dashboard: http://{}/", r.addr);
        if exposed {
            println!(
                "warning: listening beyond this computer with no authentication: anyone who reaches {} can drive the printer",
                r.addr
            );
        }
        tokio::signal::ctrl_c()
            .await
            .context("waiting for Ctrl-C")?;
        println!("stopping: boards keep their state (a print goes on, or pauses by its link-loss policy)");
        Ok(())
    })
}
