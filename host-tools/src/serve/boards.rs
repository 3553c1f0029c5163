//! The boards the dashboard drives: one worker thread per board owning its link client
//! (a serial/TCP port, or the simulated board), taking orders one at a time from a queue
//! (so orders from several tabs never interleave on the link), polling the board ten
//! times a second and publishing what it sees for the pages. The CLI's safety rules
//! apply: the job's config is loaded first, the machine is homed before a job starts, a
//! jog is sent once and bounded, a valve test closes after a bounded time, abort clears a
//! halt. Each board has its own job queue; a finished print waits for the plate to be
//! cleared before the next starts.

use super::board_config::LoadedConfig;
use super::clock::{self, PrintClock};
use super::controls;
use super::history::{History, Record};
use super::jobs::JobEntry;
use super::lock::lock;
use super::paced_board::PacedBoard;
use super::Args;
use crate::link::{
    mem_options, ops, serial, Cancelled, Client, JobFile, LinkError, Options, SerialLink, Transport,
};
use dollop::wire::{Halt, JobSlot, Mode, Request, Snapshot, Status};
use dollop::{Axis, RunState};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A board's connection: a port, or the simulated board (paced to the wall clock).
pub enum Connection {
    /// A serial device or `tcp:HOST:PORT`.
    Serial(SerialLink),
    /// The simulated board.
    Simulated(Box<PacedBoard>),
}

impl Connection {
    fn catch_up(&mut self) {
        if let Connection::Simulated(s) = self {
            s.catch_up();
        }
    }
}

/// A board's link that an Abort can cut short while an upload is under way: armed during
/// uploads only, it fails the next send or receive once the board's abort flag is up, so
/// the upload ends at once and the worker takes the abort next (status polls and other
/// orders never see the flag).
pub struct Cancellable {
    /// The link.
    pub link: Connection,
    cancel: Arc<AtomicBool>,
    armed: bool,
}

impl Cancellable {
    fn check(&self) -> Result<(), LinkError> {
        if self.armed && self.cancel.load(Ordering::SeqCst) {
            return Err(LinkError::Cancelled(Cancelled::Upload));
        }
        Ok(())
    }
}

impl Transport for Cancellable {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.check()?;
        self.link.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        self.check()?;
        self.link.recv(buf, timeout)
    }
    fn now(&self) -> Duration {
        self.link.now()
    }
    fn sleep(&mut self, d: Duration) {
        self.link.sleep(d)
    }
    fn reconnect(&mut self) -> Result<(), LinkError> {
        self.check()?;
        self.link.reconnect()
    }
}

impl Transport for Connection {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        match self {
            Connection::Serial(s) => s.send(bytes),
            Connection::Simulated(s) => s.send(bytes),
        }
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        match self {
            Connection::Serial(s) => s.recv(buf, timeout),
            Connection::Simulated(s) => s.recv(buf, timeout),
        }
    }
    fn now(&self) -> Duration {
        match self {
            Connection::Serial(s) => s.now(),
            Connection::Simulated(s) => s.now(),
        }
    }
    fn sleep(&mut self, d: Duration) {
        match self {
            Connection::Serial(s) => s.sleep(d),
            Connection::Simulated(s) => s.sleep(d),
        }
    }
    fn reconnect(&mut self) -> Result<(), LinkError> {
        match self {
            Connection::Serial(s) => s.reconnect(),
            Connection::Simulated(s) => s.reconnect(),
        }
    }
}

pub use super::view::{Queued, View};

/// An order for a board's worker, with where the answer goes.
pub enum WorkerOrder {
    /// Queue a job (and start it if the board is free).
    Send(Arc<JobEntry>),
    /// Start the first queued job (after the plate was cleared).
    StartNext,
    /// Drop a queued job.
    Unqueue(u64),
    /// Pause mid-bead (valves shut, head stopped at the pause point).
    Pause,
    /// Pause, then lift and move to the config's park position.
    Park,
    /// Resume a paused print.
    Resume,
    /// Stop now (and clear a halt).
    Abort,
    /// Home all axes.
    Home(Fallback),
    /// Move one axis, mm.
    Jog(Axis, f64, Fallback),
    /// Open a valve for this many seconds.
    Valve(u8, f64, Fallback),
}

/// The config a manual order (home, jog, valve test) loads on a board that has none and
/// no job to take one from: the one chosen on the Design page, or the server's
/// `--config`. None: such an order is refused with what to do.
pub type Fallback = Option<Box<dollop::config::Config>>;

/// A board: its worker's queue, what it shows, and who commands it.
pub struct Board {
    /// Number.
    pub id: usize,
    orders: Mutex<mpsc::Sender<(WorkerOrder, Reply)>>,
    /// The latest view.
    pub view: tokio::sync::watch::Receiver<View>,
    /// The tab that commands it (set by its last accepted order).
    pub controller: Mutex<Option<String>>,
    /// Raised by `abort` ahead of its order: an upload under way stops at once.
    cancel: Arc<AtomicBool>,
    /// The machine config its worker last loaded on it (G-code for this board is
    /// imported with it).
    pub config: Arc<LoadedConfig>,
}

impl Board {
    /// Aborts: cuts short an upload under way to this board (the worker would otherwise
    /// take the order only after it), then stops the board.
    pub async fn abort(&self) -> Result<String, String> {
        self.cancel.store(true, Ordering::SeqCst);
        self.order(WorkerOrder::Abort).await
    }

    /// Hands an order to the worker and waits for its answer (in plain words).
    pub async fn order(&self, o: WorkerOrder) -> Result<String, String> {
        let (tx, rx) = tokio::sync::oneshot::channel();
        lock(&self.orders)
            .send((o, tx))
            .map_err(|_| "the board's worker has stopped; restart dollop serve".to_string())?;
        match tokio::time::timeout(Duration::from_secs(600), rx).await {
            Ok(Ok(r)) => r,
            Ok(Err(_)) => Err("the board's worker stopped while carrying out the order".into()),
            Err(_) => Err("the board did not finish the order within 10 minutes".into()),
        }
    }
}

/// Starts the workers: the simulated boards first, then `--board` ports (or the USB board
/// found by VID/PID).
pub fn start_all(a: &Args, history: &Arc<History>) -> Vec<Arc<Board>> {
    let h = || Some(history.clone());
    let mut out = Vec::new();
    for i in 0..a.sim_boards.max(1) {
        let name = if a.sim_boards > 1 {
            format!("simulated board {}", i + 1)
        } else {
            "simulated board".into()
        };
        out.push(spawn_with(
            i,
            name,
            "simulated".into(),
            None,
            a.sim_speed,
            Duration::ZERO,
            h(),
        ));
    }
    let mut ports = a.boards.clone();
    if ports.is_empty() && !a.no_usb {
        if let Ok(p) = serial::detect() {
            ports.push(p);
        }
    }
    for p in ports {
        let id = out.len();
        let name = format!("board {id}");
        out.push(spawn_with(
            id,
            name,
            p.clone(),
            Some(p),
            1.0,
            Duration::ZERO,
            h(),
        ));
    }
    out
}

/// `spawn_with`, frames undelayed and nothing recorded (unit tests).
#[cfg(test)]
fn spawn(id: usize, name: String, port: String, path: Option<String>, speed: f64) -> Arc<Board> {
    spawn_with(id, name, port, path, speed, Duration::ZERO, None)
}

/// `spawn`, with the simulated board's link delaying each frame by `frame_delay`.
fn spawn_with(
    id: usize,
    name: String,
    port: String,
    path: Option<String>,
    speed: f64,
    frame_delay: Duration,
    history: Option<Arc<History>>,
) -> Arc<Board> {
    let (tx, rx) = mpsc::channel();
    let view = View {
        id,
        name,
        port,
        simulated: path.is_none(),
        activity: "connecting".into(),
        ..Default::default()
    };
    let (vtx, vrx) = tokio::sync::watch::channel(view.clone());
    let cancel = Arc::new(AtomicBool::new(false));
    let loaded = Arc::new(LoadedConfig::default());
    let board = Arc::new(Board {
        id,
        orders: Mutex::new(tx),
        view: vrx,
        controller: Mutex::new(None),
        cancel: cancel.clone(),
        config: loaded.clone(),
    });
    let spawned = std::thread::Builder::new()
        .name(format!("board-{id}"))
        .spawn(move || {
            let mut w = Worker::new(path, speed, view, vtx, cancel);
            w.frame_delay = frame_delay;
            w.history = history;
            w.loaded = loaded;
            w.run(rx)
        });
    if let Err(e) = spawned {
        eprintln!("dollop serve: cannot start the worker of board {id}: {e}");
    }
    board
}

type Reply = tokio::sync::oneshot::Sender<Result<String, String>>;

/// How long a message stays on the card, s.
pub const MESSAGE_S: u64 = 20;

/// The job on the board, and how its print goes.
struct Current {
    entry: Arc<JobEntry>,
    clock: PrintClock,
    /// Where each layer starts, by command.
    layer_starts: Vec<u32>,
    /// Aborted from here.
    aborted: bool,
}

struct Worker {
    path: Option<String>,
    speed: f64,
    client: Option<Client<Cancellable>>,
    cancel: Arc<AtomicBool>,
    view: View,
    vtx: tokio::sync::watch::Sender<View>,
    queue: Vec<Arc<JobEntry>>,
    current: Option<Current>,
    valve_close: Option<(Instant, u8)>,
    next_connect: Instant,
    /// The simulated board's plant is built from this instead of the loaded config (a
    /// machine that differs from its config; tests).
    plant_config: Option<dollop::config::Config>,
    /// The simulated board's link delays each frame this long (tests; see `PacedBoard`).
    frame_delay: Duration,
    /// When the last pause (or park) was ordered, for its latency.
    pause_asked: Option<Instant>,
    /// When `view.message` was said (it expires).
    message_at: Option<Instant>,
    /// A job was sent while the board was busy (homing, jogging, a valve test): start
    /// the queue's first when it is free.
    start_when_free: bool,
    /// Where an ended print is recorded (none: not recorded; unit tests).
    history: Option<Arc<History>>,
    /// The config last loaded on the board, shared with its `Board`.
    loaded: Arc<LoadedConfig>,
}

/// Still on its way: a job runs (or is paused) on the board.
fn on_its_way(k: &Snapshot) -> bool {
    k.mode == Mode::Job
        && !matches!(
            k.run,
            RunState::Done | RunState::Aborted | RunState::Faulted
        )
}

/// The running (or just ended) job's part of the view from the board's snapshot `k`:
/// command, progress, layer, its clock, time left and finish; `Some(outcome)` when the
/// job has just ended.
fn follow_job(cur: &mut Current, v: &mut View, k: &Snapshot, speed: f64) -> Option<&'static str> {
    let done = k.run == RunState::Done;
    let running = on_its_way(k);
    let mut ended = None;
    let now = Instant::now();
    if done {
        // A finished job has done every command (the board's count stops one
        // short: it counts the command under way).
        v.command = v.commands;
    }
    v.progress = if done {
        1.0
    } else {
        (k.command as f64 / v.commands.max(1) as f64).min(1.0)
    };
    v.layer = cur
        .layer_starts
        .partition_point(|&c| c <= k.command)
        .saturating_sub(1);
    if running {
        cur.clock.paused(k.run == RunState::Paused, now);
    } else if !cur.clock.ended() {
        cur.clock.end(now);
        ended = Some(if done {
            "finished"
        } else if k.mode == Mode::Halted {
            "halted"
        } else {
            "aborted"
        });
    }
    v.elapsed_s = cur.clock.elapsed_s(now);
    let f = &cur.entry.figures;
    v.eta_s = if done {
        Some(0.0)
    } else if running {
        clock::eta_s(
            &f.command_t_s,
            f.est_time_s,
            k.command,
            v.commands,
            cur.clock.printing_s(now),
            speed,
        )
    } else {
        None
    };
    v.finish_unix_ms = v.eta_s.and_then(clock::unix_ms_in);
    ended
}

/// The board's activity in words, from its mode and run state (`current`: a job is
/// the board's, finished or not).
fn activity(mode: Mode, run: RunState, current: bool) -> String {
    match (mode, run) {
        // Short words: scripts (scripts/emulator/serve.py) wait for "paused".
        (Mode::Job, RunState::Paused) => "paused".into(),
        (Mode::Job, RunState::Pausing) => "pausing".into(),
        (Mode::Job, _) => "printing".into(),
        (Mode::Homing, _) => "homing".into(),
        (Mode::Halted, _) => "halted".into(),
        (Mode::ValveTest, _) => "valve test".into(),
        (_, RunState::Done) if current => "finished: clear the plate, then Start next".into(),
        (_, RunState::Aborted) if current => "aborted".into(),
        (m, _) => format!("{m:?}").to_lowercase(),
    }
}

fn mode_words(s: &Status) -> Option<String> {
    let k = &s.control;
    if k.mode != Mode::Halted && !k.estop {
        return None;
    }
    Some(match k.halt {
        Some(Halt::Fault(dollop::Fault::EStop)) if k.estop => {
            "Emergency stop: the e-stop input is active. Release it, then press Abort to clear, then Home.".into()
        }
        Some(h) => format!("The board stopped: {h}. Press Abort to clear it, then Home before the next job."),
        None if k.estop => "Emergency stop input active: release it, then press Abort.".into(),
        None => "The board is halted. Press Abort to clear it, then Home.".into(),
    })
}

impl Worker {
    fn new(
        path: Option<String>,
        speed: f64,
        view: View,
        vtx: tokio::sync::watch::Sender<View>,
        cancel: Arc<AtomicBool>,
    ) -> Self {
        Worker {
            path,
            speed,
            client: None,
            cancel,
            view,
            vtx,
            queue: Vec::new(),
            current: None,
            valve_close: None,
            next_connect: Instant::now(),
            plant_config: None,
            frame_delay: Duration::ZERO,
            pause_asked: None,
            message_at: None,
            start_when_free: false,
            history: None,
            loaded: Arc::default(),
        }
    }

    /// Records the print that just ended.
    fn record(&mut self, outcome: &str) {
        let (Some(h), Some(cur)) = (self.history.clone(), self.current.as_ref()) else {
            return;
        };
        let now_unix = clock::unix_ms_in(0.0).unwrap_or(0.0) / 1e3;
        let now = Instant::now();
        let r = Record {
            board: self.view.id,
            board_name: self.view.name.clone(),
            job: cur.entry.figures.name.clone(),
            config_hash: format!("{:08x}", dollop::job::config_hash(&cur.entry.config)),
            started_unix_s: now_unix - cur.clock.elapsed_s(now),
            ended_unix_s: now_unix,
            outcome: outcome.into(),
            printing_s: cur.clock.printing_s(now),
            command: self.view.command,
            commands: self.view.commands,
        };
        if let Err(e) = h.add(r) {
            self.say(e);
        }
    }

    /// Shows a message on the card (until it expires or another replaces it).
    fn say(&mut self, m: impl Into<String>) {
        self.view.message = Some(m.into());
        self.message_at = Some(Instant::now());
    }

    /// Clears the message (what it was about is over).
    fn hush(&mut self) {
        self.view.message = None;
        self.message_at = None;
    }

    fn publish(&mut self) {
        if self
            .message_at
            .is_some_and(|t| t.elapsed() >= Duration::from_secs(MESSAGE_S))
        {
            self.hush();
        }
        self.view.seq += 1;
        self.view.queue = self
            .queue
            .iter()
            .map(|e| Queued {
                job: e.id,
                name: e.figures.name.clone(),
            })
            .collect();
        self.view.refused = controls::refusals(&self.view, self.queue.len());
        let _ = self.vtx.send(self.view.clone());
    }

    fn connect(&mut self) {
        if self.client.is_some() || Instant::now() < self.next_connect {
            return;
        }
        self.view.activity = "connecting".into();
        let opened = match &self.path {
            None => {
                let mut link = PacedBoard::new(self.speed);
                link.frame_delay = self.frame_delay;
                Ok((Connection::Simulated(Box::new(link)), mem_options()))
            }
            Some(p) => {
                SerialLink::open(Some(p)).map(|l| (Connection::Serial(l), Options::default()))
            }
        };
        let cancel = self.cancel.clone();
        let r = opened.and_then(|(link, opts)| {
            let link = Cancellable {
                link,
                cancel,
                armed: false,
            };
            let mut c = Client::open(link, opts);
            c.connect().map(|_| c)
        });
        match r {
            Ok(c) => {
                self.client = Some(c);
                self.view.connected = true;
                self.view.activity = "idle".into();
                self.hush();
            }
            Err(e) => {
                self.view.connected = false;
                self.view.activity = "not connected".into();
                self.say(format!(
                    "{e}; retrying every 3 s (check the cable and power)"
                ));
                self.next_connect = Instant::now() + Duration::from_secs(3);
            }
        }
    }

    fn lost(&mut self, e: &LinkError) {
        self.client = None;
        self.view.connected = false;
        self.view.upload = None;
        self.view.activity = "not connected".into();
        self.say(format!(
            "Lost the board: {e}. A print on it pauses by its link-loss policy; plug it back in and press Resume. Queued jobs are kept."
        ));
        self.next_connect = Instant::now() + Duration::from_secs(1);
    }

    fn run(mut self, rx: mpsc::Receiver<(WorkerOrder, Reply)>) {
        loop {
            self.connect();
            match rx.recv_timeout(Duration::from_millis(100)) {
                Ok((order, reply)) => {
                    let r = self.handle(order);
                    match &r {
                        Err(m) => self.say(m.clone()),
                        // The order went through: an older refusal is no longer news.
                        Ok(_) => self.hush(),
                    }
                    let _ = reply.send(r);
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => return,
            }
            self.tick();
            self.publish();
        }
    }

    /// Runs the board's clock, closes a timed valve, polls the status.
    fn tick(&mut self) {
        let Some(c) = self.client.as_mut() else {
            return;
        };
        c.transport_mut().link.catch_up();
        let mut failed = None;
        if let Some((at, inlet)) = self.valve_close {
            if Instant::now() >= at {
                self.valve_close = None;
                if let Err(e) = c.command(&Request::Valve { inlet, open: false }) {
                    failed = Some(format!("closing valve {inlet} failed: {e}"));
                }
            }
        }
        let status = c.status();
        if let Some(m) = failed {
            self.say(m);
        }
        match status {
            Ok(s) => self.show(&s),
            Err(e) => return self.lost(&e),
        }
        self.start_if_free();
    }

    /// Starts the queue's first job once the board that was busy when it was sent is
    /// free (idle, or unconfigured: the job loads its config).
    fn start_if_free(&mut self) {
        let free = matches!(self.view.mode, Some(Mode::Idle | Mode::Unconfigured));
        if !(self.start_when_free && free && self.client.is_some()) {
            return;
        }
        self.start_when_free = false;
        if self.queue.is_empty() {
            return;
        }
        match self.start_next() {
            Ok(m) => self.say(m),
            Err(m) => self.say(m),
        }
    }

    fn show(&mut self, s: &Status) {
        let k = &s.control;
        let v = &mut self.view;
        v.mode = Some(k.mode);
        v.run = Some(k.run);
        v.homed = k.homed;
        v.valves = k.valves;
        v.position = k.position_um.map(|u| u as f64 / 1000.0);
        v.pause_point = k.pause_point_um.map(|p| p.map(|u| u as f64 / 1000.0));
        v.speed = k.speed_mm_s as f64;
        v.flow_model = k.q_mm3_s as f64;
        let plant = match self.client.as_ref().map(|c| c.transport()) {
            Some(Cancellable {
                link: Connection::Simulated(s),
                ..
            }) => s.plant_now(),
            _ => None,
        };
        match plant {
            Some(p) => {
                v.flow = p.q_mm3_s;
                v.line_kpa = p.line_kpa;
                v.flow_source = "plant".into();
            }
            None => {
                v.flow = v.flow_model;
                v.line_kpa.clear();
                v.flow_source = "model".into();
            }
        }
        v.fault = mode_words(s);
        if let JobSlot::Ready { commands, .. } = s.job {
            v.commands = commands;
        }
        v.command = k.command;
        if let Some(t0) = self.pause_asked {
            let ms = t0.elapsed().as_secs_f64() * 1e3 * self.speed;
            let l = v.pause_latency_ms.get_or_insert([None; 2]);
            if k.valves == 0 {
                l[0].get_or_insert(ms);
            }
            if k.run == RunState::Paused {
                l[1].get_or_insert(ms);
            }
        }
        let printing = k.mode == Mode::Job;
        if !on_its_way(k) && !matches!(k.mode, Mode::Homing | Mode::Jogging) {
            // Nothing moves the head and no print meters paste: a stopped executor's
            // last speed and flow are not the board now.
            v.speed = 0.0;
            if k.valves == 0 {
                v.flow_model = 0.0;
                if v.flow_source == "model" {
                    v.flow = 0.0;
                }
            }
        }
        let ended = match self.current.as_mut() {
            Some(cur) => follow_job(cur, v, k, self.speed),
            None => None,
        };
        v.activity = activity(k.mode, k.run, self.current.is_some());
        if !printing && self.current.as_ref().is_some_and(|c| c.aborted) && k.mode == Mode::Idle {
            v.activity = "aborted".into();
        }
        if let Some(outcome) = ended {
            self.record(outcome);
        }
    }

    fn client(&mut self) -> Result<&mut Client<Cancellable>, String> {
        self.client
            .as_mut()
            .ok_or_else(|| "the board is not connected; check its cable and power".to_string())
    }

    /// Refuses an order the board cannot act on now (see `controls`).
    fn check(&self, action: &str) -> Result<(), String> {
        match controls::refusal(&self.view, self.queue.len(), action) {
            Some(why) => Err(format!("{action}: {why}")),
            None => Ok(()),
        }
    }

    fn handle(&mut self, o: WorkerOrder) -> Result<String, String> {
        match &o {
            WorkerOrder::StartNext => self.check("start-next")?,
            WorkerOrder::Pause => self.check("pause")?,
            WorkerOrder::Park => self.check("park")?,
            WorkerOrder::Resume => self.check("resume")?,
            WorkerOrder::Home(_) => self.check("home")?,
            WorkerOrder::Valve(..) => self.check("valve")?,
            // A jog's distance is checked first (its error says more than "not homed").
            WorkerOrder::Jog(..)
            | WorkerOrder::Send(_)
            | WorkerOrder::Unqueue(_)
            | WorkerOrder::Abort => {}
        }
        match o {
            WorkerOrder::Send(e) => self.queue_job(e),
            WorkerOrder::StartNext => self.start_next(),
            WorkerOrder::Unqueue(id) => {
                // One entry: the same job queued twice is two prints, and a remove click
                // takes back one of them (the copies are alike: the last goes).
                let Some(at) = self.queue.iter().rposition(|e| e.id == id) else {
                    return Err("that job is not in this board's queue".into());
                };
                self.queue.remove(at);
                Ok("removed from the queue".into())
            }
            WorkerOrder::Park => {
                self.client()?
                    .command(&Request::Park)
                    .map_err(|e| e.to_string())?;
                self.pause_asked = Some(Instant::now());
                self.view.pause_latency_ms = None;
                Ok("parking: the head stops at the pause point, lifts and moves to the park position; Resume brings it back".into())
            }
            WorkerOrder::Pause => {
                self.client()?
                    .command(&Request::Pause)
                    .map_err(|e| e.to_string())?;
                self.pause_asked = Some(Instant::now());
                self.view.pause_latency_ms = None;
                Ok("pausing: the valves shut where the bead's tail lands, and the head stops there".into())
            }
            WorkerOrder::Resume => {
                self.client()?
                    .command(&Request::Resume)
                    .map_err(|e| e.to_string())?;
                self.pause_asked = None;
                Ok("resumed".into())
            }
            WorkerOrder::Abort => self.abort(),
            WorkerOrder::Home(fallback) => {
                self.ensure_config(fallback)?;
                self.client()?
                    .command(&Request::Home)
                    .map_err(|e| e.to_string())?;
                Ok("homing".into())
            }
            WorkerOrder::Jog(axis, mm, fallback) => {
                let um = ops::jog_um(mm).map_err(|e| e.to_string())?;
                self.check("jog")?;
                self.ensure_config(fallback)?;
                ops::jog(self.client()?, axis, um).map_err(|e| e.to_string())?;
                Ok(format!("jogging {axis:?} by {mm} mm"))
            }
            WorkerOrder::Valve(inlet, secs, fallback) => {
                if !(secs.is_finite() && secs > 0.0 && secs <= 10.0) {
                    return Err("a valve test lasts between 0 and 10 s".into());
                }
                self.ensure_config(fallback)?;
                self.client()?
                    .command(&Request::Valve { inlet, open: true })
                    .map_err(|e| e.to_string())?;
                self.valve_close = Some((Instant::now() + Duration::from_secs_f64(secs), inlet));
                Ok(format!("valve {inlet} open for {secs} s"))
            }
        }
    }

    /// Queues `e`, and starts it at once if the board is connected and free.
    fn queue_job(&mut self, e: Arc<JobEntry>) -> Result<String, String> {
        let name = e.figures.name.clone();
        self.queue.push(e);
        let busy = self.view.mode == Some(Mode::Job) || self.view.activity.starts_with("finished");
        if busy {
            return Ok(format!("{name} queued ({} waiting)", self.queue.len()));
        }
        if self.client.is_none() {
            self.start_when_free = true;
            return Ok(format!(
                "{name} queued: the board is not connected; it starts when the board is back and free"
            ));
        }
        if let Some(what) = controls::busy_words(self.view.mode) {
            self.start_when_free = true;
            return Ok(format!(
                "{name} queued: {what}; it starts when the board is free"
            ));
        }
        self.start_next()
    }

    /// Aborts the board (marking the job it prints aborted) and clears a halt.
    fn abort(&mut self) -> Result<String, String> {
        self.start_when_free = false;
        self.cancel.store(false, Ordering::SeqCst);
        let c = self.client()?;
        let printing = c.status().map_err(|e| e.to_string())?.control.mode == Mode::Job;
        ops::abort(c).map_err(|e| e.to_string())?;
        if let (Some(cur), true) = (self.current.as_mut(), printing) {
            cur.aborted = true;
        }
        let Some(c) = self.client.as_mut() else {
            return Err("the board is not connected".into());
        };
        let done = ops::clear_if_halted(c).map_err(|e| e.to_string())?;
        Ok(done.to_string())
    }

    /// Loads a config if the board has none (jog, home and valves need one): the current
    /// job's, the first queued one's, or else `fallback` (the Design page's or `--config`).
    fn ensure_config(&mut self, fallback: Fallback) -> Result<(), String> {
        let cfg = self
            .current
            .as_ref()
            .map(|c| c.entry.config.clone())
            .or_else(|| self.queue.first().map(|e| e.config.clone()))
            .or_else(|| fallback.map(|b| *b));
        let c = self.client()?;
        if c.info().and_then(|i| i.config).is_some() {
            return Ok(());
        }
        if let Ok(s) = c.status() {
            if s.config.is_some() {
                return Ok(());
            }
        }
        let Some(cfg) = cfg else {
            return Err("the board has no machine config yet: choose one on the Design page (or start dollop serve with --config), or send it a job".into());
        };
        c.command(&Request::LoadConfig(cfg.clone()))
            .map_err(|e| format!("loading the config: {e}"))?;
        self.loaded.set(&cfg, None);
        self.couple_plant(&cfg, 0)
    }

    /// After a config was loaded on the simulated board: the reference plant of that
    /// machine (or of `plant_config`) takes the board's valve outputs from now on.
    fn couple_plant(&mut self, cfg: &dollop::config::Config, material: u8) -> Result<(), String> {
        let plant_cfg = self.plant_config.clone().unwrap_or_else(|| cfg.clone());
        if let Some(Connection::Simulated(s)) =
            self.client.as_mut().map(|c| &mut c.transport_mut().link)
        {
            s.set_plant(&plant_cfg, material)?;
        }
        Ok(())
    }

    /// Uploads the first queued job, homes if needed, and starts it.
    fn start_next(&mut self) -> Result<String, String> {
        let Some(entry) = self.queue.first().cloned() else {
            return Err("no job is waiting for this board".into());
        };
        if self.view.mode == Some(Mode::Job) {
            return Err("the board is printing; wait for the print to end or abort it".into());
        }
        let r = self.upload_and_start(&entry);
        self.view.upload = None;
        match r {
            Ok(m) => {
                self.queue.retain(|e| e.id != entry.id);
                Ok(m)
            }
            Err(LinkError::Cancelled(what)) => {
                let m = LinkError::Cancelled(what);
                self.queue.retain(|e| e.id != entry.id);
                self.view.activity = "idle".into();
                Err(format!(
                    "{}: {m}; it left the queue (send it again to print it)",
                    entry.figures.name
                ))
            }
            Err(e) => {
                if e.is_transient() || matches!(e, LinkError::Io(_) | LinkError::Stalled { .. }) {
                    self.lost(&e);
                }
                Err(format!(
                    "{} was not started: {e}; it stays in the queue",
                    entry.figures.name
                ))
            }
        }
    }

    fn upload_and_start(&mut self, entry: &Arc<JobEntry>) -> Result<String, LinkError> {
        let job = JobFile::parse(&entry.sliced.to_bytes())
            .map_err(|e| LinkError::Protocol(format!("the job does not check: {e}")))?;
        let Some(c) = self.client.as_mut() else {
            return Err(LinkError::Disconnected);
        };
        let hash = dollop::job::config_hash(&entry.config);
        let status = c.status()?;
        if status.config != Some(hash) {
            c.command(&Request::LoadConfig(entry.config.clone()))?;
            self.couple_plant(&entry.config, entry.sliced.header.initial_material)
                .map_err(LinkError::Protocol)?;
        }
        // Loaded now, or already there: the board's config either way.
        self.loaded.set(&entry.config, Some(&entry.config_text));
        let Some(c) = self.client.as_mut() else {
            return Err(LinkError::Disconnected);
        };
        c.command(&Request::Settings(dollop::wire::Settings::default()))?;
        self.view.activity = "uploading".into();
        self.view.job = Some(Queued {
            job: entry.id,
            name: entry.figures.name.clone(),
        });
        self.view.progress = 0.0;
        self.view.command = 0;
        self.view.elapsed_s = 0.0;
        // Before it starts (upload, homing): the whole estimate.
        self.view.eta_s = Some(entry.figures.est_time_s / self.speed);
        self.view.finish_unix_ms = self.view.eta_s.and_then(clock::unix_ms_in);
        let total = job.body.len() as u64;
        let vtx = self.vtx.clone();
        let mut shown = self.view.clone();
        // An Abort raised before the upload began stops it too.
        c.transport_mut().armed = true;
        let uploaded = c.upload(&job, &mut |p| {
            shown.upload = Some((p.acked, total));
            shown.seq += 1;
            let _ = vtx.send(shown.clone());
        });
        c.transport_mut().armed = false;
        let (commands, _) = uploaded?;
        self.view.seq = shown.seq;
        self.view.upload = None;
        self.view.commands = commands;
        // The job printed before is gone from the board: its figures (progress 1.0 while
        // the board still reports it Done) must not be shown for this one while it homes.
        self.current = None;
        let s = c.status()?;
        // The page has shown the status from before the config was loaded: show this one.
        self.show(&s);
        if !s.control.homed {
            self.home_and_wait()?;
        }
        let c = self.client.as_mut().ok_or(LinkError::Disconnected)?;
        c.command(&Request::Start)?;
        self.current = Some(Current {
            entry: entry.clone(),
            clock: PrintClock::start(Instant::now()),
            layer_starts: layer_starts(entry),
            aborted: false,
        });
        Ok(format!("{} uploaded and started", entry.figures.name))
    }

    /// Homes the board and waits for it to finish, showing every poll; an Abort ends the
    /// wait.
    fn home_and_wait(&mut self) -> Result<(), LinkError> {
        self.view.activity = "homing".into();
        self.publish_now();
        let c = self.client.as_mut().ok_or(LinkError::Disconnected)?;
        c.command(&Request::Home)?;
        let start = Instant::now();
        c.sleep(Duration::from_millis(5));
        loop {
            // An Abort waits behind this order: homing takes tens of seconds on a
            // real machine (7.5 s of wall time on the emulated board), so it is
            // looked at here and ends the wait (the worker then aborts the board).
            if self.cancel.load(Ordering::SeqCst) {
                return Err(LinkError::Cancelled(Cancelled::Homing));
            }
            let c = self.client.as_mut().ok_or(LinkError::Disconnected)?;
            let s = c.status()?;
            // Every poll is shown: the page's mode, position and update count move
            // while the machine homes (they stood still for the whole homing).
            self.show(&s);
            self.view.activity = "homing".into();
            self.publish_now();
            match s.control.mode {
                Mode::Idle => break,
                Mode::Halted => {
                    return Err(LinkError::Protocol(
                        mode_words(&s).unwrap_or_else(|| "homing failed".into()),
                    ))
                }
                _ => {}
            }
            if start.elapsed() > Duration::from_secs(300) {
                return Err(LinkError::Protocol(
                    "homing did not finish in 5 minutes; check the endstops".into(),
                ));
            }
            let c = self.client.as_mut().ok_or(LinkError::Disconnected)?;
            c.sleep(Duration::from_millis(50));
        }
        let c = self.client.as_mut().ok_or(LinkError::Disconnected)?;
        if !c.status()?.control.homed {
            return Err(LinkError::Protocol(
                "homing did not finish; check the endstops".into(),
            ));
        }
        Ok(())
    }

    fn publish_now(&mut self) {
        self.publish();
    }
}

/// Where each of the entry's layers starts along its toolpath.
fn layer_starts(entry: &JobEntry) -> Vec<u32> {
    let mut layer_starts = Vec::new();
    let mut last = usize::MAX;
    for (p, start) in entry
        .toolpath
        .paths
        .iter()
        .zip(entry.toolpath.starts.iter())
    {
        if p.l != last {
            last = p.l;
            layer_starts.push(*start);
        }
    }
    layer_starts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serve::design;

    #[test]
    fn the_page_reads_mode_and_run_by_name_and_empty_before_a_status() {
        let mut v = View::default();
        let j = serde_json::to_value(&v).expect("serializes");
        assert_eq!((&j["mode"], &j["run"]), (&"".into(), &"".into()));
        v.mode = Some(Mode::Job);
        v.run = Some(RunState::Pausing);
        let j = serde_json::to_value(&v).expect("serializes");
        assert_eq!((&j["mode"], &j["run"]), (&"Job".into(), &"Pausing".into()));
    }

    fn chessboard() -> Arc<JobEntry> {
        let checked = design::check(design::BUNDLED[0].1).expect("config");
        let uploads = [design::Upload {
            name: "chessboard.png".into(),
            bytes: design::DESIGNS[1].1.to_vec(),
        }];
        let form = design::SliceForm {
            width_mm: Some(8.0),
            ..Default::default()
        };
        let sliced = design::slice(&uploads, &checked.config, &form).expect("slices");
        let toolpath = design::toolpath(&sliced.commands, sliced.header.start_um, 0.8);
        let figures = design::figures(&sliced, &checked.config);
        Arc::new(JobEntry {
            id: 7,
            config: checked.config,
            config_text: checked.text,
            sliced,
            toolpath,
            figures,
        })
    }

    fn worker(speed: f64) -> Worker {
        let (vtx, _vrx) = tokio::sync::watch::channel(View::default());
        let mut w = Worker::new(None, speed, View::default(), vtx, Arc::default());
        w.connect();
        assert!(w.view.connected, "{:?}", w.view.message);
        w
    }

    #[test]
    fn a_board_gone_mid_upload_keeps_the_job_queued() {
        let mut w = worker(50.0);
        if let Some(Connection::Simulated(s)) =
            w.client.as_mut().map(|c| &mut c.transport_mut().link)
        {
            let m = s.mem();
            m.dead_after = Some(m.stats.host_frames + 12);
        }
        w.queue.push(chessboard());
        let e = w.start_next().expect_err("the upload fails");
        assert!(e.contains("stays in the queue"), "{e}");
        assert_eq!(w.queue.len(), 1);
        assert!(!w.view.connected);
        assert!(
            w.view
                .message
                .as_deref()
                .is_some_and(|m| m.contains("Lost the board")),
            "{:?}",
            w.view.message
        );
    }

    #[test]
    fn a_job_prints_to_the_end_and_orders_are_checked() {
        let mut w = worker(200.0);
        w.tick();
        let job = chessboard();
        // Nothing to pause or resume on an idle board: refused, not a success.
        for o in [WorkerOrder::Pause, WorkerOrder::Resume, WorkerOrder::Park] {
            let e = w.handle(o).expect_err("refused on an idle board");
            assert!(e.contains("no print is running"), "{e}");
        }
        assert_eq!(
            w.handle(WorkerOrder::Jog(Axis::X, f64::NAN, None))
                .err()
                .as_deref(),
            Some("jog distance NaN mm is not a plausible move")
        );
        assert!(w.handle(WorkerOrder::Valve(0, 60.0, None)).is_err());
        assert!(w
            .handle(WorkerOrder::Home(None))
            .err()
            .is_some_and(|e| e.contains("no machine config")));
        w.handle(WorkerOrder::Send(job)).expect("starts");
        assert!(w.queue.is_empty());
        let start = Instant::now();
        while w.view.progress < 1.0 {
            assert!(
                start.elapsed() < Duration::from_secs(120),
                "stuck at {} ({})",
                w.view.progress,
                w.view.activity
            );
            w.tick();
        }
        assert!(
            w.view.activity.starts_with("finished"),
            "{}",
            w.view.activity
        );
        assert_eq!(w.view.eta_s, Some(0.0));
        // Every command done, and the clock stopped with the print.
        assert_eq!(w.view.command, w.view.commands);
        assert!(w.view.commands > 10, "{}", w.view.commands);
        let elapsed = w.view.elapsed_s;
        std::thread::sleep(Duration::from_millis(150));
        w.tick();
        assert_eq!(w.view.elapsed_s, elapsed);
        assert_eq!((w.view.speed, w.view.eta_s), (0.0, Some(0.0)));
    }

    /// After an Abort mid-print nothing on the card goes on: the clock stops, the ETA
    /// goes, the speed and the model's flow read zero with the valves shut.
    #[test]
    fn abort_stops_the_clock_the_eta_the_speed_and_the_flow() {
        let mut w = worker(20.0);
        w.handle(WorkerOrder::Send(chessboard())).expect("starts");
        tick_until(&mut w, "printing", |v| {
            v.progress > 0.3 && v.run == Some(RunState::Printing) && v.speed > 0.0
        });
        let eta = w.view.eta_s.expect("an ETA while printing");
        let finish = w.view.finish_unix_ms.expect("a finishing time");
        assert!(eta > 0.0 && finish > 0.0, "{eta} {finish}");
        w.handle(WorkerOrder::Abort).expect("aborts");
        tick_until(&mut w, "aborted", |v| v.mode == Some(Mode::Idle));
        w.tick();
        let elapsed = w.view.elapsed_s;
        std::thread::sleep(Duration::from_millis(200));
        w.tick();
        let v = &w.view;
        assert_eq!(v.activity, "aborted");
        assert_eq!(v.elapsed_s, elapsed);
        assert_eq!((v.eta_s, v.finish_unix_ms), (None, None));
        assert_eq!((v.valves, v.speed, v.flow_model), (0, 0.0, 0.0));
        assert!(v.refused.contains_key("pause") && !v.refused.contains_key("home"));
    }

    /// A job sent while the board homes is queued, and starts by itself once homing ends.
    #[test]
    fn a_job_sent_while_homing_starts_when_the_board_is_free() {
        let mut w = worker(20.0);
        let cfg = design::check(design::BUNDLED[0].1).expect("config").config;
        w.handle(WorkerOrder::Home(Some(Box::new(cfg))))
            .expect("homes");
        w.tick();
        assert_eq!(w.view.mode, Some(Mode::Homing));
        let m = w.handle(WorkerOrder::Send(chessboard())).expect("queued");
        assert!(m.contains("starts when the board is free"), "{m}");
        assert_eq!(w.queue.len(), 1);
        tick_until(&mut w, "the queued job", |v| v.mode == Some(Mode::Job));
        assert!(w.queue.is_empty());
        assert_eq!(w.view.job.as_ref().map(|j| j.job), Some(7));
    }

    /// The same job queued twice: a remove takes back one copy, not both (the browser
    /// test's held click on the second copy's remove emptied the queue).
    #[test]
    fn unqueue_takes_back_one_copy() {
        let mut w = worker(20.0);
        w.queue.push(chessboard());
        w.queue.push(chessboard());
        w.handle(WorkerOrder::Unqueue(7)).expect("removed");
        assert_eq!(w.queue.len(), 1);
        w.handle(WorkerOrder::Unqueue(7)).expect("removed");
        assert!(w.handle(WorkerOrder::Unqueue(7)).is_err());
    }

    /// A refusal on the card goes after `MESSAGE_S` (it used to stay for good).
    #[test]
    fn a_message_expires() {
        let mut w = worker(20.0);
        w.say("old news");
        w.publish();
        assert_eq!(w.view.message.as_deref(), Some("old news"));
        w.message_at = Instant::now().checked_sub(Duration::from_secs(MESSAGE_S));
        w.publish();
        assert_eq!(w.view.message, None);
    }

    /// Park from the card: the board pauses, the view shows the latency (valves shut no
    /// later than the head at rest) and the pause point, the head parks (lifted, off the
    /// point) and Resume brings it back to print to the end.
    #[test]
    fn park_shows_latency_and_pause_point_and_resume_prints_on() {
        let mut w = worker(50.0);
        w.handle(WorkerOrder::Send(chessboard())).expect("starts");
        let start = Instant::now();
        let until = |w: &mut Worker, what: &str, done: &dyn Fn(&View) -> bool| {
            while !done(&w.view) {
                assert!(
                    start.elapsed() < Duration::from_secs(120),
                    "{what}: {} at {}",
                    w.view.activity,
                    w.view.progress
                );
                w.tick();
            }
        };
        until(&mut w, "printing", &|v| {
            v.progress > 0.2 && v.run == Some(RunState::Printing)
        });
        w.handle(WorkerOrder::Park).expect("parks");
        until(&mut w, "parked", &|v| {
            v.pause_point.is_some_and(|p| v.position[2] > p[2] + 4.9)
        });
        assert_eq!(w.view.activity, "paused");
        let [shut, rest] = w.view.pause_latency_ms.expect("latency shown");
        let (shut, rest) = (shut.expect("valves shut"), rest.expect("head at rest"));
        assert!(shut <= rest && rest < 5_000.0, "{shut} / {rest} ms");
        eprintln!("park from the card: valves shut {shut:.0} ms, head at rest {rest:.0} ms (polled, board time)");
        w.handle(WorkerOrder::Resume).expect("resumes");
        until(&mut w, "resumed", &|v| v.progress >= 1.0);
        assert_eq!(w.view.pause_point, None);
    }

    /// Prints the chessboard on a simulated board whose plant is built from `plant` (None:
    /// the loaded config) and returns the flow shown and the executor's model flow, each
    /// integrated over board time from the values at each poll, mm³.
    fn printed_volumes(plant: Option<dollop::config::Config>) -> (f64, f64) {
        let mut w = worker(200.0);
        w.plant_config = plant;
        w.handle(WorkerOrder::Send(chessboard())).expect("starts");
        let (mut shown, mut model) = (0.0, 0.0);
        let board_now = |w: &Worker| {
            w.client
                .as_ref()
                .map(|c| c.transport().now())
                .expect("connected")
        };
        let mut last = board_now(&w);
        let start = Instant::now();
        while w.view.progress < 1.0 {
            assert!(
                start.elapsed() < Duration::from_secs(120),
                "stuck at {}",
                w.view.progress
            );
            w.tick();
            assert_eq!(w.view.flow_source, "plant");
            assert_eq!(w.view.line_kpa.len(), 2);
            let now = board_now(&w);
            let dt = (now - last).as_secs_f64();
            last = now;
            shown += w.view.flow * dt;
            model += w.view.flow_model * dt;
        }
        (shown, model)
    }

    #[test]
    fn the_simulated_board_shows_the_plants_flow() {
        // The same machine as configured: the plant follows the executor's valves, so the
        // volumes agree closely (but are not the model's numbers).
        let (same, model) = printed_volumes(None);
        eprintln!("plant as configured: shown {same:.1} mm³, model {model:.1} mm³");
        assert!(model > 1.0, "nothing printed: {model}");
        assert!((same / model - 1.0).abs() < 0.15, "{same} vs {model}");
        assert_ne!(same, model);
        // Pastes twice as viscous as the config says, fed the pressures the config's
        // "auto" works out: the plant (a real printer) gives about half the flow.
        let text = design::BUNDLED[0].1;
        let cfg = design::check(text).expect("config").config;
        let m = cfg
            .validate::<f64, { dollop::config::MAX_CONFIG_INLETS }>()
            .expect("validates");
        let mut thick = text
            .replace("viscosity_pa_s = 1.41", "viscosity_pa_s = 2.82")
            .replace("viscosity_pa_s = 3.17", "viscosity_pa_s = 6.34");
        for inlet in m.inlets.iter() {
            thick = thick.replacen(
                "pressure_kpa = \"auto\"",
                &format!("pressure_kpa = {}", inlet.supply_pa / 1e3),
                1,
            );
        }
        assert!(!thick.contains("pressure_kpa = \"auto\""), "{thick}");
        let thick = design::check(&thick).expect("thick config").config;
        let (shown, model2) = printed_volumes(Some(thick));
        eprintln!("plant twice as viscous: shown {shown:.1} mm³, model {model2:.1} mm³");
        // (The integrals sample the flow at the worker's polls, irregular in board time:
        // compare each run's plant with its own model, over the same samples.)
        assert!(shown < 0.7 * model2, "{shown} vs {model2}");
        assert!(shown > 0.3 * model2, "{shown} vs {model2}");
    }

    /// Ticks the worker until `done` holds (board time runs at `speed` times the wall's).
    fn tick_until(w: &mut Worker, what: &str, done: impl Fn(&View) -> bool) {
        let start = Instant::now();
        while !done(&w.view) {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "waiting for {what}: {} {:?}",
                w.view.activity,
                w.view.message
            );
            w.tick();
        }
    }

    #[test]
    fn home_jog_and_valve_test_work_before_any_job_with_the_pages_config() {
        let mut w = worker(20.0);
        let cfg = || {
            Some(Box::new(
                design::check(design::BUNDLED[0].1).expect("config").config,
            ))
        };
        // Jogging an unhomed machine is the board's to refuse, as with the CLI.
        let jog = w.handle(WorkerOrder::Jog(Axis::X, 5.0, cfg()));
        assert!(jog.is_err(), "{jog:?}");
        w.handle(WorkerOrder::Home(cfg())).expect("homes");
        w.tick();
        tick_until(&mut w, "homing", |v| v.homed && v.mode == Some(Mode::Idle));
        let x0 = w.view.position[0];
        let jog = w
            .handle(WorkerOrder::Jog(Axis::X, 5.0, None))
            .expect("jogs");
        assert!(jog.contains("jogging"), "{jog}");
        w.tick();
        tick_until(&mut w, "the jog", |v| {
            v.mode == Some(Mode::Idle) && (v.position[0] - x0 - 5.0).abs() < 0.01
        });
        w.handle(WorkerOrder::Valve(1, 0.5, None)).expect("opens");
        w.tick();
        assert_eq!(w.view.valves, 2, "{:?}", w.view.mode);
        // The plant's line fills and its flow follows; then the valve closes by itself.
        tick_until(&mut w, "flow", |v| v.flow > 0.1 && v.line_kpa[1] > 1.0);
        tick_until(&mut w, "the valve closing", |v| v.valves == 0);
    }

    #[test]
    fn homing_before_a_job_is_shown_live_and_abort_ends_it_at_once() {
        // Found driving the emulated firmware (scripts/emulate --fil serve): while the
        // send order homed, the page kept the status from before the config was loaded
        // (mode Unconfigured, the head at 0, the update count still) for the whole 7.5 s,
        // and an Abort would have waited behind the homing (up to its 5 minute limit).
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime");
        let board = spawn(0, "sim".into(), "simulated".into(), None, 1.0);
        rt.block_on(async {
            let mut view = board.view.clone();
            while !view.borrow().connected {
                view.changed().await.expect("worker runs");
            }
            let b = board.clone();
            let send = tokio::spawn(async move { b.order(WorkerOrder::Send(chessboard())).await });
            // The board's own Homing mode, then the head moving and the count going on.
            // (Bounded: a page that never sees the mode would otherwise wait for ever.)
            let homing = tokio::time::timeout(Duration::from_secs(30), async {
                loop {
                    view.changed().await.expect("worker runs");
                    let v = view.borrow().clone();
                    if v.activity == "homing" && v.mode == Some(Mode::Homing) {
                        return (v.seq, v.position);
                    }
                    assert_ne!(v.activity, "printing", "homing was never shown: {v:?}");
                }
            });
            let (seq0, pos0) = homing.await.expect("homing shown within 30 s");
            let moved = loop {
                view.changed().await.expect("worker runs");
                let v = view.borrow().clone();
                assert_eq!(v.activity, "homing", "homing ended before the test looked");
                if v.seq >= seq0 + 3 && v.position != pos0 {
                    break v;
                }
            };
            assert_eq!(moved.progress, 0.0);
            let t = Instant::now();
            let aborted = board.abort().await;
            let took = t.elapsed();
            let sent = send.await.expect("joins");
            eprintln!("abort while homing (updates {seq0}..{}): answered in {took:?}: {aborted:?}; the send: {sent:?}", moved.seq);
            assert!(aborted.is_ok(), "{aborted:?}");
            assert!(took < Duration::from_secs(1), "{took:?}");
            let e = sent.expect_err("the homing was cancelled");
            assert!(e.contains("homing cancelled by Abort"), "{e}");
            tokio::time::sleep(Duration::from_millis(300)).await;
            let v = board.view.borrow().clone();
            assert!(v.queue.is_empty(), "{:?}", v.queue);
            assert_ne!(v.mode, Some(Mode::Homing));
            assert_ne!(v.mode, Some(Mode::Job));
            assert!(v.connected, "{:?}", v.message);
        });
    }

    #[test]
    fn abort_cuts_an_upload_short_and_aborts_at_once() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime");
        // A bigger job (the logo 120 mm wide: 4 166 bytes, 17 frames, more than the link's
        // window of 8), on a board at the wall clock's pace.
        let checked = design::check(design::BUNDLED[0].1).expect("config");
        let uploads = [design::Upload {
            name: "logo.png".into(),
            bytes: design::DESIGNS[0].1.to_vec(),
        }];
        let form = design::SliceForm {
            width_mm: Some(120.0),
            ..Default::default()
        };
        let sliced = design::slice(&uploads, &checked.config, &form).expect("slices");
        let entry = Arc::new(JobEntry {
            id: 9,
            toolpath: design::toolpath(&sliced.commands, sliced.header.start_um, 0.8),
            figures: design::figures(&sliced, &checked.config),
            config: checked.config,
            config_text: checked.text,
            sliced,
        });
        // Each frame 40 ms on its way: the upload lasts long enough to be seen under way
        // however loaded the machine is (at full speed it can end between two looks, and
        // the loop below would then wait on a print).
        let board = spawn_with(
            0,
            "sim".into(),
            "simulated".into(),
            None,
            1.0,
            Duration::from_millis(40),
            None,
        );
        rt.block_on(async {
            let mut view = board.view.clone();
            while !view.borrow().connected {
                view.changed().await.expect("worker runs");
            }
            let b = board.clone();
            let send = tokio::spawn(async move { b.order(WorkerOrder::Send(entry)).await });
            let seen = tokio::time::timeout(Duration::from_secs(120), async {
                loop {
                    view.changed().await.expect("worker runs");
                    let v = view.borrow().clone();
                    if let Some((acked, total)) = v.upload {
                        if acked > 0 {
                            assert!(acked < total, "the upload ended before the abort");
                            return total;
                        }
                    }
                    assert!(
                        v.upload.is_some() || v.activity == "uploading" || v.mode != Some(Mode::Job),
                        "the upload ended unseen: {v:?}"
                    );
                }
            })
            .await;
            let total = seen.expect("the upload was never seen under way in 120 s");
            let t = Instant::now();
            let aborted = board.abort().await;
            let took = t.elapsed();
            let sent = send.await.expect("joins");
            eprintln!("abort during an upload of {total} bytes: answered in {took:?}: {aborted:?}; the send: {sent:?}");
            assert!(aborted.is_ok(), "{aborted:?}");
            assert!(took < Duration::from_secs(1), "{took:?}");
            let e = sent.expect_err("the upload was cancelled");
            assert!(e.contains("upload cancelled by Abort"), "{e}");
            tokio::time::sleep(Duration::from_millis(300)).await;
            let v = board.view.borrow().clone();
            assert_eq!(v.upload, None);
            assert!(v.queue.is_empty(), "{:?}", v.queue);
            assert_ne!(v.mode, Some(Mode::Job));
            assert!(v.connected, "{:?}", v.message);
        });
    }
}
