//! Step pulses: a 100 kHz timer interrupt (highest priority but the e-stop) turns the
//! control loop's per-period step counts into STEP/DIR edges. Each control period is 10
//! ticks: tick 0 sets DIR (10 us before any edge), pulses rise on ticks 1, 3, 5, 7, 9
//! spread evenly over the period and fall one tick later. Tick 0 also starts the next
//! control period, so steps and control stay in lockstep.

use crate::board::{PULSES_PER_PERIOD, STEPPED_AXES, TICKS_PER_PERIOD};
use core::sync::atomic::{AtomicI32, AtomicU32, Ordering};
use dollop::Axis;
use embassy_stm32::gpio::Output;
use embassy_stm32::peripherals::TIM3;
use embassy_stm32::timer::low_level::Timer;

/// Signed steps per axis the control loop asked for, not yet emitted.
static PENDING: [AtomicI32; STEPPED_AXES] = [const { AtomicI32::new(0) }; STEPPED_AXES];
/// Step ticks since start: the firmware's clock (`TICK_US` each).
pub static TICKS: AtomicU32 = AtomicU32::new(0);
/// Microseconds per step tick.
pub const TICK_US: u64 = 1_000_000 / crate::board::STEP_TICK_HZ as u64;

/// Microseconds since it was made, on the step clock: the 32-bit tick count wraps after
/// 11.9 h, the differences it takes do not. The control loop and the link keep one each.
pub struct Clock {
    last_ticks: u32,
    now_us: u64,
}

impl Clock {
    /// A clock at 0 now.
    pub fn new() -> Self {
        Clock {
            last_ticks: TICKS.load(Ordering::Acquire),
            now_us: 0,
        }
    }

    /// Microseconds since `new`, never going back.
    pub fn now_us(&mut self) -> u64 {
        let t = TICKS.load(Ordering::Acquire);
        self.now_us += t.wrapping_sub(self.last_ticks) as u64 * TICK_US;
        self.last_ticks = t;
        self.now_us
    }
}

/// Asks for `count` steps on `axis` in the next period (called by the control loop).
pub fn request(axis: Axis, forward: bool, count: u32) {
    let n = count.min(i32::MAX as u32) as i32;
    // An axis this board has no pins for cannot be asked for: `BoardLink` refuses configs
    // with more inlets than the board has, so nothing is dropped here in practice.
    if let Some(p) = PENDING.get(axis.index()) {
        p.fetch_add(if forward { n } else { -n }, Ordering::AcqRel);
    }
}

/// The step generator's pins and state; owned by its interrupt.
pub struct Stepper {
    /// The tick timer.
    pub timer: Timer<'static, TIM3>,
    /// STEP pins X, Y, Z, E0..E3.
    pub step: [Output<'static>; STEPPED_AXES],
    /// DIR pins X, Y, Z, E0..E3 (high = forward).
    pub dir: [Output<'static>; STEPPED_AXES],
    pattern: [u8; STEPPED_AXES],
    phase: u32,
    /// STEP pins now high, bit per axis: only those are written low again.
    high: u8,
    /// DIR pins now high (forward), bit per axis: a DIR pin is written only to change it.
    forward: u8,
}

impl Stepper {
    /// A stepper on these pins; `timer` must already tick at `STEP_TICK_HZ`.
    pub fn new(
        timer: Timer<'static, TIM3>,
        step: [Output<'static>; STEPPED_AXES],
        dir: [Output<'static>; STEPPED_AXES],
    ) -> Self {
        Stepper {
            timer,
            step,
            dir,
            pattern: [0; STEPPED_AXES],
            phase: 0,
            high: 0,
            // Reset levels: every pin starts low (`board::parts`).
            forward: 0,
        }
    }

    /// One tick. Returns true at the start of a control period.
    pub fn on_tick(&mut self) -> bool {
        self.timer.clear_update_interrupt();
        TICKS.fetch_add(1, Ordering::Release);
        let phase = self.phase;
        self.phase = (phase + 1) % TICKS_PER_PERIOD;
        if phase == 0 {
            self.all_low();
            let axes = PENDING
                .iter()
                .zip(self.dir.iter_mut())
                .zip(self.pattern.iter_mut());
            for (i, ((pending, dir), pattern)) in axes.enumerate() {
                let want = pending.swap(0, Ordering::AcqRel);
                let max = PULSES_PER_PERIOD as i32;
                let now = want.clamp(-max, max);
                if now != want {
                    // More than a period holds (a late control tick): the rest next period.
                    pending.fetch_add(want - now, Ordering::AcqRel);
                }
                let bit = 1u8 << i;
                if now > 0 && self.forward & bit == 0 {
                    dir.set_high();
                    self.forward |= bit;
                } else if now < 0 && self.forward & bit != 0 {
                    dir.set_low();
                    self.forward &= !bit;
                }
                *pattern = spread(now.unsigned_abs());
            }
            true
        } else if phase % 2 == 1 {
            let slot = (phase - 1) / 2;
            for (i, (step, pattern)) in self.step.iter_mut().zip(self.pattern.iter()).enumerate() {
                if pattern & (1 << slot) != 0 {
                    step.set_high();
                    self.high |= 1 << i;
                }
            }
            false
        } else {
            self.all_low();
            false
        }
    }

    /// Ends the pulses that are high (only those pins are written: fewer bus writes in
    /// the highest-rate interrupt, and a pin log that shows only real edges).
    fn all_low(&mut self) {
        if self.high == 0 {
            return;
        }
        for (i, s) in self.step.iter_mut().enumerate() {
            if self.high & (1 << i) != 0 {
                s.set_low();
            }
        }
        self.high = 0;
    }
}

/// Which of the period's pulse slots carry a pulse for `n` pulses, evenly spread.
fn spread(n: u32) -> u8 {
    let mut bits = 0u8;
    for i in 0..n.min(PULSES_PER_PERIOD) {
        bits |= 1 << (i * PULSES_PER_PERIOD / n);
    }
    bits
}
