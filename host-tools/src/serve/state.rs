//! What the dashboard's handlers share: the configs offered, sliced jobs and simulations
//! (a bounded number of each, oldest dropped first), the boards with their workers, and
//! which browser tabs are open (for the one-tab-commands-a-board rule).

use super::boards::{self, Board};
use super::design::{self, Upload};
pub use super::jobs::JobEntry;
pub use super::lock::lock;
use super::simulate_page::SimRun;
use super::Args;
use crate::slicer::Sliced;
use anyhow::Context;
use dollop::config::Config;
use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Jobs (and simulations) kept; older ones are dropped from memory.
pub const KEEP: usize = 32;

/// A config offered on the pages.
pub struct ConfigChoice {
    /// Name shown.
    pub name: String,
    /// TOML.
    pub text: String,
}

/// Shared state.
pub struct AppState {
    /// Configs to choose from (`--config` first, then the bundled ones).
    pub configs: Vec<ConfigChoice>,
    jobs: Mutex<BTreeMap<u64, Arc<JobEntry>>>,
    sims: Mutex<BTreeMap<u64, Arc<SimRun>>>,
    next: AtomicU64,
    /// The boards.
    pub boards: Vec<Arc<Board>>,
    /// Open status streams per tab.
    tabs: Mutex<HashMap<String, usize>>,
    /// The job `--demo` sliced at start.
    pub demo_job: Option<u64>,
    /// `--config`, checked: what home, jog and valve tests load on a board without a
    /// config when the page names none.
    pub cli_config: Option<Config>,
    /// `--auth`: the key every request must carry.
    pub auth: Option<super::auth::Auth>,
    /// Prints that ended (kept in `--data` when given).
    pub history: Arc<super::history::History>,
    /// Designs, G-code and jobs kept (`--data DIR/files`; a temporary folder without
    /// `--data`).
    pub files: super::store::Folder,
    /// Configs saved by name (`--data DIR/configs`).
    pub saved_configs: super::store::Folder,
    /// The console's lines and the boards' trends.
    pub console: Arc<super::console::Console>,
    /// `--camera`: the stream or snapshot URL the Print page shows.
    pub camera: Option<String>,
    /// The temporary data folder when no `--data` was given (removed with the state).
    _scratch: Option<tempfile::TempDir>,
}

impl AppState {
    /// Builds the state: reads `--config`, starts the board workers, slices the demo.
    pub fn new(a: &Args) -> anyhow::Result<Self> {
        let mut configs = Vec::new();
        let mut cli_config = None;
        if let Some(p) = &a.config {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read config {}", p.display()))?;
            let checked = design::check(&text)
                .map_err(|e| anyhow::anyhow!("{}: {}", p.display(), e.message()))?;
            cli_config = Some(checked.config);
            configs.push(ConfigChoice {
                name: p
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "machine.toml".into()),
                text,
            });
        }
        for (n, t) in design::BUNDLED {
            configs.push(ConfigChoice {
                name: format!("{n} (bundled)"),
                text: t.to_string(),
            });
        }
        let history = Arc::new(match &a.data {
            Some(dir) => {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("cannot create the data folder {}", dir.display()))?;
                super::history::History::open(dir)?
            }
            None => super::history::History::memory(),
        });
        let scratch = match &a.data {
            Some(_) => None,
            None => Some(tempfile::tempdir().context("cannot create a temporary data folder")?),
        };
        let data = match (&a.data, &scratch) {
            (Some(d), _) => d.clone(),
            (None, Some(t)) => t.path().to_path_buf(),
            (None, None) => unreachable!("a temporary folder is made when --data is absent"),
        };
        let files =
            super::store::Folder::files(&data).map_err(|e| anyhow::anyhow!("{}", e.message()))?;
        let saved_configs =
            super::store::Folder::configs(&data).map_err(|e| anyhow::anyhow!("{}", e.message()))?;
        let boards = boards::start_all(a, &history);
        let console = Arc::new(super::console::Console::new(boards.len()));
        let mut st = AppState {
            configs,
            jobs: Mutex::new(BTreeMap::new()),
            sims: Mutex::new(BTreeMap::new()),
            next: AtomicU64::new(1),
            boards,
            tabs: Mutex::new(HashMap::new()),
            demo_job: None,
            cli_config,
            auth: a.auth.as_deref().map(super::auth::Auth::new).transpose()?,
            history,
            files,
            saved_configs,
            console,
            camera: a.camera.clone(),
            _scratch: scratch,
        };
        if a.demo {
            let text = design::BUNDLED[0].1;
            let checked =
                design::check(text).map_err(|e| anyhow::anyhow!("demo config: {}", e.message()))?;
            let uploads = [Upload {
                name: design::DESIGNS[0].0.into(),
                bytes: design::DESIGNS[0].1.to_vec(),
            }];
            let form = design::SliceForm {
                width_mm: Some(40.0),
                ..Default::default()
            };
            let sliced = design::slice(&uploads, &checked.config, &form)
                .map_err(|e| anyhow::anyhow!("demo design: {}", e.message()))?;
            st.demo_job = Some(st.add_job(checked.config, text.to_string(), sliced).id);
        }
        Ok(st)
    }

    /// A fresh number.
    pub fn id(&self) -> u64 {
        self.next.fetch_add(1, Ordering::Relaxed)
    }

    /// Keeps a sliced job; returns it.
    pub fn add_job(&self, config: Config, config_text: String, sliced: Sliced) -> Arc<JobEntry> {
        let toolpath = design::toolpath(
            &sliced.commands,
            sliced.header.start_um,
            config.channel.line_pitch_mm as f64,
        );
        let figures = design::figures(&sliced, &config);
        let e = Arc::new(JobEntry {
            id: self.id(),
            config,
            config_text,
            sliced,
            toolpath,
            figures,
        });
        let mut jobs = lock(&self.jobs);
        jobs.insert(e.id, e.clone());
        while jobs.len() > KEEP {
            // The demo job stays.
            let Some(old) = jobs.keys().copied().find(|k| Some(*k) != self.demo_job) else {
                break;
            };
            jobs.remove(&old);
        }
        e
    }

    /// A job by number.
    pub fn job(&self, id: u64) -> Option<Arc<JobEntry>> {
        lock(&self.jobs).get(&id).cloned()
    }

    /// Keeps a simulation; returns its number.
    pub fn add_sim(&self, run: Arc<SimRun>) -> u64 {
        let id = self.id();
        let mut sims = lock(&self.sims);
        sims.insert(id, run);
        while sims.len() > KEEP {
            let Some(old) = sims.keys().next().copied() else {
                break;
            };
            sims.remove(&old);
        }
        id
    }

    /// A simulation by number.
    pub fn sim(&self, id: u64) -> Option<Arc<SimRun>> {
        lock(&self.sims).get(&id).cloned()
    }

    /// A board by number.
    pub fn board(&self, id: usize) -> Option<Arc<Board>> {
        self.boards.get(id).cloned()
    }

    /// A tab opened a status stream.
    pub fn tab_open(&self, tab: &str) {
        *lock(&self.tabs).entry(tab.to_string()).or_insert(0) += 1;
    }

    /// A tab's status stream ended (the tab closed or went away).
    pub fn tab_closed(&self, tab: &str) {
        let mut tabs = lock(&self.tabs);
        if let Some(n) = tabs.get_mut(tab) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                tabs.remove(tab);
            }
        }
    }

    /// The tab has a status stream open.
    pub fn tab_alive(&self, tab: &str) -> bool {
        lock(&self.tabs).contains_key(tab)
    }
}
