//! What the page shows of a board (`View`, pushed ten times a second) and of a queued job:
//! plain data that the board worker fills in and the control rules read. The worker and
//! the rules themselves live in `boards` and `controls`.

use dollop::wire::Mode;
use dollop::RunState;
use serde::Serialize;

/// A queued job, as the page lists it.
#[derive(Debug, Clone, Serialize)]
pub struct Queued {
    /// The job's number.
    pub job: u64,
    /// Its name.
    pub name: String,
}

/// What the page shows of a board, pushed ten times a second.
#[derive(Debug, Clone, Serialize, Default)]
pub struct View {
    /// Board number.
    pub id: usize,
    /// Name shown.
    pub name: String,
    /// Port, or "simulated".
    pub port: String,
    /// The simulated board.
    pub simulated: bool,
    /// A link to the board is up.
    pub connected: bool,
    /// What the worker is doing: idle, uploading, homing, printing, ...
    pub activity: String,
    /// The last thing worth telling (an order refused, a link lost), in plain words;
    /// it goes after `MESSAGE_S`, or sooner when what it was about is over.
    pub message: Option<String>,
    /// A halt, in plain words with what to do.
    pub fault: Option<String>,
    /// Board mode (Idle, Job, Homing, Halted, ...; "" to the page before the first status).
    #[serde(serialize_with = "name_or_empty")]
    pub mode: Option<Mode>,
    /// Executor state (Printing, Paused, Done, ...; "" before the first status).
    #[serde(serialize_with = "name_or_empty")]
    pub run: Option<RunState>,
    /// Homed since the drivers were enabled.
    pub homed: bool,
    /// Valves open, bit per inlet.
    pub valves: u8,
    /// Head position, mm.
    pub position: [f64; 3],
    /// Head speed, mm/s.
    pub speed: f64,
    /// Flow, mm³/s: the reference plant's on the simulated board, the board's own
    /// model's on a real one (which has no flow sensor).
    pub flow: f64,
    /// What the board's executor believes the flow is, mm³/s.
    pub flow_model: f64,
    /// Where `flow` comes from: "plant" (the simulated board's reference plant) or
    /// "model" (the board's executor).
    pub flow_source: String,
    /// Pressure in each inlet's line, kPa (the simulated board's plant; empty otherwise).
    pub line_kpa: Vec<f64>,
    /// The job being printed (or last printed).
    pub job: Option<Queued>,
    /// Commands done, of `commands`.
    pub command: u32,
    /// Commands in the job on the board.
    pub commands: u32,
    /// 0..1.
    pub progress: f64,
    /// Layer of the job (0 = the priming bead's).
    pub layer: usize,
    /// Seconds since the print started; it stops when the print stops.
    pub elapsed_s: f64,
    /// Seconds left: the executor's virtual-time estimate of the job (made when it was
    /// sliced) from the command the board is on, corrected by the pace so far. None when
    /// no print is on its way (aborted, halted, nothing sent).
    pub eta_s: Option<f64>,
    /// When the print should end, ms since 1970 (the page shows the clock time).
    pub finish_unix_ms: Option<f64>,
    /// Why each control cannot act now (absent: it can), by action name.
    pub refused: std::collections::BTreeMap<String, String>,
    /// Upload to the board: bytes acknowledged and total.
    pub upload: Option<(u64, u64)>,
    /// Jobs waiting.
    pub queue: Vec<Queued>,
    /// Updates so far (the page shows the status is live).
    pub seq: u64,
    /// The last pause asked from here: ms (board time) from the order to the first
    /// status with every valve shut, and to the first reading Paused (head at rest), as
    /// this page's status polls saw them (so late by up to a poll).
    pub pause_latency_ms: Option<[Option<f64>; 2]>,
    /// The pause point while a pause is in effect, mm.
    pub pause_point: Option<[f64; 3]>,
}

/// A state as the page reads it: the variant's name, or "" when none is known yet.
fn name_or_empty<S: serde::Serializer, T: Serialize>(
    v: &Option<T>,
    s: S,
) -> Result<S::Ok, S::Error> {
    match v {
        Some(v) => v.serialize(s),
        None => s.serialize_str(""),
    }
}
