//! `dollop serve`: a local web dashboard over the same library code the CLI calls
//! (slicer, dollop-sim, the link client). This file parses the options, builds the shared
//! state, binds the listener and runs axum on tokio; the pages are plain HTML/CSS/JS
//! compiled into the binary (`assets`), the HTTP API is `routes`, the work behind it is
//! `design` (configs, uploads, slicing), `simulate_page`, `calibrate` and `boards` (one worker thread per
//! board, the simulated board among them through `paced_board`).

pub mod assets;
pub mod auth;
pub mod board_config;
pub mod boards;
pub mod calibrate;
pub mod clock;
pub mod console;
pub mod controls;
pub mod design;
pub mod error;
pub mod files;
pub mod gate;
pub mod history;
pub mod jobs;
pub mod lock;
pub mod octoprint;
pub mod octoprint_common;
pub mod octoprint_control;
pub mod octoprint_login;
pub mod paced_board;
pub mod reply;
pub mod routes;
pub mod samples;
pub mod simulate_page;
pub mod snapshot;
pub mod state;
pub mod store;
pub mod view;

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
The dashboard listens on 127.0.0.1 only unless --listen says otherwise; beyond this \
computer it needs --auth KEY (every page, API call and the status stream then ask for it).")]
pub struct Args {
    /// Address and port to listen on (127.0.0.1: this computer only; 0.0.0.0: every
    /// network this computer is on, which needs --auth).
    #[arg(long, value_name = "ADDR:PORT", default_value = "127.0.0.1:7125")]
    pub listen: SocketAddr,
    /// Port to listen on (replaces the port of --listen).
    #[arg(long, value_name = "PORT")]
    pub port: Option<u16>,
    /// An API key or password (8 characters or more) every request must carry: a browser
    /// signs in once, scripts send `Authorization: Bearer KEY`. Required when --listen is
    /// not a loopback address.
    #[arg(long, value_name = "KEY")]
    pub auth: Option<String>,
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
    /// Folder kept across restarts (the print history, kept files, configs saved by
    /// name); default: `dollop` under the
    /// user's data folder ($XDG_DATA_HOME, else ~/.local/share).
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// A camera the Print page shows: an MJPEG stream or a snapshot URL (http:// or
    /// https://; a snapshot is fetched again every two seconds by the browser).
    #[arg(long, value_name = "URL")]
    pub camera: Option<String>,
}

/// The data folder `dollop serve` uses when `--data` names none.
pub fn default_data_dir() -> Option<PathBuf> {
    let base = match std::env::var_os("XDG_DATA_HOME").filter(|d| !d.is_empty()) {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(std::env::var_os("HOME")?).join(".local/share"),
    };
    Some(base.join("dollop"))
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
    if let Some(url) = &a.camera {
        if !(url.starts_with("http://") || url.starts_with("https://")) || url.len() > 2000 {
            anyhow::bail!(
                "--camera {url:?}: give the camera's http:// or https:// address (an MJPEG stream or a snapshot)"
            );
        }
    }
    let listen = match a.port {
        Some(p) => SocketAddr::new(a.listen.ip(), p),
        None => a.listen,
    };
    if !listen.ip().is_loopback() && a.auth.is_none() {
        anyhow::bail!(
            "listening on {listen} lets anyone on the network drive the printer: give --auth KEY (a key or password every request must carry), or listen on 127.0.0.1"
        );
    }
    let state = Arc::new(state::AppState::new(&a)?);
    let listener = tokio::net::TcpListener::bind(listen)
        .await
        .with_context(|| format!("cannot listen on {listen}"))?;
    let addr = listener
        .local_addr()
        .context("the listener has no address")?;
    console::watch(state.boards.clone(), state.console.clone());
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
    let mut a = a;
    if a.data.is_none() {
        a.data = default_data_dir();
    }
    rt.block_on(async move {
        let guarded = a.auth.is_some();
        let r = start(a).await?;
        println!("dollop dashboard: http://{}/", r.addr);
        if guarded {
            println!("every request needs the --auth key (a browser signs in at /login)");
        }
        tokio::signal::ctrl_c()
            .await
            .context("waiting for Ctrl-C")?;
        println!("stopping: boards keep their state (a print goes on, or pauses by its link-loss policy)");
        Ok(())
    })
}
