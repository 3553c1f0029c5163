//! Measures the executor's control cycle on a Cortex-M4F under QEMU: runs a whole job
//! (a chessboard: a switch every millimetre, corners every row) tick by tick with SysTick
//! timing each tick, for the seed printhead with real valves (Newtonian), for
//! power-law pastes and for stepper syringes, and prints the mean and worst instructions
//! per tick.
#![no_std]
#![no_main]

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use dollop::{Axis, Command, Config, Executor, Outputs, RunState};

static VALVES: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/valves.config"));
static PASTES: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/pastes.config"));
static SYRINGES: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/syringes.config"));
static HEAD: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/job.head"));
static BODY: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/job.body"));

/// SysTick counts per instruction under `-icount shift=10` (1024 ns per instruction at the
/// board's 25 MHz system clock).
const COUNTS_PER_INSN: u32 = 256; // tenths: 25.6

/// Outputs that only remember enough that the work cannot be optimised away.
struct Null {
    sum: u32,
}

impl Outputs for Null {
    fn step(&mut self, axis: Axis, forward: bool, count: u32) {
        self.sum = self
            .sum
            .wrapping_add(count * (axis.index() as u32 + 1) + forward as u32);
    }
    fn valve(&mut self, inlet: u8, open: bool) {
        self.sum = self.sum.wrapping_add(inlet as u32 * 7 + open as u32);
    }
    fn drivers(&mut self, enabled: bool) {
        self.sum = self.sum.wrapping_add(enabled as u32);
    }
}

struct Stats {
    top: [(u32, u32); 8],
    ticks: u32,
    total: u64,
    worst: u32,
    worst_state: RunState,
    worst_at: u32,
}

fn run(name: &str, config: &[u8], syst: &mut SYST) {
    let cfg: Config = match postcard::from_bytes(config) {
        Ok(c) => c,
        Err(_) => {
            hprintln!("{}: config does not decode", name);
            return;
        }
    };
    let machine = match cfg.validate::<f32, 4>() {
        Ok(m) => m,
        Err(_) => {
            hprintln!("{}: config does not validate", name);
            return;
        }
    };
    let period = machine.period_us as u64;
    let mut ex: Executor<f32> = Executor::new(machine);
    let start = [
        i32::from_le_bytes([HEAD[0], HEAD[1], HEAD[2], HEAD[3]]),
        i32::from_le_bytes([HEAD[4], HEAD[5], HEAD[6], HEAD[7]]),
        i32::from_le_bytes([HEAD[8], HEAD[9], HEAD[10], HEAD[11]]),
    ];
    if ex.begin(start, HEAD[12]).is_err() {
        hprintln!("{}: job does not begin", name);
        return;
    }
    // BENCH_TICKS stops early: runs of K and 2K ticks under insn-count give the
    // instructions of K ticks by difference.
    let max_ticks: u32 = match option_env!("BENCH_TICKS") {
        Some(t) => parse_u32(t),
        None => u32::MAX,
    };
    let mut body = BODY;
    let mut pending: Option<Command> = None;
    let mut out = Null { sum: 0 };
    let mut s = Stats {
        top: [(0, 0); 8],
        ticks: 0,
        total: 0,
        worst: 0,
        worst_state: RunState::Idle,
        worst_at: 0,
    };
    // The feeder is outside the measured tick, as in the firmware (another task).
    loop {
        while ex.room() > 0 {
            let cmd = match pending.take() {
                Some(c) => c,
                None => match postcard::take_from_bytes::<Command>(body) {
                    Ok((c, rest)) => {
                        body = rest;
                        c
                    }
                    Err(_) => break,
                },
            };
            if ex.push(cmd).is_err() {
                pending = Some(cmd);
                break;
            }
        }
        let now = s.ticks as u64 * period;
        let t0 = SYST::get_current();
        let r = ex.tick(now, &mut out);
        let t1 = SYST::get_current();
        let counts = t0.wrapping_sub(t1) & 0x00FF_FFFF;
        s.ticks += 1;
        s.total += counts as u64;
        let state = match r {
            Ok(rep) => rep.state,
            Err(_) => {
                hprintln!("{}: fault at tick {}", name, s.ticks);
                break;
            }
        };
        if let Some(slot) = s.top.iter_mut().min_by_key(|t| t.0) {
            if counts > slot.0 {
                *slot = (counts, s.ticks);
            }
        }
        if counts > s.worst {
            s.worst = counts;
            s.worst_state = state;
            s.worst_at = s.ticks;
        }
        if state == RunState::Done || s.ticks >= max_ticks {
            break;
        }
    }
    let _ = syst;
    if option_env!("BENCH_TOP").is_some() {
        for (c, t) in s.top {
            hprintln!(
                "  tick {}: {} instructions",
                t,
                c as u64 * 10 / COUNTS_PER_INSN as u64
            );
        }
    }
    let mean_x10 = (s.total * 10 * 10 / (s.ticks as u64 * COUNTS_PER_INSN as u64)) as u32;
    let worst_x10 = (s.worst as u64 * 10 * 10 / COUNTS_PER_INSN as u64) as u32;
    hprintln!(
        "{}: {} ticks ({} s printed); instructions per tick: mean {}.{}, worst {}.{} (tick {}, {:?}); outputs checksum {}",
        name,
        s.ticks,
        s.ticks as u64 * period / 1_000_000,
        mean_x10 / 10,
        mean_x10 % 10,
        worst_x10 / 10,
        worst_x10 % 10,
        s.worst_at,
        s.worst_state,
        out.sum
    );
}

fn parse_u32(s: &str) -> u32 {
    s.bytes().filter(u8::is_ascii_digit).fold(0u32, |a, d| {
        a.saturating_mul(10).saturating_add((d - b'0') as u32)
    })
}

#[entry]
fn main() -> ! {
    let mut cp = match cortex_m::Peripherals::take() {
        Some(p) => p,
        None => {
            debug::exit(debug::EXIT_FAILURE);
            loop {
                cortex_m::asm::wfi();
            }
        }
    };
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(0x00FF_FFFF);
    cp.SYST.clear_current();
    cp.SYST.enable_counter();
    // Calibration: `delay(n)` is a two-instruction loop run n/2 times, about n instructions.
    let n = 200_000u32;
    let t0 = SYST::get_current();
    cortex_m::asm::delay(n);
    let t1 = SYST::get_current();
    let counts = t0.wrapping_sub(t1) & 0x00FF_FFFF;
    hprintln!(
        "calibration: delay({}) took {} SysTick counts = {} instructions at 25.6 counts each",
        n,
        counts,
        counts as u64 * 10 / COUNTS_PER_INSN as u64
    );
    // BENCH_ONLY=valves|pastes|syringes runs just one machine.
    let only: Option<&str> = option_env!("BENCH_ONLY");
    let machines: [(&str, &str, &[u8]); 3] = [
        ("valves", "seed printhead, real valves (Newtonian)", VALVES),
        ("pastes", "food pastes, power law n = 0.6 / 0.45", PASTES),
        ("syringes", "two stepper syringes (Weibull lag)", SYRINGES),
    ];
    for (key, name, config) in machines {
        if only.is_none_or(|o| o == key) {
            run(name, config, &mut cp.SYST);
        }
    }
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
