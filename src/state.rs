//! The run state the core reports to everything above the executor: what it is doing
//! (`RunState`), why it stopped (`Fault`), and what a control cycle left (`Report`). A
//! leaf below the ramp, the executor and the wire, so that each can name the states
//! without importing the others; the executor re-exports them from its old paths. The
//! executor decides the states; this only names them.

use crate::command::CommandError;
use crate::outputs::Axis;
use crate::vol::Vol;
use serde::{Deserialize, Serialize};

/// Why the executor went to the safe state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Fault {
    /// A planned position lies outside the axis's travel limits.
    Limit {
        /// The axis.
        axis: Axis,
    },
    /// A cycle needed more steps than the drivers' maximum rate allows.
    StepRate {
        /// The axis.
        axis: Axis,
        /// Steps the cycle needed.
        steps: u32,
        /// Steps a cycle may have.
        max: u32,
    },
    /// The job queue ran dry while paste was flowing.
    Underrun,
    /// The job needs more look-ahead than `PLAN_CAPACITY` items give (features too fine
    /// for the bead section).
    LookaheadFull,
    /// A command that cannot be executed.
    InvalidCommand(CommandError),
    /// More material changes in flight than the channel model holds.
    ChannelFull,
    /// The flow did not die out after the valves closed.
    FlowDidNotStop,
    /// `tick` came more than `MAX_CATCH_UP` periods late.
    Late {
        /// Periods since the previous tick.
        periods: u64,
    },
    /// Emergency stop input.
    EStop,
    /// Watchdog expiry.
    Watchdog,
    /// Host link lost while printing (and the config says stop).
    LinkLost,
    /// A job command arrived with no job begun.
    NotReady,
    /// A config failed validation while loading; the old one is no longer trusted.
    InvalidConfig,
}

impl core::fmt::Display for Fault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Fault::Limit { axis } => write!(f, "{axis:?} would leave its travel limits"),
            Fault::StepRate { axis, steps, max } => write!(
                f,
                "{axis:?} needed {steps} steps in one cycle, more than the {max} allowed"
            ),
            Fault::Underrun => write!(f, "job queue ran dry while printing"),
            Fault::LookaheadFull => write!(
                f,
                "job needs more look-ahead than the executor holds (features too fine)"
            ),
            Fault::InvalidCommand(e) => write!(f, "invalid command: {e}"),
            Fault::ChannelFull => write!(f, "too many material changes in the channel at once"),
            Fault::FlowDidNotStop => write!(f, "flow did not stop after the valves closed"),
            Fault::Late { periods } => write!(f, "control cycle {periods} periods late"),
            Fault::EStop => write!(f, "emergency stop"),
            Fault::Watchdog => write!(f, "watchdog expired"),
            Fault::LinkLost => write!(f, "host link lost while printing"),
            Fault::NotReady => write!(f, "command before a job was begun"),
            Fault::InvalidConfig => write!(f, "machine config failed validation"),
        }
    }
}

/// What the executor is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum RunState {
    /// No job.
    Idle,
    /// Laying a bead.
    Printing,
    /// Waiting at a bead's end for the flow to die out.
    Settling,
    /// Travel or layer move, valves closed.
    Travelling,
    /// Dwell.
    Dwelling,
    /// Paused: valves shut, head at rest (mid-bead at the pause point, or between beads).
    Paused,
    /// Job finished.
    Done,
    /// Job aborted on request.
    Aborted,
    /// Stopped by a fault.
    Faulted,
    /// Valves shut for a pause; the head follows the flow's tail to the pause point. (A
    /// request still waiting for its valve decision, see `Executor::pause`, reads as
    /// Printing: the tick does not pay for telling them apart.)
    Pausing,
}

/// The state after a cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Report<R> {
    /// Run state.
    pub state: RunState,
    /// Head position the outputs were commanded to, mm (with speed ramps, the mean of the
    /// ramp window; the fields below marked "plan" run half a window ahead of it).
    pub position: [R; 3],
    /// Valves commanded open, bit per inlet.
    pub valves: u32,
    /// Inlet feeding the channel (model), if anything flows.
    pub feeding: Option<u8>,
    /// Material landing on the plate (model).
    pub landing: u8,
    /// Mean flow over the cycle, mm^3/s.
    pub q: R,
    /// Volume that left the nozzle this cycle.
    pub dv: Vol,
    /// Head speed along the print path this cycle, mm/s (0 off the path).
    pub speed: R,
    /// Head position along the concatenated print paths, as volume.
    pub plan_volume: Vol,
    /// Index (0-based, in push order) of the command being executed.
    pub command_index: u32,
    /// Material slugs in the channel and hanging filament (features in flight).
    pub slugs: u8,
}
