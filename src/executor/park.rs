//! Parked pauses: once a pause has brought the head to rest at the pause point, the head
//! lifts by the machine's `Park::lift_mm` and moves to `Park::xy_mm`; `resume` brings it
//! back over the pause point, lowers it, and only then restarts the flow as a resume at
//! the pause point does (`pause.rs`). On a syringe machine a `refill` while parked
//! retracts every plunger to where its fill began and restarts its count there: the
//! volume clock and the channel's slugs are untouched, so no boundary moves. The valves
//! stay shut throughout; moves use the travel speed and the axes' limits. The head holds
//! still for one ramp window at the pause point before it leaves, at the park position,
//! and back on the pause point before the flow restarts, so that the outputs (half a
//! window behind the plan with speed ramps) reach each exactly.

use super::{Executor, Phase};
use crate::motion::Trapezoid;
use crate::real::Real;
use crate::vol::Vol;

/// Where a parked pause is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParkStage {
    /// Not parking (no park asked, or back and printing).
    None,
    /// At rest on the pause point, the outputs catching up before the lift.
    Wait,
    /// Lifting Z over the pause point.
    Lift,
    /// Moving to the park position.
    Out,
    /// At the park position (a refill may run).
    Parked,
    /// Moving back over the pause point.
    Back,
    /// Lowering Z onto the pause point.
    Lower,
    /// On the pause point, the outputs catching up before the flow restarts.
    Land,
}

/// Why `refill` did nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefillError {
    /// Only a syringe machine has plungers to retract.
    NotSyringes,
    /// The head is not at the park position (park first: `park`).
    NotParked,
}

impl core::fmt::Display for RefillError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RefillError::NotSyringes => {
                write!(f, "nothing to refill: this machine's inlets are not syringes")
            }
            RefillError::NotParked => write!(
                f,
                "refill only while parked: pause with park first, and wait for the head to reach the park position"
            ),
        }
    }
}

/// One straight move of the excursion.
#[derive(Clone, Copy, Debug)]
struct Leg<R> {
    from: [R; 3],
    to: [R; 3],
    dir: [R; 3],
    trap: Trapezoid<R>,
    cycles: u32,
}

/// The park request and where the excursion is.
#[derive(Clone, Copy, Debug)]
pub(super) struct ParkState<R> {
    /// Park once the pause is at rest.
    pub wanted: bool,
    pub stage: ParkStage,
    /// The pause point, where the head returns.
    home: [R; 3],
    leg: Option<Leg<R>>,
    /// Cycles left to hold still (`Wait`, `Parked`, `Land`).
    hold: u32,
    /// `resume` asked: go back once parked (and any refill retracted).
    resume_due: bool,
    /// Plungers still retracting for a refill.
    refilling: bool,
    /// Refills done during the current job.
    pub refills: u32,
}

impl<R: Real> ParkState<R> {
    pub const NONE: Self = ParkState {
        wanted: false,
        stage: ParkStage::None,
        home: [R::ZERO; 3],
        leg: None,
        hold: 0,
        resume_due: false,
        refilling: false,
        refills: 0,
    };
}

impl<R: Real, const N: usize> Executor<R, N> {
    /// Requests a pause (as `pause`) that parks the head once at rest: Z lifts by the
    /// configured amount (cut to the Z travel maximum), then the head moves to the park
    /// position. Asked while already paused, the head parks from the pause point.
    pub fn park(&mut self) {
        self.pause();
        if !self.pause.requested || self.pause.park.resume_due {
            return;
        }
        self.pause.park.wanted = true;
        if matches!(self.phase, Phase::Paused { .. }) && self.pause.park.stage == ParkStage::None {
            self.park_at_rest();
        }
    }

    /// Where a parked pause is (`ParkStage::None` when not parking).
    pub fn park_stage(&self) -> ParkStage {
        self.pause.park.stage
    }

    /// True while the head is off the pause point for a park, or the outputs may still
    /// show it off (lifting, out, parked, back, lowering, landing).
    pub fn parked_off_point(&self) -> bool {
        !matches!(self.pause.park.stage, ParkStage::None | ParkStage::Wait)
    }

    /// Refills done during this job (each re-zeroed the plungers).
    pub fn refills(&self) -> u32 {
        self.pause.park.refills
    }

    /// Syringe refill while parked: every plunger retracts (within the step-rate limit) to
    /// where its current fill began, and its count restarts there: the operator swaps or
    /// refills the syringes, then `resume`s. Refused on a pneumatic machine or when not
    /// parked.
    pub fn refill(&mut self) -> Result<(), RefillError> {
        if !self.machine.syringes {
            return Err(RefillError::NotSyringes);
        }
        if self.pause.park.stage != ParkStage::Parked {
            return Err(RefillError::NotParked);
        }
        self.pause.park.refilling = true;
        Ok(())
    }

    /// The pause came to rest: start the excursion if a park was asked.
    pub(super) fn park_at_rest(&mut self) {
        if !self.pause.park.wanted {
            return;
        }
        let p = &mut self.pause.park;
        p.home = self.head_pos;
        p.stage = ParkStage::Wait;
        p.hold = self.machine.ramp_cycles;
        p.resume_due = false;
    }

    /// `resume` while parking: go back first. False when no park is under way (the
    /// resume then acts at once).
    pub(super) fn park_resume(&mut self) -> bool {
        let p = &mut self.pause.park;
        p.wanted = false;
        match p.stage {
            ParkStage::None => false,
            // Not off the point yet: nothing to undo.
            ParkStage::Wait => {
                p.stage = ParkStage::None;
                false
            }
            _ => {
                p.resume_due = true;
                true
            }
        }
    }

    /// One cycle of the excursion (phase `Paused`). Out of line: a parked pause is rare.
    #[inline(never)]
    pub(super) fn park_cycle(&mut self) {
        if self.pause.park.refilling {
            self.retract_plungers();
        }
        let p = self.pause.park;
        match p.stage {
            ParkStage::None => {}
            ParkStage::Wait => {
                if p.hold <= 1 {
                    let mut to = p.home;
                    to[2] =
                        (p.home[2] + self.machine.park.lift_mm).min(self.machine.motion.max_mm[2]);
                    self.start_leg(ParkStage::Lift, to);
                } else {
                    self.pause.park.hold -= 1;
                }
            }
            ParkStage::Parked => {
                if p.hold > 1 {
                    self.pause.park.hold -= 1;
                } else if p.resume_due && !p.refilling {
                    let mut to = p.home;
                    to[2] = self.head_pos[2];
                    self.start_leg(ParkStage::Back, to);
                }
            }
            ParkStage::Land => {
                if p.hold <= 1 {
                    self.pause.park = ParkState {
                        refills: p.refills,
                        ..ParkState::NONE
                    };
                    // Phase `Paused` here: the restart cannot be refused.
                    let _ = self.restart_flow();
                } else {
                    self.pause.park.hold -= 1;
                }
            }
            ParkStage::Lift | ParkStage::Out | ParkStage::Back | ParkStage::Lower => {
                if self.advance_leg() {
                    self.next_leg(p.stage);
                }
            }
        }
    }

    /// The move after one that ended.
    fn next_leg(&mut self, done: ParkStage) {
        let home = self.pause.park.home;
        match done {
            ParkStage::Lift => {
                let xy = self.machine.park.xy_mm;
                self.start_leg(ParkStage::Out, [xy[0], xy[1], self.head_pos[2]]);
            }
            // Held a ramp window there before any return: the outputs reach it too.
            ParkStage::Out => {
                self.pause.park.stage = ParkStage::Parked;
                self.pause.park.hold = self.machine.ramp_cycles;
            }
            ParkStage::Back => self.start_leg(ParkStage::Lower, home),
            _ => {
                self.head_pos = home;
                self.pause.park.stage = ParkStage::Land;
                self.pause.park.hold = self.machine.ramp_cycles;
            }
        }
    }

    /// Plans a straight move from the head to `to` within the travel speed and the axes'
    /// limits (as a travel's).
    fn start_leg(&mut self, stage: ParkStage, to: [R; 3]) {
        let from = self.head_pos;
        let mut dir = [R::ZERO; 3];
        let mut len2 = R::ZERO;
        for a in 0..3 {
            dir[a] = to[a] - from[a];
            len2 += dir[a] * dir[a];
        }
        let len = len2.sqrt();
        let m = &self.machine.motion;
        let (mut v, mut acc) = (m.travel_speed, R::of(1e9));
        if len > R::of(1e-6) {
            for (a, d) in dir.iter_mut().enumerate() {
                *d /= len;
                let c = d.abs();
                if c > R::of(1e-9) {
                    v = v.min(m.max_speed[a] / c);
                    acc = acc.min(m.max_accel[a] / c);
                }
            }
        }
        self.pause.park.stage = stage;
        self.pause.park.leg = Some(Leg {
            from,
            to,
            dir,
            trap: Trapezoid::new(len, v, acc),
            cycles: 0,
        });
    }

    /// Moves the head one cycle along the leg; true when it arrived.
    fn advance_leg(&mut self) -> bool {
        let Some(mut leg) = self.pause.park.leg else {
            return true;
        };
        leg.cycles += 1;
        let t = self.dt * R::from_u32(leg.cycles);
        if t >= leg.trap.duration() {
            self.head_pos = leg.to;
            self.pause.park.leg = None;
            return true;
        }
        let d = leg.trap.distance(t);
        for a in 0..3 {
            self.head_pos[a] = leg.from[a] + leg.dir[a] * d;
        }
        self.pause.park.leg = Some(leg);
        false
    }

    /// A refill's retraction: each plunger back towards the start of its fill, at half
    /// the step-rate limit; once all are there the count restarts (they already read 0).
    fn retract_plungers(&mut self) {
        let half = R::from_u32((self.machine.motion.max_steps_per_cycle / 2).max(1));
        let mut done = true;
        for (i, inlet) in self.machine.inlets.iter().enumerate() {
            let Some(sy) = inlet.syringe else { continue };
            let Some(v) = self.plunger_vol.get_mut(i) else {
                continue;
            };
            let step = Vol::from_mm3(half / sy.steps_per_mm3);
            *v = if *v > step {
                done = false;
                *v - step
            } else if *v < Vol::ZERO - step {
                done = false;
                *v + step
            } else {
                Vol::ZERO
            };
        }
        if done {
            self.pause.park.refilling = false;
            self.pause.park.refills += 1;
        }
    }
}
