//! The core's fixed capacities, each chosen on purpose: how many inlets a build and a
//! config may have, and the rings and queues whose sizes set the executor's RAM. A leaf
//! (it uses nothing), so that the config, the outputs and the ramp can all size by them
//! without importing each other; the modules that own the storage re-export them from
//! their old paths. Sizes private to one module (the per-step ramps, the wire's frames,
//! the device's queues) stay with that module.

/// Most inlets (valves and materials) one build of the core supports by default.
pub const DEFAULT_INLETS: usize = 4;

/// Most inlets a config can list (the wire and file formats' limit); a build supports
/// `N <= MAX_CONFIG_INLETS` of them and refuses configs with more. Also the valves the
/// safe state closes (`crate::outputs::force_safe`), whatever the config says.
pub const MAX_CONFIG_INLETS: usize = 8;

/// Planned items (finalised print segments, travels, dwells, end) the executor holds
/// ahead of the head. The valve cursor needs the path up to (channel + filament volume +
/// switch lead) / bead section ahead, about 4 mm on the seed printhead: 20 segments of
/// 0.2 mm. 256 leaves room for finer beads and keeps RAM use on the STM32 near 20 KiB.
pub const PLAN_CAPACITY: usize = 256;

/// Material boundaries held ahead of the valve cursor (at most one per planned item).
pub const BOUNDARY_CAPACITY: usize = PLAN_CAPACITY;

/// Slugs the channel model holds, from the plate to the junction. Each change of the
/// feeding material starts one, so this bounds how many features can be in flight at once:
/// the smallest printable feature is about (channel + hanging volume) / 64 of bead.
pub const SLUG_CAPACITY: usize = 64;

/// Frames the speed-ramp ring holds (`crate::ramp`): a window of up to
/// `RAMP_CAPACITY - 1` cycles (51 ms at 10 kHz: the seed printhead's 22.5 mm/s step at
/// 630 mm/s^2 of X/Y limit). A power of two, for the index mask; 48 bytes a frame with
/// four inlets, 24 KiB in all. The config refuses a machine whose window needs more.
pub const RAMP_CAPACITY: usize = 512;
