//! The link's messages: what the host asks (`Request`), what the device answers (`Reply`),
//! and the status, settings and refusal types inside them. Serde types only; framing is
//! `frame`'s, acting on them is `device`'s and the host client's.

use super::TEXT_LEN;
use crate::config::Config;
use crate::job::{JobError, JobHeader};
use crate::outputs::Axis;
use crate::state::{Fault, RunState};
use core::fmt;
use serde::{Deserialize, Serialize};

/// A short text (config errors, reasons), cut at `TEXT_LEN` bytes.
pub type Text = heapless::String<TEXT_LEN>;

/// Formats into a `Text`, cutting what does not fit.
pub fn text(args: fmt::Arguments<'_>) -> Text {
    struct Cut(Text);
    impl fmt::Write for Cut {
        fn write_str(&mut self, s: &str) -> fmt::Result {
            for c in s.chars() {
                if self.0.push(c).is_err() {
                    break;
                }
            }
            Ok(())
        }
    }
    let mut t = Cut(Text::new());
    let _ = fmt::write(&mut t, args);
    t.0
}

/// Header of every host frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct HostHeader {
    /// Session id the host chose in its hello.
    pub session: u16,
    /// Sequence number of this request.
    pub seq: u16,
}

/// Header of every device frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceHeader {
    /// Session the reply belongs to (the host ignores others).
    pub session: u16,
    /// Sequence number of the frame this answers (stale answers are told apart by it).
    pub answers: u16,
    /// Sequence number the device expects next: everything before it was taken.
    pub next: u16,
    /// Job chunks the device can take beyond `next`.
    pub credit: u8,
}

/// What the host asks. `Hello` must stay the first variant with `version` its first field.
// `LoadConfig` dwarfs the rest, but there is no heap to box it into: a request is decoded
// once, into one buffer, so the size is paid once rather than per message.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Request<'a> {
    /// Opens a session; the device answers `Reply::Hello`.
    Hello {
        /// The host's `PROTOCOL_VERSION`.
        version: u16,
    },
    /// Asks for `Reply::Status`.
    Status,
    /// Loads a machine config (validated on the device as well); only while no job runs.
    LoadConfig(Config),
    /// Board settings: homing and the link-loss policy.
    Settings(Settings),
    /// Begins uploading a job: its header (size, CRC, config hash, bounds).
    BeginJob(JobHeader),
    /// A piece of the job body.
    Chunk {
        /// Byte offset in the body.
        offset: u32,
        /// The bytes, at most `MAX_CHUNK`.
        #[serde(borrow)]
        data: &'a [u8],
    },
    /// The whole body was sent: the device checks it (length, CRC, commands) before it
    /// can be started. `Status` tells when the check is done.
    EndJob,
    /// Starts the uploaded, checked job (homed machine, matching config).
    Start,
    /// Pauses mid-bead: valves shut where the flow's tail lands on the bead (or at the
    /// current bead's end when that comes first), the head stops at the pause point and
    /// holds. `Status` shows Pausing, then Paused.
    Pause,
    /// Continues after a pause, from the pause point (refused with nothing paused).
    Resume,
    /// Stops now: valves closed, motion stopped, drivers off.
    Abort,
    /// Emergency stop, as the input pin: safe state, latched until `ClearFault`.
    EStop,
    /// Acknowledges a fault, abort or emergency stop (the e-stop input must be released).
    ClearFault,
    /// Homes all axes against their endstops.
    Home,
    /// Moves one axis by hand (homed machine, within the soft limits).
    Jog {
        /// The axis.
        axis: Axis,
        /// Distance, micrometres (negative: towards the minimum).
        um: i32,
    },
    /// Opens or closes one valve by hand (valve test), only while no job runs.
    Valve {
        /// Inlet index.
        inlet: u8,
        /// Open (true) or close.
        open: bool,
    },
    /// Pauses as `Pause` does, then parks: once the head rests at the pause point it
    /// lifts Z by the config's `pause.park_lift_mm` and moves to `pause.park_position_mm`
    /// (asked while paused, it parks from the pause point). `Resume` comes back over the
    /// pause point, lowers, then restarts the flow. (Protocol 3.)
    Park,
    /// Syringe machines, while parked: every plunger retracts to where its fill began
    /// and counts from there (refill the syringes, then `Resume`). (Protocol 3.)
    Refill,
}

/// What the device answers. `Hello` must stay the first variant.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Reply {
    /// Answer to `Request::Hello`.
    Hello(HelloInfo),
    /// Done (or, for chunks, taken).
    Ack,
    /// Answer to `Request::Status`.
    Status(Status),
    /// Not done, and why.
    Refused(Refusal),
}

/// The device's hello. `version` must stay the first field.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HelloInfo {
    /// The device's `PROTOCOL_VERSION`.
    pub version: u16,
    /// Firmware version (the crate version it was built from).
    pub firmware: heapless::String<16>,
    /// Board name.
    pub board: heapless::String<16>,
    /// Largest chunk the device takes.
    pub max_chunk: u16,
    /// Chunks the device buffers.
    pub window: u8,
    /// Bytes of job the device can store.
    pub capacity: u32,
    /// Hash of the loaded config, if any.
    pub config: Option<u32>,
    /// The job the device holds, with how much of it arrived.
    pub job: JobSlot,
}

/// Identifies a job: what its header promises about its body.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct JobId {
    /// CRC-32 of the body.
    pub body_crc: u32,
    /// Body length, bytes.
    pub body_len: u32,
    /// Hash of the config it was sliced for.
    pub config_hash: u32,
}

impl JobId {
    /// The id of the job `header` describes.
    pub fn of(header: &JobHeader) -> Self {
        JobId {
            body_crc: header.body_crc,
            body_len: header.body_len,
            config_hash: header.config_hash,
        }
    }
}

/// The job store's content.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum JobSlot {
    /// No job.
    Empty,
    /// Erasing room for a job; chunks are taken once this is done.
    Preparing {
        /// The job.
        id: JobId,
    },
    /// Taking chunks.
    Receiving {
        /// The job.
        id: JobId,
        /// Body bytes taken so far (the offset the next chunk must have).
        received: u32,
    },
    /// All bytes taken; reading the body back and checking it.
    Verifying {
        /// The job.
        id: JobId,
        /// Bytes checked so far.
        checked: u32,
    },
    /// Checked: can be started (again).
    Ready {
        /// The job.
        id: JobId,
        /// Commands in the body.
        commands: u32,
        /// Print segments in the body.
        segments: u32,
    },
    /// The upload or check failed; upload it again.
    Failed {
        /// The job.
        id: JobId,
        /// Why.
        why: JobFailure,
    },
}

/// Why a stored job cannot run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum JobFailure {
    /// The body is not the length the header says.
    BodyLength {
        /// From the header.
        expected: u32,
        /// Found.
        found: u32,
    },
    /// The body fails its CRC.
    BodyCrc,
    /// A command does not decode.
    CommandDecode {
        /// Byte offset in the body.
        offset: u32,
    },
    /// The body holds another number of commands than the header says.
    CommandCount {
        /// From the header.
        expected: u32,
        /// Found.
        found: u32,
    },
    /// Anything else the job decoder refused.
    Format,
    /// The job store failed.
    Store(StoreError),
}

impl From<JobError> for JobFailure {
    fn from(e: JobError) -> Self {
        match e {
            JobError::BodyLength { expected, found } => JobFailure::BodyLength {
                expected,
                found: found.min(u32::MAX as u64) as u32,
            },
            JobError::BodyCrc => JobFailure::BodyCrc,
            JobError::CommandDecode { offset } => JobFailure::CommandDecode { offset },
            JobError::CommandCount { expected, found } => {
                JobFailure::CommandCount { expected, found }
            }
            _ => JobFailure::Format,
        }
    }
}

impl fmt::Display for JobFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            JobFailure::BodyLength { expected, found } => write!(
                f,
                "the board holds {found} bytes of job body but the header says {expected}"
            ),
            JobFailure::BodyCrc => write!(f, "the job body on the board fails its CRC check"),
            JobFailure::CommandDecode { offset } => {
                write!(f, "job command at body byte {offset} does not decode")
            }
            JobFailure::CommandCount { expected, found } => write!(
                f,
                "job body holds {found} commands but the header says {expected}"
            ),
            JobFailure::Format => write!(f, "job body is not in the job format"),
            JobFailure::Store(e) => write!(f, "job store: {e}"),
        }
    }
}

/// Why the job store failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum StoreError {
    /// Outside the store.
    OutOfRange,
    /// Erasing failed.
    Erase,
    /// Writing failed.
    Write,
    /// Reading failed.
    Read,
}

impl fmt::Display for StoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            StoreError::OutOfRange => "access outside the job store",
            StoreError::Erase => "erasing the job store failed",
            StoreError::Write => "writing the job store failed",
            StoreError::Read => "reading the job store failed",
        })
    }
}

/// What to do when the host link is lost while a job runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum LinkLossPolicy {
    /// Pause as `Request::Pause` does (valves shut, head stopped mid-bead), then hold
    /// until resumed.
    Pause,
    /// Safe state at once (fault `LinkLost`).
    Stop,
}

/// Board settings that are not part of the machine config.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// What a lost link does to a running job.
    pub on_link_loss: LinkLossPolicy,
    /// Axes in the order they home.
    pub home_order: [Axis; 3],
    /// Per axis: the endstop is at the maximum (true) or the minimum.
    pub home_to_max: [bool; 3],
    /// Homing speed, mm/s.
    pub home_speed_mm_s: f32,
    /// Distance moved back off the endstop after it triggers, mm.
    pub home_backoff_mm: f32,
}

impl Default for Settings {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl Settings {
    /// Pause on link loss; Z homes up to its maximum first (away from the plate), then X
    /// and Y to their minimum, at 10 mm/s, backing off 2 mm. A constant, so the board's
    /// control state can be built at compile time.
    pub const DEFAULT: Settings = Settings {
        on_link_loss: LinkLossPolicy::Pause,
        home_order: [Axis::Z, Axis::X, Axis::Y],
        home_to_max: [false, false, true],
        home_speed_mm_s: 10.0,
        home_backoff_mm: 2.0,
    };

    /// Checks the values; the error names the field.
    pub fn check(&self) -> Result<(), Text> {
        let mut seen = [false; 3];
        for a in self.home_order {
            if seen[a.index()] {
                return Err(text(format_args!(
                    "settings.home_order names {a:?} twice; list X, Y and Z once each"
                )));
            }
            seen[a.index()] = true;
        }
        for (name, v, max) in [
            ("home_speed_mm_s", self.home_speed_mm_s, 100u16),
            ("home_backoff_mm", self.home_backoff_mm, 50),
        ] {
            // No float in the text: formatting floats costs the chip 15 KiB of flash.
            if !(v.is_finite() && v > 0.0 && v <= max as f32) {
                return Err(text(format_args!(
                    "settings.{name} must be above 0 and at most {max}"
                )));
            }
        }
        Ok(())
    }
}

/// What the board is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Mode {
    /// No machine config loaded yet.
    Unconfigured,
    /// Nothing running.
    Idle,
    /// Homing.
    Homing,
    /// A hand move.
    Jogging,
    /// Valves opened by hand.
    ValveTest,
    /// A job runs (printing, moving, paused: see `RunState`).
    Job,
    /// Safe state after a fault or emergency stop, until `ClearFault`.
    Halted,
}

/// Why the board is halted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Halt {
    /// A fault of the executor or from outside (e-stop, watchdog, link loss).
    Fault(Fault),
    /// An endstop did not trigger (or did not release) while homing.
    HomingFailed {
        /// The axis.
        axis: Axis,
    },
}

impl fmt::Display for Halt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Halt::Fault(x) => write!(f, "{x}"),
            Halt::HomingFailed { axis } => write!(
                f,
                "homing {axis:?} failed: its endstop did not trigger within the travel (check wiring and settings.home_to_max)"
            ),
        }
    }
}

/// The control loop's state, as the loop publishes it every cycle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Snapshot {
    /// What the board is doing.
    pub mode: Mode,
    /// The executor's state (jobs).
    pub run: RunState,
    /// Why it is halted.
    pub halt: Option<Halt>,
    /// All axes homed since the drivers were last enabled.
    pub homed: bool,
    /// The e-stop input is active.
    pub estop: bool,
    /// Drivers enabled.
    pub drivers: bool,
    /// Valves open, bit per inlet.
    pub valves: u8,
    /// Commanded position, micrometres (meaningful once homed).
    pub position_um: [i32; 3],
    /// Commands of the job executed so far (index into the job body).
    pub command: u32,
    /// Job number this snapshot's `command` belongs to.
    pub epoch: u8,
    /// Head speed along the bead, mm/s.
    pub speed_mm_s: f32,
    /// Flow, mm^3/s.
    pub q_mm3_s: f32,
    /// While a pause is in effect (the head came to rest; parked or not): the pause
    /// point, micrometres, where the print goes on from. (Protocol 3.)
    pub pause_point_um: Option<[i32; 3]>,
}

impl Snapshot {
    /// The state at power-up: nothing configured, everything off.
    pub const POWER_UP: Snapshot = Snapshot {
        mode: Mode::Unconfigured,
        run: RunState::Idle,
        halt: None,
        homed: false,
        estop: false,
        drivers: false,
        valves: 0,
        position_um: [0; 3],
        command: 0,
        epoch: 0,
        speed_mm_s: 0.0,
        q_mm3_s: 0.0,
        pause_point_um: None,
    };
}

/// Answer to `Request::Status`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// The control loop's state.
    pub control: Snapshot,
    /// The job store's content.
    pub job: JobSlot,
    /// Commands of the running job handed to the control loop so far.
    pub fed: u32,
    /// Hash of the loaded config, if any.
    pub config: Option<u32>,
    /// The link was lost while a job ran (and the policy applied) since the last hello.
    pub link_lost: bool,
    /// The host UART's receive errors since the board started (zeros where there is no
    /// UART): bytes lost or corrupted on the wire, each costing a resent frame.
    pub line_errors: LineErrors,
}

/// Receive errors of a serial line, counted since start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LineErrors {
    /// A byte arrived before the previous one was read (the receiver was late).
    pub overrun: u32,
    /// No stop bit where one was due (a baud-rate mismatch, a break, a glitch).
    pub framing: u32,
    /// Noise seen by the receiver's oversampling.
    pub noise: u32,
    /// Parity errors (only with a misconfigured host: the link uses no parity).
    pub parity: u32,
}

impl LineErrors {
    /// True if any count is non-zero.
    pub fn any(&self) -> bool {
        self.overrun | self.framing | self.noise | self.parity != 0
    }
}

/// Why a request was not carried out.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Refusal {
    /// The two sides speak different protocol versions.
    Version {
        /// The device's.
        device: u16,
        /// The host's.
        host: u16,
    },
    /// No session: send a hello first (the device may have restarted).
    NoSession,
    /// Something is running that this request would disturb.
    Busy {
        /// What is running.
        mode: Mode,
    },
    /// The control loop's queue is full; try again.
    QueueFull,
    /// No machine config loaded.
    NoConfig,
    /// The config does not validate (field and reason).
    Config(Text),
    /// The settings do not validate.
    Settings(Text),
    /// The job was sliced for another config.
    ConfigMismatch {
        /// Hash in the job.
        job: u32,
        /// Hash of the loaded config.
        device: u32,
    },
    /// The job is larger than the store.
    JobTooLarge {
        /// Body bytes.
        len: u32,
        /// Store bytes.
        capacity: u32,
    },
    /// The job visits places outside the machine's travel.
    JobOutsideTravel {
        /// The first axis that leaves it.
        axis: Axis,
    },
    /// The job header is unusable.
    JobHeader(Text),
    /// The stored job cannot run.
    Job(JobFailure),
    /// No checked job to start.
    NoJob,
    /// A chunk or end-of-job with no upload in progress.
    NotUploading,
    /// A chunk at another offset than the next expected (host bug).
    ChunkOffset {
        /// Offset expected.
        expected: u32,
        /// Offset sent.
        got: u32,
    },
    /// A chunk longer than `MAX_CHUNK`, past the body's end, or not whole flash words.
    ChunkSize {
        /// Its length.
        len: u32,
    },
    /// Home first.
    NotHomed,
    /// The move would leave the soft limits.
    SoftLimit {
        /// The axis.
        axis: Axis,
        /// Where it would end, um.
        target_um: i32,
        /// Lowest allowed, um.
        min_um: i32,
        /// Highest allowed, um.
        max_um: i32,
    },
    /// No such valve.
    NoSuchInlet {
        /// Asked for.
        inlet: u8,
        /// Inlets configured.
        inlets: u8,
    },
    /// Halted: clear the fault first.
    Halted(Halt),
    /// The e-stop input is still active.
    EStopActive,
    /// The job store failed.
    Store(StoreError),
    /// Hand moves are for X, Y and Z; syringe plungers move only in a job.
    NotJoggable {
        /// The axis asked for.
        axis: Axis,
    },
    /// An upload is preparing or writing the job store, which stalls the chip on flash
    /// boards: nothing may move or open until it is done.
    Uploading,
    /// Resume with nothing paused (no pause requested or in effect).
    NotPaused {
        /// What the job is doing.
        run: RunState,
    },
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::Version { device, host } => write!(
                f,
                "the board speaks link protocol version {device} but this dollop speaks version {host}; flash matching firmware or install the matching dollop"
            ),
            Refusal::NoSession => write!(f, "no session (the board restarted?); reconnect"),
            Refusal::Busy { mode } => {
                write!(f, "the board is busy ({mode:?}); wait, or abort it first")
            }
            Refusal::QueueFull => write!(f, "the control loop's queue is full; try again"),
            Refusal::NoConfig => write!(
                f,
                "the board has no machine config; pass --config FILE to load one"
            ),
            Refusal::Config(t) => write!(f, "the board refused the config: {t}"),
            Refusal::Settings(t) => write!(f, "the board refused the settings: {t}"),
            Refusal::ConfigMismatch { job, device } => write!(
                f,
                "the job was sliced for config {job:08x} but the board has config {device:08x}; load the job's config (--config FILE) or re-slice"
            ),
            Refusal::JobTooLarge { len, capacity } => write!(
                f,
                "the job body is {len} bytes but the board stores at most {capacity}; split the job"
            ),
            Refusal::JobOutsideTravel { axis } => write!(
                f,
                "the job leaves the machine's {axis:?} travel; move it or check the config's travel limits"
            ),
            Refusal::JobHeader(t) => write!(f, "job header refused: {t}"),
            Refusal::Job(e) => write!(f, "{e}; upload the job again"),
            Refusal::NoJob => write!(f, "no checked job on the board; upload one (dollop send)"),
            Refusal::NotUploading => write!(f, "no upload in progress"),
            Refusal::ChunkOffset { expected, got } => write!(
                f,
                "chunk at body byte {got} but the board expects byte {expected}"
            ),
            Refusal::ChunkSize { len } => write!(f, "chunk of {len} bytes refused"),
            Refusal::NotHomed => write!(f, "the machine is not homed; home it first"),
            Refusal::SoftLimit {
                axis,
                target_um,
                min_um,
                max_um,
            } => write!(
                f,
                "{axis:?} would end at {:.3} mm, outside its travel {:.3} ..= {:.3} mm",
                *target_um as f32 / 1000.0,
                *min_um as f32 / 1000.0,
                *max_um as f32 / 1000.0
            ),
            Refusal::NoSuchInlet { inlet, inlets } => write!(
                f,
                "valve {inlet} does not exist; the config has {inlets} inlet(s), numbered from 0"
            ),
            Refusal::Halted(h) => write!(f, "the board is halted ({h}); clear the fault first"),
            Refusal::EStopActive => write!(f, "the emergency stop input is still active; release it"),
            Refusal::Store(e) => write!(f, "{e}"),
            Refusal::NotJoggable { axis } => write!(
                f,
                "{axis:?} cannot be jogged: hand moves are for X, Y and Z (syringe plungers move in a job)"
            ),
            Refusal::Uploading => write!(
                f,
                "a job upload is writing the board's job store; wait for it to finish (dollop status) or abort it"
            ),
            Refusal::NotPaused { run } => write!(
                f,
                "nothing to resume: the print is not paused (run state {run:?}); `dollop pause` pauses it"
            ),
        }
    }
}
