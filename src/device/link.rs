//! The link's logic (thread mode on the board): cuts USB bytes into frames, keeps the
//! session (sequence numbers, cumulative acks, credits, the cached last reply), answers
//! requests, takes a job's chunks into the `JobStore`, checks the stored body before it
//! may start, feeds the running job to the control loop, and applies the link-loss
//! policy. Frame bytes out go to a fixed buffer the board drains to USB.

use super::store::JobStore;
use super::{ControlOrder, JobRecord, ToControl};
use crate::command::Command;
use crate::config::Config;
use crate::executor::RunState;
use crate::job::{self, BodyDecoder, JobHeader};
use crate::outputs::Axis;
use crate::wire::frame::Event;
use crate::wire::{
    self, seq_after, text, DeviceHeader, FrameReader, HelloInfo, HostHeader, JobFailure, JobId,
    JobSlot, Mode, Refusal, Reply, Request, Settings, Snapshot, Status, MAX_CHUNK,
    PROTOCOL_VERSION, WINDOW,
};
use heapless::Deque;

/// Bytes of reply frames waiting for USB: a few replies (the longest is about 150 bytes);
/// replies that do not fit are dropped and the host asks again.
pub const TX_CAP: usize = 1024;
/// Longest reply frame, bytes.
pub const REPLY_MAX: usize = 256;
/// Body bytes read back and checked per poll (keeps each poll short).
pub const VERIFY_STEP: usize = 512;
/// Body bytes decoded at a time while feeding a job (at most as many commands).
const FEED_READ: usize = 32;
/// Session ids remembered as finished, so a late hello of an old session cannot take
/// the link back from the current one.
const RETIRED: usize = 4;

/// What the board tells the host about itself.
#[derive(Clone, Copy, Debug)]
pub struct BoardInfo {
    /// Board name.
    pub name: &'static str,
    /// Firmware version.
    pub firmware: &'static str,
    /// Highest step rate per axis the board's step generator makes, steps/s.
    pub max_step_hz: f32,
    /// The board's control loop rate, Hz: a config must ask for exactly this
    /// (`control.rate_hz`), or its model would run faster or slower than real time.
    pub control_hz: u32,
}

/// Counters of what the link saw; for tests and the debug log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames that decoded.
    pub frames: u32,
    /// Frames dropped: bad COBS, CRC or content.
    pub bad: u32,
    /// Frames longer than `MAX_FRAME`, dropped.
    pub oversize: u32,
    /// Requests seen again (answered, not acted on).
    pub duplicates: u32,
    /// Requests ahead of the expected one (dropped, answered with the expected number).
    pub out_of_order: u32,
    /// Chunks with no free buffer (a host that ignored its credit), dropped.
    pub no_room: u32,
    /// Replies dropped because the transmit buffer was full.
    pub tx_dropped: u32,
}

impl LinkStats {
    /// Nothing seen yet.
    pub const ZERO: LinkStats = LinkStats {
        frames: 0,
        bad: 0,
        oversize: 0,
        duplicates: 0,
        out_of_order: 0,
        no_room: 0,
        tx_dropped: 0,
    };
}

#[derive(Clone, Copy, Debug)]
struct Session {
    id: u16,
    next: u16,
    /// The host's protocol version, from its hello.
    version: u16,
}

struct Slot {
    offset: u32,
    len: u16,
    data: [u8; MAX_CHUNK],
}

#[allow(clippy::large_enum_variant)]
enum Upload {
    Empty,
    Preparing(JobHeader),
    Receiving {
        header: JobHeader,
        received: u32,
        written: u32,
        ended: bool,
    },
    Verifying {
        header: JobHeader,
        decoder: BodyDecoder,
        checked: u32,
        segments: u32,
    },
    Ready {
        header: JobHeader,
        segments: u32,
    },
    Failed {
        id: JobId,
        why: JobFailure,
    },
}

struct Feeder {
    epoch: u8,
    decoder: BodyDecoder,
    offset: u32,
    len: u32,
    pending: Deque<Command, FEED_READ>,
    fed: u32,
    seen_running: bool,
}

/// The link's state. One per board; `S` keeps the job.
pub struct BoardLink<S: JobStore> {
    reader: FrameReader,
    core: Core<S>,
}

struct Core<S: JobStore> {
    store: S,
    info: BoardInfo,
    session: Option<Session>,
    retired: Deque<u16, RETIRED>,
    cache: Option<(u16, heapless::Vec<u8, REPLY_MAX>)>,
    slots: Deque<Slot, WINDOW>,
    upload: Upload,
    feeder: Option<Feeder>,
    config: Option<Config>,
    config_hash: Option<u32>,
    settings: Settings,
    tx: Deque<u8, TX_CAP>,
    last_rx: Option<u64>,
    lost_applied: bool,
    link_lost: bool,
    epoch: u8,
    /// Commands of the latest job handed to the control loop (kept after it ends).
    fed: u32,
    stats: LinkStats,
}

impl<S: JobStore> BoardLink<S> {
    /// A link with no session, no config and an empty store. A constant constructor: the
    /// board keeps its link (6 KiB) in a static built at compile time.
    pub const fn new(store: S, info: BoardInfo) -> Self {
        BoardLink {
            reader: FrameReader::new(),
            core: Core {
                store,
                info,
                session: None,
                retired: Deque::new(),
                cache: None,
                slots: Deque::new(),
                upload: Upload::Empty,
                feeder: None,
                config: None,
                config_hash: None,
                settings: Settings::DEFAULT,
                tx: Deque::new(),
                last_rx: None,
                lost_applied: false,
                link_lost: false,
                epoch: 0,
                fed: 0,
                stats: LinkStats::ZERO,
            },
        }
    }

    /// Takes bytes from USB at `now_us`; replies queue up for `take_tx`.
    // Never inlined: on the board the link task would otherwise carry every request's
    // locals in one frame of several KiB.
    #[inline(never)]
    pub fn receive(&mut self, bytes: &[u8], now_us: u64, port: &mut impl ToControl) {
        let mut rest = bytes;
        while !rest.is_empty() {
            let (n, ev) = self.reader.feed(rest);
            rest = &rest[n..];
            match ev {
                Some(Event::Frame(len)) => {
                    let frame = self.reader.frame(len);
                    self.core.on_frame(frame, now_us, port);
                }
                Some(Event::Oversize) => self.core.stats.oversize += 1,
                None => {}
            }
        }
    }

    /// Moves up to `buf.len()` bytes of replies into `buf`; returns how many.
    pub fn take_tx(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        while n < buf.len() {
            match self.core.tx.pop_front() {
                Some(b) => {
                    buf[n] = b;
                    n += 1;
                }
                None => break,
            }
        }
        n
    }

    /// Background work, called often: job store preparation and writes, checking the
    /// stored body, feeding the running job, noticing a silent host.
    // Never inlined: on the board the link task would otherwise carry every request's
    // locals in one frame of several KiB.
    #[inline(never)]
    pub fn poll(&mut self, now_us: u64, port: &mut impl ToControl) {
        self.core.poll(now_us, port);
    }

    /// The USB connection went away (cable, host closed the port): applies the link-loss
    /// policy at once if something runs.
    // Never inlined: on the board the link task would otherwise carry every request's
    // locals in one frame of several KiB.
    #[inline(never)]
    pub fn disconnected(&mut self, port: &mut impl ToControl) {
        self.reader.clear();
        self.core.lose_link(port);
    }

    /// Forgets everything but the store's bytes, as a chip reset does to RAM.
    pub fn reset(&mut self) {
        self.reader.clear();
        let c = &mut self.core;
        c.session = None;
        c.retired.clear();
        c.cache = None;
        c.slots.clear();
        c.upload = Upload::Empty;
        c.feeder = None;
        c.config = None;
        c.config_hash = None;
        c.settings = Settings::default();
        c.tx.clear();
        c.last_rx = None;
        c.lost_applied = false;
        c.link_lost = false;
        c.epoch = 0;
        c.fed = 0;
        c.stats = LinkStats::default();
    }

    /// What the link saw so far.
    pub fn stats(&self) -> LinkStats {
        self.core.stats
    }

    /// The job store.
    pub fn store(&self) -> &S {
        &self.core.store
    }

    /// The job store, to change (tests inject faults through it).
    pub fn store_mut(&mut self) -> &mut S {
        &mut self.core.store
    }

    /// The job slot as the host sees it.
    pub fn job(&self) -> JobSlot {
        self.core.job_slot()
    }

    /// Commands of the running job handed to the control loop so far.
    pub fn fed(&self) -> u32 {
        self.core.fed
    }
}

impl<S: JobStore> Core<S> {
    fn on_frame(&mut self, frame: &mut [u8], now: u64, port: &mut impl ToControl) {
        let Ok(payload) = wire::open(frame) else {
            self.stats.bad += 1;
            return;
        };
        let (h, req) = match wire::parse::<HostHeader, Request<'_>>(payload) {
            Ok(hr) => hr,
            Err(_) => {
                // A hello of another protocol version may not decode whole; its first
                // bytes do, and the answer names both versions.
                match wire::peek_hello::<HostHeader>(payload) {
                    Some((h, version)) if version != PROTOCOL_VERSION => {
                        self.stats.frames += 1;
                        self.hello(h, version, now);
                    }
                    _ => self.stats.bad += 1,
                }
                return;
            }
        };
        self.stats.frames += 1;
        if let Request::Hello { version } = req {
            self.hello(h, version, now);
            return;
        }
        let s = match self.session {
            Some(s) if s.id == h.session => s,
            _ => {
                let hdr = DeviceHeader {
                    session: h.session,
                    answers: h.seq,
                    next: h.seq,
                    credit: 0,
                };
                self.send(&hdr, &Reply::Refused(Refusal::NoSession));
                return;
            }
        };
        self.last_rx = Some(now);
        self.lost_applied = false;
        if s.version != PROTOCOL_VERSION {
            let r = Reply::Refused(Refusal::Version {
                device: PROTOCOL_VERSION,
                host: s.version,
            });
            let hdr = self.header(s, h.seq);
            self.send(&hdr, &r);
            return;
        }
        if h.seq != s.next {
            let last = s.next.wrapping_sub(1);
            match &self.cache {
                Some((seq, bytes)) if *seq == h.seq && h.seq == last => {
                    self.stats.duplicates += 1;
                    let bytes = bytes.clone();
                    self.push_tx(&bytes);
                }
                _ => {
                    if seq_after(h.seq, s.next) {
                        self.stats.out_of_order += 1;
                    } else {
                        self.stats.duplicates += 1;
                    }
                    let hdr = self.header(s, h.seq);
                    self.send(&hdr, &Reply::Ack);
                }
            }
            return;
        }
        if let Request::Chunk { offset, data } = req {
            match self.chunk(offset, data) {
                // No room: not taken, so the sequence does not advance; the bare ack tells
                // the host where it stands.
                None => {
                    self.stats.no_room += 1;
                    let hdr = self.header(s, h.seq);
                    self.send(&hdr, &Reply::Ack);
                }
                Some(reply) => {
                    self.advance();
                    self.cache = None;
                    let hdr = self.header(self.session.unwrap_or(s), h.seq);
                    let bytes = self.send(&hdr, &reply);
                    if matches!(reply, Reply::Refused(_)) {
                        self.cache = bytes.map(|b| (h.seq, b));
                    }
                }
            }
            return;
        }
        let reply = self.request(req, port);
        self.advance();
        let hdr = self.header(self.session.unwrap_or(s), h.seq);
        let bytes = self.send(&hdr, &reply);
        self.cache = bytes.map(|b| (h.seq, b));
    }

    fn hello(&mut self, h: HostHeader, version: u16, now: u64) {
        if self.retired.iter().any(|&id| id == h.session) {
            // A late hello of a finished session: it must not take the link back.
            return;
        }
        let same = self.session.is_some_and(|s| s.id == h.session);
        if !same {
            if let Some(old) = self.session {
                if self.retired.is_full() {
                    self.retired.pop_front();
                }
                let _ = self.retired.push_back(old.id);
            }
            self.session = Some(Session {
                id: h.session,
                next: h.seq.wrapping_add(1),
                version,
            });
            self.cache = None;
            self.link_lost = false;
        }
        self.last_rx = Some(now);
        self.lost_applied = false;
        let info = HelloInfo {
            version: PROTOCOL_VERSION,
            firmware: short(self.info.firmware),
            board: short(self.info.name),
            max_chunk: MAX_CHUNK as u16,
            window: WINDOW as u8,
            capacity: self.store.capacity(),
            config: self.config_hash,
            job: self.job_slot(),
        };
        let s = self.session.unwrap_or(Session {
            id: h.session,
            next: h.seq.wrapping_add(1),
            version,
        });
        // Also on a version mismatch: the host learns the device's version from the
        // hello (whose first bytes never change) and names both; any later request of
        // that session is refused naming both.
        let hdr = self.header(s, h.seq);
        self.send(&hdr, &Reply::Hello(info));
    }

    fn advance(&mut self) {
        if let Some(s) = &mut self.session {
            s.next = s.next.wrapping_add(1);
        }
    }

    fn header(&self, s: Session, answers: u16) -> DeviceHeader {
        DeviceHeader {
            session: s.id,
            answers,
            next: s.next,
            credit: self.credit(),
        }
    }

    fn credit(&self) -> u8 {
        match self.upload {
            Upload::Receiving { ended: false, .. } => (WINDOW - self.slots.len()) as u8,
            _ => 0,
        }
    }

    /// Encodes and queues a reply; returns its bytes for the duplicate cache.
    #[inline(never)] // keeps the board's link frames small (see `receive`)
    fn send(&mut self, hdr: &DeviceHeader, reply: &Reply) -> Option<heapless::Vec<u8, REPLY_MAX>> {
        // A leading delimiter, so a reply never merges with a cut one before it.
        let mut buf = [0u8; REPLY_MAX];
        let n = wire::encode(hdr, reply, &mut buf[1..]).ok()? + 1;
        self.push_tx(&buf[..n]);
        heapless::Vec::from_slice(&buf[..n]).ok()
    }

    fn push_tx(&mut self, bytes: &[u8]) {
        if TX_CAP - self.tx.len() < bytes.len() {
            self.stats.tx_dropped += 1;
            return;
        }
        for &b in bytes {
            let _ = self.tx.push_back(b);
        }
    }

    /// Takes a chunk; None if there is no buffer for it (not taken at all).
    #[inline(never)] // keeps the board's link frames small (see `receive`)
    fn chunk(&mut self, offset: u32, data: &[u8]) -> Option<Reply> {
        let Upload::Receiving {
            header,
            received,
            ended,
            ..
        } = &mut self.upload
        else {
            return Some(Reply::Refused(Refusal::NotUploading));
        };
        if *ended {
            return Some(Reply::Refused(Refusal::NotUploading));
        }
        if offset != *received {
            return Some(Reply::Refused(Refusal::ChunkOffset {
                expected: *received,
                got: offset,
            }));
        }
        let len = data.len() as u32;
        let end = offset as u64 + len as u64;
        let last = end == header.body_len as u64;
        if data.is_empty()
            || data.len() > MAX_CHUNK
            || end > header.body_len as u64
            || (!last && len % 4 != 0)
        {
            return Some(Reply::Refused(Refusal::ChunkSize { len }));
        }
        if self.slots.is_full() {
            return None;
        }
        let mut slot = Slot {
            offset,
            len: len as u16,
            data: [0; MAX_CHUNK],
        };
        slot.data[..data.len()].copy_from_slice(data);
        let _ = self.slots.push_back(slot);
        *received += len;
        Some(Reply::Ack)
    }

    /// Refuses motion and valve tests while an upload prepares or writes the store (flash
    /// erases and writes stall the chip; `poll_upload` does them only while all is safe).
    fn not_uploading(&self) -> Result<(), Refusal> {
        match self.upload {
            Upload::Preparing(_) | Upload::Receiving { .. } => Err(Refusal::Uploading),
            _ => Ok(()),
        }
    }

    fn snapshot_busy(&self, port: &impl ToControl) -> Option<Refusal> {
        let s = port.snapshot();
        match s.mode {
            Mode::Job | Mode::Homing | Mode::Jogging | Mode::ValveTest => {
                Some(Refusal::Busy { mode: s.mode })
            }
            _ => None,
        }
    }

    fn request(&mut self, req: Request<'_>, port: &mut impl ToControl) -> Reply {
        match self.act(req, port) {
            Ok(r) => r,
            Err(why) => Reply::Refused(why),
        }
    }

    /// One request, one method: the dispatcher reads the control loop's snapshot once and
    /// hands it on; each method checks what its request needs and orders the control loop.
    #[inline(never)] // keeps the board's link frames small (see `receive`)
    fn act(&mut self, req: Request<'_>, port: &mut impl ToControl) -> Result<Reply, Refusal> {
        let snap = port.snapshot();
        match req {
            Request::Hello { .. } | Request::Chunk { .. } => Ok(Reply::Ack),
            Request::Status => Ok(Reply::Status(self.status(port))),
            Request::LoadConfig(c) => self.load_config(c, port),
            Request::Settings(s) => self.settings(s, port),
            Request::BeginJob(h) => self.begin_job(h, port),
            Request::EndJob => self.end_job(),
            Request::Start => self.start(&snap, port),
            Request::Pause => ack(port, ControlOrder::Pause),
            Request::Park => ack(port, ControlOrder::Park),
            Request::Refill => refill(&snap, port),
            Request::Resume => resume(&snap, port),
            Request::Abort => self.stop(port, ControlOrder::Abort),
            Request::EStop => self.stop(port, ControlOrder::EStop),
            Request::ClearFault => clear_fault(&snap, port),
            Request::Home => self.home(&snap, port),
            Request::Jog { axis, um } => self.jog(&snap, axis, um, port),
            Request::Valve { inlet, open } => self.valve(&snap, inlet, open, port),
        }
    }

    /// Validates a config as the control loop will run it, checks it against this board,
    /// and hands the machine over.
    fn load_config(&mut self, c: Config, port: &mut impl ToControl) -> Result<Reply, Refusal> {
        if let Some(r) = self.snapshot_busy(port) {
            return Err(r);
        }
        let machine = match c.validate::<f32, { crate::DEFAULT_INLETS }>() {
            Ok(m) => m,
            Err(e) => {
                // The field and the kind of problem, without numbers: formatting floats
                // costs the chip 15 KiB of flash, and the host names the values.
                return Err(Refusal::Config(text(format_args!(
                    "{}: {}",
                    e.field,
                    e.problem.name()
                ))));
            }
        };
        if c.motion.max_step_rate_hz.is_nan() || c.motion.max_step_rate_hz > self.info.max_step_hz {
            return Err(Refusal::Config(text(format_args!(
                "motion.max_step_rate_hz: above the {} steps/s this board makes",
                self.info.max_step_hz as u32
            ))));
        }
        if c.control.rate_hz != self.info.control_hz {
            return Err(Refusal::Config(text(format_args!(
                "control.rate_hz: this board's control loop runs at {} Hz",
                self.info.control_hz
            ))));
        }
        if !port.post_config(&machine) {
            return Err(Refusal::QueueFull);
        }
        order(port, ControlOrder::LoadConfig)?;
        self.config_hash = Some(job::config_hash(&c));
        self.config = Some(c);
        Ok(Reply::Ack)
    }

    fn settings(&mut self, s: Settings, port: &mut impl ToControl) -> Result<Reply, Refusal> {
        s.check().map_err(Refusal::Settings)?;
        order(port, ControlOrder::Settings(s))?;
        self.settings = s;
        Ok(Reply::Ack)
    }

    /// Starts the uploaded job: it must be whole, made for the config loaded, and the
    /// machine idle, homed and not stopped.
    fn start(&mut self, snap: &Snapshot, port: &mut impl ToControl) -> Result<Reply, Refusal> {
        halted(snap)?;
        if snap.estop {
            return Err(Refusal::EStopActive);
        }
        let (header, _) = match &self.upload {
            Upload::Ready { header, segments } => (header.clone(), *segments),
            Upload::Failed { why, .. } => return Err(Refusal::Job(*why)),
            _ => return Err(Refusal::NoJob),
        };
        let Some(hash) = self.config_hash else {
            return Err(Refusal::NoConfig);
        };
        if hash != header.config_hash {
            return Err(Refusal::ConfigMismatch {
                job: header.config_hash,
                device: hash,
            });
        }
        if snap.mode != Mode::Idle {
            return Err(Refusal::Busy { mode: snap.mode });
        }
        if !snap.homed {
            return Err(Refusal::NotHomed);
        }
        let epoch = self.epoch.wrapping_add(1);
        order(
            port,
            ControlOrder::Start {
                epoch,
                start_um: header.start_um,
                initial_material: header.initial_material,
            },
        )?;
        self.epoch = epoch;
        self.fed = 0;
        self.feeder = Some(Feeder {
            epoch,
            decoder: BodyDecoder::new(&header),
            offset: 0,
            len: header.body_len,
            pending: Deque::new(),
            fed: 0,
            seen_running: false,
        });
        Ok(Reply::Ack)
    }

    /// Abort or e-stop: ordered whatever the state, and the job's feeding ends.
    fn stop(&mut self, port: &mut impl ToControl, o: ControlOrder) -> Result<Reply, Refusal> {
        order(port, o)?;
        self.feeder = None;
        Ok(Reply::Ack)
    }

    fn home(&mut self, snap: &Snapshot, port: &mut impl ToControl) -> Result<Reply, Refusal> {
        halted(snap)?;
        if self.config.is_none() {
            return Err(Refusal::NoConfig);
        }
        self.not_uploading()?;
        if snap.mode != Mode::Idle {
            return Err(Refusal::Busy { mode: snap.mode });
        }
        ack(port, ControlOrder::Home)
    }

    /// A jog of the head within the config's travel limits, once homed.
    fn jog(
        &mut self,
        snap: &Snapshot,
        axis: Axis,
        um: i32,
        port: &mut impl ToControl,
    ) -> Result<Reply, Refusal> {
        halted(snap)?;
        let Some(c) = &self.config else {
            return Err(Refusal::NoConfig);
        };
        let a = axis.index();
        if a >= 3 {
            return Err(Refusal::NotJoggable { axis });
        }
        self.not_uploading()?;
        if snap.mode != Mode::Idle {
            return Err(Refusal::Busy { mode: snap.mode });
        }
        if !snap.homed {
            return Err(Refusal::NotHomed);
        }
        let min_um = mm_to_um(c.motion.travel_min_mm[a]);
        let max_um = mm_to_um(c.motion.travel_max_mm[a]);
        let target_um = snap.position_um[a].saturating_add(um);
        if target_um < min_um || target_um > max_um {
            return Err(Refusal::SoftLimit {
                axis,
                target_um,
                min_um,
                max_um,
            });
        }
        ack(port, ControlOrder::Jog { axis, um })
    }

    /// A valve test on one of the config's inlets.
    fn valve(
        &mut self,
        snap: &Snapshot,
        inlet: u8,
        open: bool,
        port: &mut impl ToControl,
    ) -> Result<Reply, Refusal> {
        halted(snap)?;
        let Some(c) = &self.config else {
            return Err(Refusal::NoConfig);
        };
        let inlets = c.inlets.len().min(crate::DEFAULT_INLETS) as u8;
        if inlet >= inlets {
            return Err(Refusal::NoSuchInlet { inlet, inlets });
        }
        if open {
            // Closing is always allowed: it is the safe direction.
            self.not_uploading()?;
        }
        if !matches!(snap.mode, Mode::Idle | Mode::ValveTest) {
            return Err(Refusal::Busy { mode: snap.mode });
        }
        ack(port, ControlOrder::Valve { inlet, open })
    }

    #[inline(never)] // keeps the board's link frames small (see `receive`)
    fn begin_job(&mut self, h: JobHeader, port: &impl ToControl) -> Result<Reply, Refusal> {
        if let Some(r) = self.snapshot_busy(port) {
            // Preparing the store stalls the chip on flash boards: never while anything moves.
            return Err(r);
        }
        if !job::reads_version(h.format_version) {
            return Err(Refusal::JobHeader(text(format_args!(
                "job format version {}, but the board reads versions 1 to {}; re-slice with a matching dollop",
                h.format_version,
                job::FORMAT_VERSION_MAX
            ))));
        }
        let Some(c) = &self.config else {
            return Err(Refusal::NoConfig);
        };
        let hash = self.config_hash.unwrap_or(0);
        if h.config_hash != hash {
            return Err(Refusal::ConfigMismatch {
                job: h.config_hash,
                device: hash,
            });
        }
        if h.body_len > self.store.capacity() {
            return Err(Refusal::JobTooLarge {
                len: h.body_len,
                capacity: self.store.capacity(),
            });
        }
        if h.initial_material as usize >= c.inlets.len().min(crate::DEFAULT_INLETS) {
            return Err(Refusal::JobHeader(text(format_args!(
                "the job starts with material {} but the config has {} inlet(s)",
                h.initial_material,
                c.inlets.len()
            ))));
        }
        for (a, axis) in Axis::ALL.iter().enumerate() {
            let lo = mm_to_um(c.motion.travel_min_mm[a]);
            let hi = mm_to_um(c.motion.travel_max_mm[a]);
            let inside = |v: i32| v >= lo && v <= hi;
            if !inside(h.bounds_min_um[a]) || !inside(h.bounds_max_um[a]) || !inside(h.start_um[a])
            {
                return Err(Refusal::JobOutsideTravel { axis: *axis });
            }
        }
        self.feeder = None;
        self.slots.clear();
        self.store.prepare(h.body_len).map_err(Refusal::Store)?;
        self.upload = Upload::Preparing(h);
        Ok(Reply::Ack)
    }

    fn end_job(&mut self) -> Result<Reply, Refusal> {
        match &mut self.upload {
            Upload::Receiving {
                header,
                received,
                ended,
                ..
            } => {
                if *received != header.body_len {
                    return Err(Refusal::Job(JobFailure::BodyLength {
                        expected: header.body_len,
                        found: *received,
                    }));
                }
                *ended = true;
                Ok(Reply::Ack)
            }
            Upload::Verifying { .. } | Upload::Ready { .. } => Ok(Reply::Ack),
            Upload::Failed { why, .. } => Err(Refusal::Job(*why)),
            Upload::Empty | Upload::Preparing(_) => Err(Refusal::NotUploading),
        }
    }

    fn job_slot(&self) -> JobSlot {
        match &self.upload {
            Upload::Empty => JobSlot::Empty,
            Upload::Preparing(h) => JobSlot::Preparing { id: JobId::of(h) },
            Upload::Receiving {
                header, received, ..
            } => JobSlot::Receiving {
                id: JobId::of(header),
                received: *received,
            },
            Upload::Verifying {
                header, checked, ..
            } => JobSlot::Verifying {
                id: JobId::of(header),
                checked: *checked,
            },
            Upload::Ready { header, segments } => JobSlot::Ready {
                id: JobId::of(header),
                commands: header.commands,
                segments: *segments,
            },
            Upload::Failed { id, why } => JobSlot::Failed { id: *id, why: *why },
        }
    }

    fn status(&self, port: &impl ToControl) -> Status {
        Status {
            control: port.snapshot(),
            job: self.job_slot(),
            fed: self.fed,
            config: self.config_hash,
            link_lost: self.link_lost,
            line_errors: port.line_errors(),
        }
    }

    fn fail(&mut self, why: JobFailure) {
        let id = match &self.upload {
            Upload::Preparing(h) => JobId::of(h),
            Upload::Receiving { header, .. }
            | Upload::Verifying { header, .. }
            | Upload::Ready { header, .. } => JobId::of(header),
            Upload::Failed { id, .. } => *id,
            Upload::Empty => return,
        };
        self.slots.clear();
        self.upload = Upload::Failed { id, why };
    }

    fn poll(&mut self, now: u64, port: &mut impl ToControl) {
        let snap = port.snapshot();
        // Erasing or writing flash stalls every fetch from it: only while nothing moves
        // and every valve is shut (the requests that could change that are refused while
        // an upload writes, so this holds until the upload is done).
        let quiet =
            matches!(snap.mode, Mode::Unconfigured | Mode::Idle | Mode::Halted) && snap.valves == 0;
        self.poll_upload(quiet);
        self.feed(port);
        let watched = matches!(
            snap.mode,
            Mode::Job | Mode::Homing | Mode::Jogging | Mode::ValveTest
        );
        let silent = self
            .last_rx
            .is_none_or(|t| now.saturating_sub(t) > wire::LINK_TIMEOUT_MS as u64 * 1000);
        if watched && silent {
            self.lose_link(port);
        }
    }

    fn lose_link(&mut self, port: &mut impl ToControl) {
        let snap = port.snapshot();
        let watched = matches!(
            snap.mode,
            Mode::Job | Mode::Homing | Mode::Jogging | Mode::ValveTest
        );
        if watched
            && !self.lost_applied
            && port
                .order(ControlOrder::LinkLost(self.settings.on_link_loss))
                .is_ok()
        {
            self.lost_applied = true;
            self.link_lost = true;
        }
    }

    fn poll_upload(&mut self, quiet: bool) {
        match &mut self.upload {
            Upload::Preparing(_) | Upload::Receiving { .. } if !quiet => {}
            Upload::Preparing(h) => match self.store.prepare_step() {
                Ok(true) => {
                    let header = h.clone();
                    self.upload = Upload::Receiving {
                        header,
                        received: 0,
                        written: 0,
                        ended: false,
                    };
                }
                Ok(false) => {}
                Err(e) => self.fail(JobFailure::Store(e)),
            },
            Upload::Receiving {
                header,
                written,
                ended,
                ..
            } => {
                if let Some(slot) = self.slots.pop_front() {
                    let data = &slot.data[..slot.len as usize];
                    if slot.offset != *written {
                        let why = JobFailure::BodyLength {
                            expected: *written,
                            found: slot.offset,
                        };
                        self.fail(why);
                        return;
                    }
                    if let Err(e) = self.store.write(slot.offset, data) {
                        self.fail(JobFailure::Store(e));
                        return;
                    }
                    *written += slot.len as u32;
                } else if *ended && *written == header.body_len {
                    let header = header.clone();
                    let decoder = BodyDecoder::new(&header);
                    self.upload = Upload::Verifying {
                        header,
                        decoder,
                        checked: 0,
                        segments: 0,
                    };
                }
            }
            Upload::Verifying {
                header,
                decoder,
                checked,
                segments,
            } => {
                let mut buf = [0u8; VERIFY_STEP];
                let n = (header.body_len - *checked).min(VERIFY_STEP as u32) as usize;
                if let Err(e) = self.store.read(*checked, &mut buf[..n]) {
                    self.fail(JobFailure::Store(e));
                    return;
                }
                let mut prints = 0u32;
                let fed = decoder.feed(&buf[..n], |c| {
                    if matches!(c, Command::Print { .. }) {
                        prints += 1;
                    }
                    Ok::<(), ()>(())
                });
                *segments += prints;
                if let Err(e) = fed {
                    self.fail(e.into());
                    return;
                }
                *checked += n as u32;
                if *checked == header.body_len {
                    match decoder.finish() {
                        Ok(()) => {
                            let header = header.clone();
                            let segments = *segments;
                            self.upload = Upload::Ready { header, segments };
                        }
                        Err(e) => self.fail(e.into()),
                    }
                }
            }
            Upload::Empty | Upload::Ready { .. } | Upload::Failed { .. } => {}
        }
    }

    fn feed(&mut self, port: &mut impl ToControl) {
        let Some(f) = &mut self.feeder else { return };
        let snap = port.snapshot();
        let ours = snap.epoch == f.epoch;
        if ours && snap.mode == Mode::Job {
            f.seen_running = true;
        } else if f.seen_running || (ours && snap.mode == Mode::Halted) {
            // The job ended (done, aborted, halted): stop feeding.
            self.feeder = None;
            return;
        }
        while port.command_room() > 0 {
            if f.pending.is_empty() {
                if f.offset >= f.len {
                    return;
                }
                let mut buf = [0u8; FEED_READ];
                let n = (f.len - f.offset).min(FEED_READ as u32) as usize;
                if self.store.read(f.offset, &mut buf[..n]).is_err() {
                    let _ = port.order(ControlOrder::Abort);
                    self.feeder = None;
                    return;
                }
                let pending = &mut f.pending;
                let r = f.decoder.feed(&buf[..n], |c| pending.push_back(c));
                if !matches!(r, Ok(Ok(()))) {
                    // Checked before the start, so the store changed under the job.
                    let _ = port.order(ControlOrder::Abort);
                    self.feeder = None;
                    return;
                }
                f.offset += n as u32;
                continue;
            }
            let Some(cmd) = f.pending.pop_front() else {
                return;
            };
            if let Err(r) = port.command(JobRecord {
                epoch: f.epoch,
                cmd,
            }) {
                let _ = f.pending.push_front(r.cmd);
                return;
            }
            f.fed += 1;
            self.fed = f.fed;
        }
    }
}

/// Refuses while the board is halted (a fault or an e-stop not yet cleared).
fn halted(snap: &Snapshot) -> Result<(), Refusal> {
    match snap.halt {
        Some(h) if snap.mode == Mode::Halted => Err(Refusal::Halted(h)),
        _ => Ok(()),
    }
}

/// Orders `o` and acknowledges.
fn ack(port: &mut impl ToControl, o: ControlOrder) -> Result<Reply, Refusal> {
    order(port, o)?;
    Ok(Reply::Ack)
}

/// Refills a parked pause's syringes: only while paused.
fn refill(snap: &Snapshot, port: &mut impl ToControl) -> Result<Reply, Refusal> {
    halted(snap)?;
    if snap.mode != Mode::Job || snap.run != RunState::Paused {
        return Err(Refusal::NotPaused { run: snap.run });
    }
    ack(port, ControlOrder::Refill)
}

/// Resumes a pause, or one still coming to rest.
fn resume(snap: &Snapshot, port: &mut impl ToControl) -> Result<Reply, Refusal> {
    halted(snap)?;
    if snap.mode != Mode::Job || !matches!(snap.run, RunState::Paused | RunState::Pausing) {
        return Err(Refusal::NotPaused { run: snap.run });
    }
    ack(port, ControlOrder::Resume)
}

/// Clears a fault; never while the e-stop input is active.
fn clear_fault(snap: &Snapshot, port: &mut impl ToControl) -> Result<Reply, Refusal> {
    if snap.estop {
        return Err(Refusal::EStopActive);
    }
    ack(port, ControlOrder::ClearFault)
}

fn order(port: &mut impl ToControl, o: ControlOrder) -> Result<(), Refusal> {
    port.order(o).map_err(|_| Refusal::QueueFull)
}

fn short(s: &str) -> heapless::String<16> {
    let mut out = heapless::String::new();
    for c in s.chars() {
        if out.push(c).is_err() {
            break;
        }
    }
    out
}

fn mm_to_um(mm: f32) -> i32 {
    let v = libm::roundf(mm * 1000.0);
    if v.is_nan() {
        0
    } else {
        v.clamp(i32::MIN as f32, i32::MAX as f32) as i32
    }
}
