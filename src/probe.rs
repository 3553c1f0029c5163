//! Where a control cycle's instructions go, on the chip (feature `probe`, never in the
//! firmware): SysTick's count over named sections of the tick, summed per section until
//! the caller takes them (`take`). bench-m4 built with `--features probe` prints the
//! sections' means per tick; the tick's total is its own SysTick span. A section costs
//! its probe about 10 instructions, and the compiler may move a few instructions across
//! a probe's read of SysTick: the figures are a map of the tick, not an exact split.
//! Stops at counting: the bench reads and prints.

use core::sync::atomic::{AtomicU32, Ordering};

/// The flow model's step (`FlowModel::step`).
pub const FLOW: usize = 0;
/// The head along the plan: the phases of one cycle (`cycle_once`'s loop).
pub const PHASES: usize = 1;
/// A valve decision's sizing steps after it (`Executor::sizing_step`).
pub const SIZING: usize = 2;
/// Valve decisions and the predictions' work (`decide_valves`).
pub const DECIDE: usize = 3;
/// The cycle's frame as the ring takes it (`frame`).
pub const FRAME: usize = 4;
/// The ring's push, plain or narrowed (`Ramp::push`, `Ramp::push_narrow`).
pub const RING: usize = 5;
/// The flow's follower: its push, its `follow`, and the ring's bend.
pub const FOLLOWER: usize = 6;
/// Of the follower, `FlowFollow::follow` alone (inside `FOLLOWER`).
pub const FOLLOW: usize = 7;
/// The window's mean position (`Ramp::position`).
pub const MEAN: usize = 8;
/// The step outputs (`move_head`).
pub const STEPS: usize = 9;
/// Plungers, valves and the tick's report.
pub const REPORT: usize = 10;
/// The head's slowing at tight fillets (`Executor::slow_at_turns`).
pub const TURNS: usize = 11;
/// Sections.
pub const N: usize = 12;
/// Each section's name, by its index.
pub const NAMES: [&str; N] = [
    "flow model step",
    "plan phases",
    "decision sizing",
    "valve decisions, predictions",
    "frame",
    "ring push",
    "follower (all)",
    "  of which follow()",
    "window mean",
    "step outputs",
    "plungers, valves, report",
    "slowing at tight fillets",
];

#[allow(clippy::declare_interior_mutable_const)]
const ZERO: AtomicU32 = AtomicU32::new(0);
/// SysTick counts per section since the last `take`.
static COUNTS: [AtomicU32; N] = [ZERO; N];

/// SysTick's current value (it counts down, 24 bits).
#[inline(always)]
pub fn now() -> u32 {
    cortex_m::peripheral::SYST::get_current()
}

/// Adds the SysTick counts since `start` (a `now`) to section `i`.
#[inline(always)]
pub fn add(i: usize, start: u32) {
    let d = start.wrapping_sub(now()) & 0x00FF_FFFF;
    COUNTS[i].fetch_add(d, Ordering::Relaxed);
}

/// Each section's counts since the last call, and zero again.
pub fn take() -> [u32; N] {
    core::array::from_fn(|i| COUNTS[i].swap(0, Ordering::Relaxed))
}
