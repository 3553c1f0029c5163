//! A stateful driver of the simulated board (`dollop::device::SimBoard`), shared by the
//! `board_states` fuzz target and the bounded property test `tests/device_states.rs`:
//! bytes become a sequence of host requests (hello, valid and hostile configs, homing,
//! job uploads good and corrupt, start, pause, resume, abort, e-stop, jogs, valve tests,
//! settings), raw frames, and board events (time passing, the e-stop input, a pulled
//! cable, broken endstops), and after every control cycle the outputs are checked
//! against what the board's state says they must be.

use dollop::config::{Pressure, SyringeConfig};
use dollop::device::{RamStore, SimBoard};
use dollop::job::{self, JobHeader};
use dollop::wire::{
    encode, HostHeader, LinkLossPolicy, Mode, Request, Settings, MAX_CHUNK, MAX_FRAME,
    PROTOCOL_VERSION,
};
use dollop::{Axis, Command, Config};

/// The board under test: a RAM job store big enough for the driver's jobs.
pub type Board = SimBoard<RamStore<Vec<u8>>>;

/// Bundled configs, parsed once per run (small; the fuzzer's time goes to the board).
const CONFIGS: [&str; 3] = [
    include_str!("../../../configs/seed-paper-valves.toml"),
    include_str!("../../../configs/syringes.toml"),
    include_str!("../../../configs/food-pastes.toml"),
];

/// Simulated time one input may spend, us: bounds a fuzz execution's cost.
const TIME_BUDGET_US: u64 = 1_000_000;

/// Reads the input a byte at a time; zeros once it runs out.
struct Bytes<'a> {
    data: &'a [u8],
    at: usize,
}

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        let b = self.data.get(self.at).copied().unwrap_or(0);
        self.at += 1;
        b
    }
    fn done(&self) -> bool {
        self.at >= self.data.len()
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }
    /// A float that is often hostile: 0, negative, NaN, infinities, tiny, huge.
    fn f32(&mut self) -> f32 {
        match self.u8() % 10 {
            0 => 0.0,
            1 => -1.0,
            2 => f32::NAN,
            3 => f32::INFINITY,
            4 => 1e-30,
            5 => 1e30,
            6 => 0.01,
            7 => 1e-6,
            _ => f32::from_bits(self.u32()),
        }
    }
}

/// The driver: a board, a host's session state, and the configs it may load.
pub struct Driver {
    /// The board.
    pub board: Board,
    configs: Vec<Config>,
    /// The config the board last accepted, if any (jobs are built for it).
    loaded: Option<Config>,
    session: u16,
    seq: u16,
    spent_us: u64,
    /// Control cycles checked.
    pub cycles: u64,
}

impl Default for Driver {
    fn default() -> Self {
        Driver::new()
    }
}

impl Driver {
    /// A powered-up board and bundled configs.
    pub fn new() -> Self {
        let configs = CONFIGS
            .iter()
            .map(|t| toml::from_str(t).expect("bundled config parses"))
            .collect();
        let board = Board::new(RamStore::new(vec![0xFF; 64 * 1024]));
        check(&board);
        Driver {
            board,
            configs,
            loaded: None,
            session: 0x4242,
            seq: 1,
            spent_us: 0,
            cycles: 0,
        }
    }

    /// Runs one input: an optional scripted start (hello, config, job, home, start: so
    /// the fuzzer reaches a running print at once), then one step per few bytes.
    pub fn run(&mut self, data: &[u8]) {
        let mut b = Bytes { data, at: 0 };
        self.spent_us = 0;
        let script = b.u8();
        if script & 1 == 1 {
            let cfg = (script >> 1) as usize % self.configs.len();
            self.send(&Request::Hello {
                version: PROTOCOL_VERSION,
            });
            let c = self.configs[cfg].clone();
            self.load(c);
            self.upload(1 + (script >> 3) as i32 % 3, 0);
            // Z homes down here (the default homes it up, seconds away from the plate).
            let mut settings = Settings::DEFAULT;
            settings.home_to_max = [false; 3];
            self.send(&Request::Settings(settings));
            // Stand the machine half a millimetre from each endstop so homing takes
            // milliseconds, not the seconds of board time a fuzz input cannot afford.
            if let Some(e) = self.board.control.executor() {
                let m = e.machine().motion;
                let to_max = self.board.control.settings().home_to_max;
                for (a, at) in self.board.start_mm.iter_mut().enumerate() {
                    *at = if to_max[a] {
                        m.max_mm[a] - 0.5
                    } else {
                        m.min_mm[a] + 0.5
                    };
                }
            }
            self.send(&Request::Home);
            for _ in 0..100 {
                if self.board.control.mode() != Mode::Homing {
                    break;
                }
                self.run_for(20_000);
            }
            if script & 0x80 != 0 {
                self.send(&Request::Start);
            }
        }
        while !b.done() && self.spent_us < TIME_BUDGET_US {
            self.step(&mut b);
        }
    }

    fn step(&mut self, b: &mut Bytes<'_>) {
        match b.u8() % 18 {
            0 => {
                let version = if b.u8() < 240 {
                    PROTOCOL_VERSION
                } else {
                    b.u8() as u16
                };
                self.send(&Request::Hello { version });
            }
            1 => {
                let i = b.u8() as usize % self.configs.len();
                let c = self.configs[i].clone();
                self.load(c);
            }
            2 => {
                let i = b.u8() as usize % self.configs.len();
                let c = hostile(self.configs[i].clone(), b);
                self.load(c);
            }
            3 => self.send(&Request::Home),
            16 => self.status(),
            4 => {
                let rows = 1 + b.u8() as i32 % 3;
                let corrupt = b.u8();
                self.upload(rows, corrupt);
            }
            5 => self.send(&Request::Start),
            6 => self.send(&Request::Pause),
            7 => self.send(&Request::Resume),
            8 => self.send(&Request::Abort),
            9 => self.send(&Request::EStop),
            10 => self.send(&Request::ClearFault),
            11 => {
                let axis = match b.u8() % 5 {
                    0 => Axis::X,
                    1 => Axis::Y,
                    2 => Axis::Z,
                    _ => Axis::E(b.u8()),
                };
                let um = match b.u8() % 4 {
                    0 => b.u32() as i32,
                    1 => i32::MIN,
                    _ => (b.u8() as i32 - 128) * 100,
                };
                self.send(&Request::Jog { axis, um });
            }
            12 => {
                let inlet = b.u8() % 6;
                let open = b.u8() & 1 == 1;
                self.send(&Request::Valve { inlet, open });
            }
            13 => {
                let mut s = Settings::DEFAULT;
                s.on_link_loss = if b.u8() & 1 == 1 {
                    LinkLossPolicy::Stop
                } else {
                    LinkLossPolicy::Pause
                };
                s.home_speed_mm_s = b.f32();
                s.home_backoff_mm = b.f32();
                s.home_to_max[b.u8() as usize % 3] ^= true;
                self.send(&Request::Settings(s));
            }
            14 => {
                // Raw bytes, or a valid frame with its payload's bytes changed.
                let n = b.u8() as usize % 48;
                let mut raw: Vec<u8> = (0..n).map(|_| b.u8()).collect();
                if b.u8() & 1 == 1 {
                    let mut f = self.frame(self.seq, &Request::Status);
                    if let Some(x) = f.get_mut(1 + n % 8) {
                        *x ^= 1 << (n % 8);
                    }
                    raw.extend_from_slice(&f);
                }
                self.board.receive(&raw);
                self.run_for(300);
            }
            15 => {
                let ms = b.u8() as u64 * 4;
                self.run_for(ms * 1000);
            }
            _ => match b.u8() % 5 {
                0 | 1 => {
                    self.board.estop ^= true;
                    self.run_for(500);
                }
                2 => {
                    self.board.disconnect();
                    self.session = self.session.wrapping_add(1);
                    self.run_for(500);
                }
                3 => self.board.endstops_broken ^= true,
                _ => self.seq = self.seq.wrapping_add(b.u8() as u16),
            },
        }
    }

    /// Asks for the status (what a following host does; the board counts the link as
    /// alive while requests arrive).
    pub fn status(&mut self) {
        self.send(&Request::Status);
    }

    fn frame(&self, seq: u16, r: &Request<'_>) -> Vec<u8> {
        let mut buf = vec![0u8; MAX_FRAME + 2];
        let n = encode(
            &HostHeader {
                session: self.session,
                seq,
            },
            r,
            &mut buf[1..],
        )
        .expect("a request fits a frame");
        buf.truncate(n + 1);
        buf
    }

    /// Sends one request and runs the board long enough to answer it.
    fn send(&mut self, r: &Request<'_>) {
        let f = self.frame(self.seq, r);
        self.seq = self.seq.wrapping_add(1);
        self.board.receive(&f);
        self.run_for(300);
    }

    fn load(&mut self, c: Config) {
        let ok = c.validate::<f32, { dollop::DEFAULT_INLETS }>().is_ok();
        self.send(&Request::LoadConfig(c.clone()));
        self.run_for(1000);
        if ok && self.board.control.mode() != Mode::Unconfigured {
            self.loaded = Some(c);
        }
    }

    /// Uploads a small two-material job for the loaded config; `corrupt` picks a bad
    /// CRC, a truncated body, a chunk at a wrong offset or a header for another config.
    fn upload(&mut self, rows: i32, corrupt: u8) {
        let cfg = self
            .loaded
            .clone()
            .unwrap_or_else(|| self.configs[0].clone());
        let (mut h, body) = small_job(&cfg, rows);
        match corrupt % 8 {
            1 => h.body_crc ^= 1,
            2 => h.config_hash ^= 1,
            3 => h.body_len += 7,
            4 => h.bounds_max_um[0] = i32::MAX,
            _ => {}
        }
        self.send(&Request::BeginJob(h));
        self.run_for(1000);
        let mut offset = 0usize;
        for (i, c) in body.chunks(MAX_CHUNK).enumerate() {
            if corrupt % 8 == 5 && i == 1 {
                continue;
            }
            let at = if corrupt % 8 == 6 { offset + 1 } else { offset };
            self.send(&Request::Chunk {
                offset: at as u32,
                data: c,
            });
            offset += c.len();
        }
        self.send(&Request::EndJob);
        self.run_for(20_000);
    }

    /// Runs control cycles for `us` of board time, checking the outputs after each.
    pub fn run_for(&mut self, us: u64) {
        let end = self.board.now_us + us;
        while self.board.now_us < end {
            let period = self
                .board
                .control
                .executor()
                .map_or(100, |e| e.machine().period_us as u64)
                .max(1);
            self.board.now_us += period;
            self.spent_us += period;
            self.board.cycle();
            self.cycles += 1;
            let mut sink = [0u8; 4096];
            while self.board.take_tx(&mut sink) > 0 {}
            check(&self.board);
        }
    }
}

/// What the outputs must be, given the board's state after a control cycle.
pub fn check(b: &Board) {
    let mode = b.control.mode();
    let snap = b.snapshot();
    let out = &b.out;
    let ctx = || {
        format!(
            "mode {mode:?}, snapshot {snap:?}, valves {:#x}, drivers {}",
            out.valves, out.drivers
        )
    };
    if b.estop || snap.estop {
        assert_eq!(out.valves, 0, "e-stop with a valve open: {}", ctx());
        assert!(!out.drivers, "e-stop with the drivers on: {}", ctx());
    }
    match mode {
        Mode::Halted => {
            assert_eq!(out.valves, 0, "halted with a valve open: {}", ctx());
            assert!(!out.drivers, "halted with the drivers on: {}", ctx());
        }
        Mode::Unconfigured | Mode::Idle | Mode::Homing | Mode::Jogging => {
            assert_eq!(out.valves, 0, "a valve open while not printing: {}", ctx());
        }
        Mode::ValveTest | Mode::Job => {}
    }
    if let Some(e) = b.control.executor() {
        let inlets = e.machine().inlet_count();
        if inlets > 0 && inlets < 32 {
            assert_eq!(
                out.valves >> inlets,
                0,
                "a valve beyond the {inlets} configured inlets: {}",
                ctx()
            );
        }
    }
}

/// A config with one value made hostile.
fn hostile(mut c: Config, b: &mut Bytes<'_>) -> Config {
    let v = b.f32();
    let i = b.u8() as usize % c.inlets.len().max(1);
    let a = b.u8() as usize % 3;
    match b.u8() % 16 {
        0 => c.channel.line_pitch_mm = v,
        1 => c.channel.layer_height_mm = v,
        2 => c.channel.nozzle_diameter_mm = v,
        3 => c.channel.channel_length_mm = v,
        4 => c.motion.steps_per_mm[a] = v,
        5 => c.motion.max_speed_mm_s[a] = v,
        6 => c.motion.max_accel_mm_s2[a] = v,
        7 => c.motion.print_speed_mm_s = v,
        8 => c.motion.travel_min_mm[a] = v,
        9 => c.motion.max_step_rate_hz = v,
        10 => c.control.rate_hz = b.u32(),
        11 => {
            if let Some(x) = c.inlets.get_mut(i) {
                x.pressure_kpa = Pressure::Kpa(v);
            }
        }
        12 => {
            if let Some(x) = c.inlets.get_mut(i) {
                x.pressure_rise_ms = v;
            }
        }
        13 => {
            let n = b.f32();
            for x in c.inlets.iter_mut() {
                x.syringe = Some(SyringeConfig {
                    steps_per_mm3: 2.264,
                    lag_k: v,
                    lag_n: n,
                });
            }
        }
        14 => {
            if let Some(x) = c.inlets.get_mut(i) {
                x.valve_close_delay_ms = v;
            }
        }
        _ => c.motion.flow_stop_fraction = v,
    }
    c
}

/// A short two-material job near (20, 20) mm: `rows` beads of 10 mm.
fn small_job(cfg: &Config, rows: i32) -> (JobHeader, Vec<u8>) {
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
    let mut body = Vec::new();
    let mut buf = [0u8; job::MAX_COMMAND_LEN];
    let mut lo = start;
    let mut hi = start;
    let mut at = start;
    for c in &cmds {
        if let Ok(bytes) = job::encode_command(c, &mut buf) {
            body.extend_from_slice(bytes);
        }
        match *c {
            Command::Print { dx, dy, .. } => {
                at[0] += dx;
                at[1] += dy;
            }
            Command::Travel { x, y, z } => at = [x, y, z],
            Command::Layer { z } => at[2] = z,
            _ => {}
        }
        for k in 0..3 {
            lo[k] = lo[k].min(at[k]);
            hi[k] = hi[k].max(at[k]);
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
