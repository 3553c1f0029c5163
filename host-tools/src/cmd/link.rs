//! `dollop send|status|pause|resume|abort|jog|valve`: the board's USB commands. Each opens
//! the board's port (auto-detected by USB VID/PID unless `--port` names it), says hello,
//! and does its one thing through `link::Client`; `send` and `resume` then follow the
//! print, and Ctrl-C pauses it safely.

use crate::link::{ops, Client, JobFile, Options, Progress, SerialLink, Transport};
use anyhow::{bail, Context};
use dollop::wire::{Halt, JobSlot, LinkLossPolicy, Mode, Request, Settings, Status, POLL_MS};
use dollop::{Axis, Config, RunState};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Serial port selection.
#[derive(clap::Args, Debug)]
pub struct PortArgs {
    /// The board's port: a serial device (its USB port, or a host serial port wired to the
    /// board's UART, 1 Mbaud), or tcp:HOST:PORT (an emulated board, a serial server).
    /// Default: the USB board found by its VID/PID.
    #[arg(long)]
    pub port: Option<String>,
}

/// Arguments of `dollop pause`.
#[derive(clap::Args, Debug)]
pub struct PauseArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Park once the head rests: lift Z by the config's `pause.park_lift_mm` and move to
    /// `pause.park_position_mm`; `dollop resume` comes back, lowers, then prints on.
    /// Asked while paused, it parks from the pause point.
    #[arg(long)]
    pub park: bool,
    /// Syringe machines, while parked: retract every plunger to where its fill began (it
    /// counts from there after the refill); refill, then `dollop resume`.
    #[arg(long, conflicts_with = "park")]
    pub refill: bool,
}

/// What the board does when the link is lost while it prints.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum LossArg {
    /// Pause mid-bead (valves shut, head stopped where the paste's tail ends), then hold
    /// until resumed.
    Pause,
    /// Stop at once: valves closed, drivers off.
    Stop,
}

/// Arguments of `dollop send`.
#[derive(clap::Args, Debug)]
pub struct SendArgs {
    /// Job file (.dlp).
    pub job: PathBuf,
    #[command(flatten)]
    pub port: PortArgs,
    /// Machine config (TOML) to load on the board first, if the board's differs.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// What the board does if the link is lost while it prints.
    #[arg(long, value_enum, default_value = "pause")]
    pub on_link_loss: LossArg,
    /// Upload and check the job, but do not start it.
    #[arg(long)]
    pub upload_only: bool,
}

/// An axis on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum AxisArg {
    /// X
    X,
    /// Y
    Y,
    /// Z
    Z,
}

/// Arguments of `dollop jog`.
#[derive(clap::Args, Debug)]
pub struct JogArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Axis to move.
    #[arg(value_enum, required_unless_present = "home")]
    pub axis: Option<AxisArg>,
    /// Distance in mm (negative: towards the minimum).
    #[arg(allow_negative_numbers = true, required_unless_present = "home")]
    pub mm: Option<f64>,
    /// Home all axes against their endstops instead.
    #[arg(long, conflicts_with_all = ["axis", "mm"])]
    pub home: bool,
}

/// Valve state on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum OnOff {
    /// Open.
    On,
    /// Close.
    Off,
}

/// Arguments of `dollop valve`.
#[derive(clap::Args, Debug)]
pub struct ValveArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Valve (inlet) number, from 0.
    pub inlet: u8,
    /// Open (on) or close (off).
    #[arg(value_enum)]
    pub state: OnOff,
    /// With `on`: close again after this many seconds (default: on Ctrl-C). The board
    /// closes it by itself when the link goes silent.
    #[arg(long)]
    pub seconds: Option<f64>,
}

type Board = Client<SerialLink>;

fn connect(p: &PortArgs) -> anyhow::Result<Board> {
    let link = SerialLink::open(p.port.as_deref())?;
    let path = link.path().to_string();
    let opts = Options::default();
    let mut c = Client::open(link, opts);
    // Within a second and then every few, say what the command waits for.
    let waiting_on = path.clone();
    let rto_ms = opts.rto.as_millis() as u64;
    c.on_silence(move |s| {
        let waited_ms = u64::from(s.tries) * rto_ms;
        if s.tries == 1 || waited_ms % 3000 < rto_ms {
            eprintln!(
                "waiting for the board on {waiting_on}: no answer yet after {:.1} s (hello {} of {}); Ctrl-C to stop",
                waited_ms as f64 / 1000.0,
                s.tries,
                s.of
            );
        }
    });
    let info = c
        .connect()
        .with_context(|| format!("talking to the board on {path}"))?;
    eprintln!(
        "board \"{}\" (firmware {}, link protocol {}) on {path}",
        info.board, info.firmware, info.version
    );
    Ok(c)
}

fn interrupted() -> &'static AtomicBool {
    static FLAG: OnceLock<&'static AtomicBool> = OnceLock::new();
    FLAG.get_or_init(|| {
        let flag: &'static AtomicBool = Box::leak(Box::new(AtomicBool::new(false)));
        // If a handler cannot be installed Ctrl-C ends the process; the board then pauses
        // by its link-loss policy, which is safe too.
        let _ = ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst));
        flag
    })
}

fn bar(len: u64, template: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template(template) {
        pb.set_style(style.progress_chars("=> "));
    }
    pb
}

fn read_config(path: &PathBuf) -> anyhow::Result<Config> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read config {}", path.display()))?;
    toml::from_str(&text).with_context(|| format!("config {}", path.display()))
}

/// `dollop send`.
pub fn send(a: SendArgs) -> anyhow::Result<()> {
    let job = JobFile::read(&a.job)?;
    let mut c = connect(&a.port)?;
    send_on(&mut c, &job, &a)
}

/// The body of `dollop send` on any transport (tests drive it over the in-memory link).
pub fn send_on<T: Transport>(c: &mut Client<T>, job: &JobFile, a: &SendArgs) -> anyhow::Result<()> {
    let mut board_config = c.info().and_then(|i| i.config);
    if let Some(path) = &a.config {
        let cfg = read_config(path)?;
        let hash = dollop::job::config_hash(&cfg);
        if board_config != Some(hash) {
            c.command(&Request::LoadConfig(cfg))
                .context("loading the config")?;
            eprintln!("loaded config {} ({hash:08x})", path.display());
            board_config = Some(hash);
        }
    }
    match board_config {
        None => bail!("the board has no machine config; pass --config FILE (the one the job was sliced for)"),
        Some(h) if h != job.header.config_hash => bail!(
            "the job was sliced for config {:08x} but the board has {h:08x}; pass --config FILE with the job's config, or re-slice",
            job.header.config_hash
        ),
        _ => {}
    }
    let settings = Settings {
        on_link_loss: match a.on_link_loss {
            LossArg::Pause => LinkLossPolicy::Pause,
            LossArg::Stop => LinkLossPolicy::Stop,
        },
        ..Settings::default()
    };
    c.command(&Request::Settings(settings))?;

    let total = job.body.len() as u64;
    let segments = job.segments() as u64;
    let pb = bar(
        total,
        "uploading [{bar:30}] {bytes}/{total_bytes} {msg} {binary_bytes_per_sec} ETA {eta}",
    );
    let (commands, counted) = c
        .upload(job, &mut |p: Progress| {
            pb.set_position(p.acked);
            let seg = segments * p.acked / p.total.max(1);
            pb.set_message(format!("{seg}/{segments} segments"));
        })
        .context("uploading the job")?;
    pb.finish_and_clear();
    eprintln!("job on the board and checked: {counted} print segments, {commands} commands");
    if a.upload_only {
        eprintln!("not started (--upload-only); `dollop send` the same job again to start it");
        return Ok(());
    }
    interrupted();
    ensure_homed(c)?;
    c.command(&Request::Start).context("starting the job")?;
    eprintln!("printing; Ctrl-C pauses safely");
    follow(c, commands)
}

/// Homes the machine if it is not homed, and waits for it.
fn ensure_homed<T: Transport>(c: &mut Client<T>) -> anyhow::Result<()> {
    if c.status()?.control.homed {
        return Ok(());
    }
    eprintln!("homing");
    ops::home_and_wait(c).map_err(waited)?;
    Ok(())
}

/// A wait that did not end at rest, in the command line's words (a halt names
/// `dollop abort`, which clears it).
fn waited(e: ops::WaitError) -> anyhow::Error {
    match e {
        ops::WaitError::Halted(s) => anyhow::anyhow!("{}", halted(&s)),
        ops::WaitError::Link(e) => e.into(),
        other => anyhow::anyhow!("{other}"),
    }
}

fn halted(s: &Status) -> String {
    match s.control.halt {
        Some(Halt::Fault(dollop::Fault::EStop)) if s.control.estop => {
            "emergency stop (input still active: release it, then `dollop abort` clears it)".into()
        }
        Some(h) => format!("the board halted: {h}; `dollop abort` clears it"),
        None => "the board halted".into(),
    }
}

/// Follows a running job until it ends; Ctrl-C pauses it.
fn follow<T: Transport>(c: &mut Client<T>, commands: u32) -> anyhow::Result<()> {
    let flag = interrupted();
    let pb = bar(
        commands as u64,
        "printing [{bar:30}] {pos}/{len} commands {msg} ETA {eta}",
    );
    let started = Instant::now();
    // Let the control loop take the start order before reading its state.
    c.sleep(Duration::from_millis(5));
    loop {
        if flag.swap(false, Ordering::SeqCst) {
            c.command(&Request::Pause)?;
            pb.abandon();
            eprintln!(
                "pausing (valves shut, the head stops where the paste's tail ends).\n  resume: dollop resume\n  stop:   dollop abort"
            );
            return Ok(());
        }
        let s = c.status()?;
        let k = &s.control;
        pb.set_position(k.command as u64);
        pb.set_message(format!(
            "{:?} at ({:.2}, {:.2}, {:.2}) mm, valves {:04b}, {:.1} mm/s",
            k.run,
            k.position_um[0] as f64 / 1000.0,
            k.position_um[1] as f64 / 1000.0,
            k.position_um[2] as f64 / 1000.0,
            k.valves,
            k.speed_mm_s
        ));
        match (k.mode, k.run) {
            (Mode::Job, RunState::Paused) => {
                pb.abandon();
                eprintln!(
                    "the print is paused{}.\n  resume: dollop resume\n  stop:   dollop abort",
                    if s.link_lost {
                        " (the link was lost)"
                    } else {
                        ""
                    }
                );
                return Ok(());
            }
            (Mode::Job, _) => {}
            (Mode::Halted, _) => {
                pb.abandon();
                bail!("{}", halted(&s));
            }
            (_, RunState::Done) => {
                pb.finish_and_clear();
                eprintln!("done in {:.0} s", started.elapsed().as_secs_f64());
                return Ok(());
            }
            (m, _) => {
                pb.abandon();
                bail!("the job stopped (board now {m:?}); it was aborted");
            }
        }
        c.sleep(Duration::from_millis(POLL_MS as u64 / 2));
    }
}

fn describe(s: &Status) -> String {
    let k = &s.control;
    let mut out = format!(
        "mode: {:?} ({:?}), {}, drivers {}, valves open {:04b}\nposition: x {:.3} y {:.3} z {:.3} mm\n",
        k.mode,
        k.run,
        if k.homed { "homed" } else { "not homed" },
        if k.drivers { "on" } else { "off" },
        k.valves,
        k.position_um[0] as f64 / 1000.0,
        k.position_um[1] as f64 / 1000.0,
        k.position_um[2] as f64 / 1000.0,
    );
    if let Some(p) = k.pause_point_um {
        out.push_str(&format!(
            "pause point: x {:.3} y {:.3} z {:.3} mm (the print goes on from here)\n",
            p[0] as f64 / 1000.0,
            p[1] as f64 / 1000.0,
            p[2] as f64 / 1000.0
        ));
    }
    out.push_str(&match s.config {
        Some(h) => format!("config: {h:08x}\n"),
        None => "config: none loaded\n".into(),
    });
    out.push_str(&match s.job {
        JobSlot::Empty => "job: none".into(),
        JobSlot::Preparing { .. } => "job: preparing the store".into(),
        JobSlot::Receiving { id, received } => {
            format!("job: uploading, {received} of {} bytes", id.body_len)
        }
        JobSlot::Verifying { id, checked } => {
            format!("job: checking, {checked} of {} bytes", id.body_len)
        }
        JobSlot::Ready {
            commands, segments, ..
        } => format!(
            "job: ready, {segments} print segments; at command {} of {commands}",
            k.command
        ),
        JobSlot::Failed { why, .. } => format!("job: failed: {why}"),
    });
    out.push('\n');
    if let Some(h) = k.halt {
        out.push_str(&format!("halted: {h}\n"));
    }
    if k.estop {
        out.push_str("emergency stop input: ACTIVE\n");
    }
    let e = &s.line_errors;
    if e.any() {
        out.push_str(&format!(
            "host UART receive errors since start: overrun {}, framing {}, noise {}, parity {} (each costs a resent frame; see docs/bring-up.md)\n",
            e.overrun, e.framing, e.noise, e.parity
        ));
    }
    if s.link_lost {
        out.push_str("the link was lost while the job ran; the link-loss policy applied\n");
    }
    out
}

/// `dollop status`.
pub fn status(a: PortArgs) -> anyhow::Result<()> {
    let mut c = connect(&a)?;
    let s = c.status()?;
    print!("{}", describe(&s));
    Ok(())
}

/// `dollop pause [--park | --refill]`.
pub fn pause(args: PauseArgs) -> anyhow::Result<()> {
    let a = &args.port;
    let mut c = connect(a)?;
    if args.refill {
        c.command(&Request::Refill)?;
        eprintln!(
            "refill: the plungers retract to where their fill began (if parked on a syringe machine); refill, then `dollop resume`"
        );
        return Ok(());
    }
    if args.park {
        c.command(&Request::Park)?;
        eprintln!(
            "pausing to park: valves shut, the head stops where the paste's tail ends, then lifts and moves to the park position"
        );
    } else {
        c.command(&Request::Pause)?;
        eprintln!("pausing: valves shut, the head stops where the paste's tail ends");
    }
    // The board says Pausing until the head rests at the pause point.
    let asked = Instant::now();
    while asked.elapsed() < Duration::from_secs(30) {
        let s = c.status()?;
        let k = &s.control;
        if k.run == RunState::Paused {
            let p = k.pause_point_um.unwrap_or(k.position_um);
            eprintln!(
                "paused at ({:.3}, {:.3}, {:.3}) mm, {:.0} ms after the request; {}`dollop resume` continues",
                p[0] as f64 / 1000.0,
                p[1] as f64 / 1000.0,
                p[2] as f64 / 1000.0,
                asked.elapsed().as_secs_f64() * 1e3,
                if args.park {
                    "the head now lifts and moves to the park position (`dollop status` shows it); "
                } else {
                    ""
                }
            );
            return Ok(());
        }
        if k.mode != Mode::Job {
            eprintln!("no print to pause (the board is {:?})", k.mode);
            return Ok(());
        }
        c.sleep(Duration::from_millis(20));
    }
    eprintln!("still pausing after 30 s (`dollop status` shows the state)");
    Ok(())
}

/// `dollop resume`: resumes and follows the print (the board pauses again if the link
/// stays silent).
pub fn resume(a: PortArgs) -> anyhow::Result<()> {
    let mut c = connect(&a)?;
    interrupted();
    let total = match c.status()?.job {
        JobSlot::Ready { commands, .. } => commands,
        _ => 0,
    };
    c.command(&Request::Resume)?;
    eprintln!("resumed; Ctrl-C pauses safely");
    follow(&mut c, total)
}

/// `dollop abort`: stops now (valves closed, drivers off) and clears a halt.
pub fn abort(a: PortArgs) -> anyhow::Result<()> {
    let mut c = connect(&a)?;
    eprintln!("{}", ops::abort_and_clear(&mut c)?);
    Ok(())
}

/// `dollop jog`.
pub fn jog(a: JogArgs) -> anyhow::Result<()> {
    let mut c = connect(&a.port)?;
    jog_on(&mut c, &a)
}

/// The body of `dollop jog` on any transport.
pub fn jog_on<T: Transport>(c: &mut Client<T>, a: &JogArgs) -> anyhow::Result<()> {
    let s = if a.home {
        eprintln!("homing");
        ops::home_and_wait(c).map_err(waited)?
    } else {
        let (Some(axis), Some(mm)) = (a.axis, a.mm) else {
            bail!("name an axis and a distance, e.g. `dollop jog x 10`, or use --home");
        };
        let um = ops::jog_um(mm)?;
        let axis = match axis {
            AxisArg::X => Axis::X,
            AxisArg::Y => Axis::Y,
            AxisArg::Z => Axis::Z,
        };
        ops::jog(c, axis, um)?;
        ops::wait_idle(c, Duration::from_secs(300)).map_err(waited)?
    };
    let p = s.control.position_um;
    eprintln!(
        "at x {:.3} y {:.3} z {:.3} mm",
        p[0] as f64 / 1000.0,
        p[1] as f64 / 1000.0,
        p[2] as f64 / 1000.0
    );
    Ok(())
}

/// `dollop valve`: opens a valve and holds it open while this command runs (until
/// Ctrl-C or `--seconds`), or closes it.
pub fn valve(a: ValveArgs) -> anyhow::Result<()> {
    let mut c = connect(&a.port)?;
    valve_on(&mut c, &a)
}

/// The body of `dollop valve` on any transport.
pub fn valve_on<T: Transport>(c: &mut Client<T>, a: &ValveArgs) -> anyhow::Result<()> {
    let open = matches!(a.state, OnOff::On);
    c.command(&Request::Valve {
        inlet: a.inlet,
        open,
    })?;
    if !open {
        eprintln!("valve {} closed", a.inlet);
        return Ok(());
    }
    let flag = interrupted();
    let limit = a.seconds.filter(|s| s.is_finite() && *s >= 0.0);
    eprintln!(
        "valve {} open; {}",
        a.inlet,
        match limit {
            Some(s) => format!("closing after {s} s (Ctrl-C closes it sooner)"),
            None => "Ctrl-C closes it".into(),
        }
    );
    let start = c.transport().now();
    // Polling keeps the link alive: a silent link makes the board close the valve.
    loop {
        if flag.swap(false, Ordering::SeqCst) {
            break;
        }
        if limit.is_some_and(|s| c.transport().now().saturating_sub(start).as_secs_f64() >= s) {
            break;
        }
        let s = c.status()?;
        if s.control.valves & (1 << a.inlet) == 0 && s.control.mode != Mode::ValveTest {
            bail!("the valve closed by itself ({:?})", s.control.mode);
        }
        c.sleep(Duration::from_millis(POLL_MS as u64 / 2));
    }
    c.command(&Request::Valve {
        inlet: a.inlet,
        open: false,
    })?;
    eprintln!("valve {} closed", a.inlet);
    Ok(())
}
