//! Shared helpers of the device tests: a simulated board with a RAM job store, a minimal
//! host that speaks frames to it, and small jobs.
#![allow(dead_code)]

use dollop::device::{RamStore, SimBoard};
use dollop::job::{self, JobHeader};
use dollop::wire::frame::Event;
use dollop::wire::*;
use dollop::{Command, Config};

pub type Board = SimBoard<RamStore<Vec<u8>>>;

pub fn config() -> Config {
    config_file("seed-paper-valves.toml")
}

/// One of the bundled machine configs (`configs/NAME`).
pub fn config_file(name: &str) -> Config {
    let path = format!("{}/configs/{name}", env!("CARGO_MANIFEST_DIR"));
    toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

pub fn board() -> Board {
    Board::new(RamStore::new(vec![0xFF; 256 * 1024]))
}

/// A job and its header, built from commands.
pub fn job(cfg: &Config, start: [i32; 3], cmds: &[Command]) -> (JobHeader, Vec<u8>) {
    let mut body = Vec::new();
    let mut buf = [0u8; job::MAX_COMMAND_LEN];
    let mut lo = start;
    let mut hi = start;
    let mut at = start;
    for c in cmds {
        body.extend_from_slice(job::encode_command(c, &mut buf).unwrap());
        match *c {
            Command::Print { dx, dy, .. } => {
                at[0] += dx;
                at[1] += dy;
            }
            Command::Travel { x, y, z } => at = [x, y, z],
            Command::Layer { z } => at[2] = z,
            _ => {}
        }
        for a in 0..3 {
            lo[a] = lo[a].min(at[a]);
            hi[a] = hi[a].max(at[a]);
        }
    }
    let h = JobHeader {
        format_version: job::FORMAT_VERSION,
        config_hash: job::config_hash(cfg),
        materials: heapless::Vec::new(),
        bounds_min_um: lo,
        bounds_max_um: hi,
        start_um: start,
        initial_material: 0,
        print_segments: cmds
            .iter()
            .filter(|c| matches!(c, Command::Print { .. }))
            .count() as u32,
        commands: cmds.len() as u32,
        body_len: body.len() as u32,
        body_crc: job::body_crc(&body),
    };
    (h, body)
}

/// A short two-material job near (20, 20) mm: `rows` beads of 10 mm, a travel between
/// them.
pub fn small_job(cfg: &Config, rows: i32) -> (JobHeader, Vec<u8>) {
    let start = [20_000, 20_000, 600];
    let mut cmds = vec![Command::Travel {
        x: 20_000,
        y: 20_000,
        z: 600,
    }];
    for r in 0..rows {
        for k in 0..10 {
            cmds.push(Command::Print {
                dx: 1000,
                dy: 0,
                material: (k / 5) as u8,
            });
        }
        cmds.push(Command::Travel {
            x: 20_000,
            y: 20_000 + 800 * (r + 1),
            z: 600,
        });
    }
    cmds.push(Command::End);
    job(cfg, start, &cmds)
}

/// A host that speaks frames to a `Board` directly (no faults).
pub struct Host {
    pub session: u16,
    pub seq: u16,
    pub reader: FrameReader,
}

impl Default for Host {
    fn default() -> Self {
        Host {
            session: 0x4242,
            seq: 100,
            reader: FrameReader::new(),
        }
    }
}

impl Host {
    /// Sends raw bytes, runs the board a few periods, returns the decoded replies.
    pub fn raw(&mut self, b: &mut Board, bytes: &[u8]) -> Vec<(DeviceHeader, Reply)> {
        b.receive(bytes);
        b.advance(300);
        let mut out = Vec::new();
        let mut buf = [0u8; 4096];
        let n = b.take_tx(&mut buf);
        let mut rest = &buf[..n];
        while !rest.is_empty() {
            let (k, ev) = self.reader.feed(rest);
            rest = &rest[k..];
            if let Some(Event::Frame(len)) = ev {
                if let Ok(r) = decode::<DeviceHeader, Reply>(self.reader.frame(len)) {
                    out.push(r);
                }
            }
        }
        out
    }

    /// A frame with a leading delimiter, as the host client sends them (it ends any
    /// garbage before it, so a frame never merges with noise).
    pub fn frame(&self, seq: u16, r: &Request<'_>) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME + 2];
        let n = encode(
            &HostHeader {
                session: self.session,
                seq,
            },
            r,
            &mut buf[1..],
        )
        .unwrap();
        buf[..n + 1].to_vec()
    }

    /// One request with the next sequence number; its reply.
    pub fn req(&mut self, b: &mut Board, r: &Request<'_>) -> Reply {
        let seq = self.seq;
        let f = self.frame(seq, r);
        let replies = self.raw(b, &f);
        let (h, reply) = replies
            .into_iter()
            .find(|(h, _)| h.answers == seq && h.session == self.session)
            .expect("no reply");
        if h.next == seq.wrapping_add(1) {
            self.seq = seq.wrapping_add(1);
        }
        reply
    }

    pub fn hello(&mut self, b: &mut Board) -> HelloInfo {
        let seq = self.seq;
        let f = self.frame(
            seq,
            &Request::Hello {
                version: PROTOCOL_VERSION,
            },
        );
        for (_, r) in self.raw(b, &f) {
            if let Reply::Hello(i) = r {
                self.seq = seq.wrapping_add(1);
                return i;
            }
        }
        panic!("no hello");
    }

    pub fn ok(&mut self, b: &mut Board, r: &Request<'_>) {
        match self.req(b, r) {
            Reply::Ack => {}
            other => panic!("{r:?}: {other:?}"),
        }
    }

    pub fn refused(&mut self, b: &mut Board, r: &Request<'_>) -> Refusal {
        match self.req(b, r) {
            Reply::Refused(why) => why,
            other => panic!("{r:?} was not refused: {other:?}"),
        }
    }

    pub fn status(&mut self, b: &mut Board) -> Status {
        match self.req(b, &Request::Status) {
            Reply::Status(s) => s,
            other => panic!("{other:?}"),
        }
    }

    /// Hello, config, upload and check of a job.
    pub fn upload(&mut self, b: &mut Board, h: &JobHeader, body: &[u8]) {
        self.ok(b, &Request::BeginJob(h.clone()));
        b.advance(1000);
        self.chunks(b, body, 0);
        self.ok(b, &Request::EndJob);
        for _ in 0..1000 {
            b.advance(1000);
            match self.status(b).job {
                JobSlot::Ready { .. } => return,
                JobSlot::Failed { why, .. } => panic!("{why}"),
                _ => {}
            }
        }
        panic!("job never checked");
    }

    /// Sends `body` in chunks from chunk number `first` on, each acknowledged.
    pub fn chunks(&mut self, b: &mut Board, body: &[u8], first: usize) {
        for (i, c) in body.chunks(MAX_CHUNK).enumerate().skip(first) {
            self.ok(
                b,
                &Request::Chunk {
                    offset: (i * MAX_CHUNK) as u32,
                    data: c,
                },
            );
        }
    }

    /// Homes and waits until homed.
    pub fn home(&mut self, b: &mut Board) {
        self.ok(b, &Request::Home);
        self.wait(b, |s| s.control.homed && s.control.mode == Mode::Idle);
    }

    /// Runs the board until `done` holds, failing after 120 s of board time.
    pub fn wait(&mut self, b: &mut Board, done: impl Fn(&Status) -> bool) -> Status {
        for _ in 0..2400 {
            let s = self.status(b);
            if done(&s) {
                return s;
            }
            b.advance(50_000);
        }
        panic!("condition not reached: {:?}", self.status(b));
    }

    /// A configured, homed board holding a checked job.
    pub fn ready(b: &mut Board, rows: i32) -> Host {
        Host::ready_with(b, config(), rows)
    }

    /// A board configured with `cfg`, homed, holding a checked job.
    pub fn ready_with(b: &mut Board, cfg: Config, rows: i32) -> Host {
        let mut h = Host::default();
        h.hello(b);
        h.ok(b, &Request::LoadConfig(cfg.clone()));
        b.advance(1000);
        let (hd, body) = small_job(&cfg, rows);
        h.upload(b, &hd, &body);
        h.home(b);
        h
    }
}

/// Valves closed and drivers off.
pub fn assert_safe(b: &Board) {
    assert_eq!(b.out.valves, 0, "a valve is open");
    assert!(!b.out.drivers, "drivers are on");
}
