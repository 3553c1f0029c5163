//! Pauses in a simulated run: when to request them and resume, and what each one did,
//! measured from the outputs and the plant as a printed part would show it (valves shut
//! on the pins, head at rest, the seam's deposit along the path). The runner feeds it
//! cycle by cycle; it neither drives the executor's physics nor knows the design.

use dollop::RunState;
use std::collections::VecDeque;

/// Pauses to request: each at a virtual time (s from the job's start), resumed a wait
/// after the head has come to rest.
#[derive(Clone, Debug, Default)]
pub struct PausePlan {
    /// (request time, wait after rest), s, in time order. A request falling while an
    /// earlier pause is still in effect is made right after that one's resume.
    pub requests: Vec<(f64, f64)>,
    /// Absolute resume times (s), by request: where given, the pause is resumed at the
    /// first cycle at or after it once the head rests, instead of a wait after the rest
    /// (to replay a board's pause, as the firmware-in-the-loop check does).
    pub resume_at: Vec<f64>,
    /// Park each pause (`Executor::park`): lift and move to the park position once at
    /// rest, back before the flow restarts.
    pub park: bool,
    /// On a syringe machine, refill (`Executor::refill`) at each park position.
    pub refill: bool,
}

impl PausePlan {
    /// Every time in `at_s` with the same wait.
    pub fn uniform(at_s: &[f64], wait_s: f64) -> Self {
        let mut requests: Vec<(f64, f64)> = at_s.iter().map(|&t| (t, wait_s)).collect();
        requests.sort_by(|a, b| a.0.total_cmp(&b.0));
        PausePlan {
            requests,
            ..Default::default()
        }
    }
}

/// One pause as it happened.
#[derive(Clone, Debug, Default)]
pub struct PauseRecord {
    /// Virtual time of the request, s.
    pub t_request: f64,
    /// When every valve output was shut (the pins), s; None if never.
    pub t_shut: Option<f64>,
    /// When the head (the outputs) came to rest: the last cycle it moved faster than the
    /// stop threshold `q_stop / S`, s.
    pub t_rest: Option<f64>,
    /// When it was resumed, s.
    pub t_resume: Option<f64>,
    /// Print path (plan volume / S) at the request and at the pause point, mm.
    pub s_request_mm: f64,
    /// See `s_request_mm`.
    pub s_point_mm: f64,
    /// Head position (outputs) at rest, mm.
    pub point_xy: [f64; 2],
    /// The pause fell at a bead's end (or between beads), not mid-bead.
    pub at_bead_end: bool,
    /// Cycles from the request to the executor's decision to shut the valves (plan).
    pub plan_shut_cycles: Option<u64>,
    /// Plant (or model) flow at the request and the largest once the head was at rest,
    /// mm^3/s.
    pub q_print: f64,
    /// See `q_print`.
    pub q_rested_max: f64,
    /// Seam: longest stretch of path within 0.5 mm of the pause point on which less than
    /// half a bead section landed, mm.
    pub seam_gap_mm: f64,
    /// Seam: smallest and largest section over 0.2 mm of path within 1 mm of the pause
    /// point, as a fraction of S.
    pub seam_section: (f64, f64),
    /// The seam was measured (mid-bead pause, 1 mm of bead after the resume).
    pub seam_measured: bool,
    /// A parked pause's excursion, as the outputs made it.
    pub park: Option<ParkRecord>,
}

/// A parked pause's excursion from the pause point and back (outputs).
#[derive(Clone, Debug, Default)]
pub struct ParkRecord {
    /// When the head left the pause point, s.
    pub t_left: f64,
    /// When the plan reached the park position, s.
    pub t_parked: Option<f64>,
    /// When the head was back on the pause point, s.
    pub t_back: Option<f64>,
    /// Highest Z above the pause point, mm.
    pub lift_mm: f64,
    /// The XY farthest from the pause point the head reached, mm.
    pub far_xy: [f64; 2],
    /// A refill was asked at the park position and done.
    pub refilled: bool,
    /// Largest plunger retraction of the refill, steps (E axes).
    pub retract_steps: i64,
}

impl PauseRecord {
    /// Request to valves shut (pins), s.
    pub fn shut_latency(&self) -> Option<f64> {
        self.t_shut.map(|t| t - self.t_request)
    }
    /// Request to head at rest, s.
    pub fn rest_latency(&self) -> Option<f64> {
        self.t_rest.map(|t| t - self.t_request)
    }
    /// Path from the head at the request to the pause point, mm.
    pub fn distance_mm(&self) -> f64 {
        self.s_point_mm - self.s_request_mm
    }
}

/// Bins of the seam's deposit profile, mm.
const BIN_MM: f64 = 0.01;
/// Path kept before a request, and measured each side of the pause point, mm.
const SEAM_MM: f64 = 1.0;
/// Section window at the seam, mm.
const SECTION_MM: f64 = dollop::config::SECTION_WINDOW_MM;

/// The runner's pause bookkeeping.
#[derive(Debug)]
pub(crate) struct Pauser {
    plan: VecDeque<(f64, f64, Option<f64>)>,
    bead_area: f64,
    /// Head speed below which it counts as at rest, mm/s.
    v_rest: f64,
    /// Output path length so far, mm, and the recent deposit (s0, s1, volume, on a bead).
    s: f64,
    last_pos: Option<[f64; 2]>,
    recent: VecDeque<(f64, f64, f64, bool)>,
    active: Option<Active>,
    pub records: Vec<PauseRecord>,
}

#[derive(Debug)]
struct Active {
    rec: PauseRecord,
    wait: f64,
    resume_at: Option<f64>,
    /// Output path length at rest.
    s_rest: Option<f64>,
    /// Stage: waiting for rest, waiting to resume, resumed (measuring the seam).
    resumed: bool,
}

/// What the runner should do to the executor this cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Action {
    None,
    Pause,
    Resume,
}

/// What the pauser sees of one cycle.
pub(crate) struct Seen {
    pub t: f64,
    pub state: RunState,
    pub pos: [f64; 2],
    pub plan_mm: f64,
    pub valves: u32,
    pub landed: f64,
    pub q_plant: f64,
    /// A park has the head off the pause point: `pos` then stays the pause point, and
    /// `raw` is where the outputs are.
    pub off_point: bool,
    pub raw: [f64; 3],
    /// Z of the pause point (outputs), mm.
    pub point_z: f64,
    /// The plan is at the park position.
    pub parked: bool,
}

impl Pauser {
    pub fn new(plan: &PausePlan, bead_area: f64, v_rest: f64) -> Self {
        Pauser {
            plan: plan
                .requests
                .iter()
                .enumerate()
                .map(|(k, &(t, w))| (t, w, plan.resume_at.get(k).copied()))
                .collect(),
            bead_area,
            v_rest,
            s: 0.0,
            last_pos: None,
            recent: VecDeque::new(),
            active: None,
            records: Vec::new(),
        }
    }

    /// True while a pause is requested or in effect (not yet resumed).
    pub fn holding(&self) -> bool {
        self.active.as_ref().is_some_and(|a| !a.resumed)
    }

    /// Feeds a cycle's outcome; returns what to do before the next.
    pub fn cycle(&mut self, c: &Seen, dt: f64) -> Action {
        let ds = self.last_pos.map_or(0.0, |p| {
            ((c.pos[0] - p[0]).powi(2) + (c.pos[1] - p[1]).powi(2)).sqrt()
        });
        self.last_pos = Some(c.pos);
        let s0 = self.s;
        self.s += ds;
        // The bead proper: not a travel, nor the settling at a bead's end.
        let on_bead = matches!(
            c.state,
            RunState::Printing | RunState::Pausing | RunState::Paused
        );
        self.recent.push_back((s0, self.s, c.landed, on_bead));
        if self.active.is_none() {
            while self.recent.front().is_some_and(|r| r.1 < self.s - SEAM_MM) {
                self.recent.pop_front();
            }
        }
        let moving = ds > self.v_rest * dt;
        let mut action = Action::None;
        let (s_now, bead_area) = (self.s, self.bead_area);
        if let Some(a) = self.active.as_mut() {
            park_cycle(&mut a.rec, c);
            if a.rec.t_shut.is_none() && c.valves == 0 {
                a.rec.t_shut = Some(c.t);
            }
            if !a.resumed {
                let paused = c.state == RunState::Paused;
                if paused && a.rec.t_shut.is_some() {
                    if moving || a.s_rest.is_none() {
                        a.rec.t_rest = Some(c.t);
                        a.s_rest = Some(s_now);
                        a.rec.point_xy = c.pos;
                        a.rec.s_point_mm = c.plan_mm;
                        a.rec.q_rested_max = c.q_plant;
                    }
                    a.rec.q_rested_max = a.rec.q_rested_max.max(c.q_plant);
                    let due = match a.resume_at {
                        Some(at) => c.t >= at,
                        None => c.t >= a.rec.t_rest.unwrap_or(c.t) + a.wait,
                    };
                    if due {
                        a.resumed = true;
                        a.rec.t_resume = Some(c.t);
                        action = Action::Resume;
                    }
                } else if matches!(c.state, RunState::Done | RunState::Aborted) {
                    a.resumed = true;
                }
            } else if !c.off_point
                && (a.rec.at_bead_end
                    || a.s_rest.is_some_and(|r| s_now > r + SEAM_MM + SECTION_MM)
                    || matches!(c.state, RunState::Done | RunState::Aborted))
            {
                let mut a = self.active.take().expect("active");
                if !a.rec.at_bead_end {
                    if let Some(r) = a.s_rest {
                        seam(&self.recent, r, bead_area, &mut a.rec);
                    }
                }
                self.records.push(a.rec);
            }
        }
        if self.active.is_none() && self.plan.front().is_some_and(|p| c.t >= p.0) {
            let (_, wait, resume_at) = self.plan.pop_front().expect("front");
            if !matches!(
                c.state,
                RunState::Done | RunState::Aborted | RunState::Faulted | RunState::Idle
            ) {
                self.active = Some(Active {
                    rec: PauseRecord {
                        t_request: c.t,
                        s_request_mm: c.plan_mm,
                        q_print: c.q_plant,
                        ..Default::default()
                    },
                    wait,
                    resume_at,
                    s_rest: None,
                    resumed: false,
                });
                action = Action::Pause;
            }
        }
        action
    }

    /// What the executor says of the active pause: where it fell, when it shut.
    pub fn executor_says(&mut self, info: Option<dollop::executor::PauseInfo>) {
        if let (Some(a), Some(i)) = (self.active.as_mut(), info) {
            a.rec.at_bead_end = i.at_bead_end;
            a.rec.plan_shut_cycles = i.shut_cycle.map(|c| c.saturating_sub(i.requested_cycle));
        }
    }

    /// A refill at the active pause's park position retracted the plungers by up to
    /// `steps`.
    pub fn refilled(&mut self, steps: i64) {
        if let Some(p) = self.active.as_mut().and_then(|a| a.rec.park.as_mut()) {
            p.refilled = true;
            p.retract_steps = steps;
        }
    }

    /// The records, a pause still open at the run's end included.
    pub fn finish(mut self) -> Vec<PauseRecord> {
        if let Some(a) = self.active.take() {
            self.records.push(a.rec);
        }
        self.records
    }
}

/// A park's figures: the excursion from the pause point (`c.pos` holds it while off).
fn park_cycle(rec: &mut PauseRecord, c: &Seen) {
    if !c.off_point {
        if let Some(p) = rec.park.as_mut() {
            p.t_back.get_or_insert(c.t);
        }
        return;
    }
    let p = rec.park.get_or_insert_with(|| ParkRecord {
        t_left: c.t,
        far_xy: c.pos,
        ..Default::default()
    });
    if p.t_back.is_some() {
        return;
    }
    let d = |xy: [f64; 2]| (xy[0] - c.pos[0]).hypot(xy[1] - c.pos[1]);
    if d([c.raw[0], c.raw[1]]) > d(p.far_xy) {
        p.far_xy = [c.raw[0], c.raw[1]];
    }
    p.lift_mm = p.lift_mm.max(c.raw[2] - c.point_z);
    if c.parked {
        p.t_parked.get_or_insert(c.t);
    }
}

/// The seam figures from the deposit around output path length `s_rest`.
fn seam(
    recent: &VecDeque<(f64, f64, f64, bool)>,
    s_rest: f64,
    bead_area: f64,
    rec: &mut PauseRecord,
) {
    // The stretch of bead around the point: up to where the head was off the bead.
    let (mut lo, mut hi) = (s_rest - SEAM_MM, s_rest + SEAM_MM);
    for &(s0, s1, _, on) in recent {
        if !on && s1 > s0 {
            if s1 <= s_rest {
                lo = lo.max(s1);
            } else if s0 >= s_rest {
                hi = hi.min(s0);
            }
        }
    }
    let n = (((hi - lo) / BIN_MM).floor() as usize).max(1);
    let mut bins = vec![0.0f64; n];
    let bin_of = |s: f64| ((s - lo) / BIN_MM).floor();
    for &(s0, s1, v, on) in recent {
        if v <= 0.0 || !on {
            continue;
        }
        if s1 - s0 < 1e-9 {
            let b = bin_of(s1);
            if b >= 0.0 && (b as usize) < n {
                bins[b as usize] += v;
            }
            continue;
        }
        // Spread over the stretch the head covered this cycle.
        let (b0, b1) = (bin_of(s0).max(0.0), bin_of(s1).min(n as f64 - 1.0));
        let mut b = b0;
        while b <= b1 {
            let (a, z) = (lo + b * BIN_MM, lo + (b + 1.0) * BIN_MM);
            let overlap = (z.min(s1) - a.max(s0)).max(0.0);
            bins[b as usize] += v * overlap / (s1 - s0);
            b += 1.0;
        }
    }
    let full = bead_area * BIN_MM;
    // Gap within 0.5 mm each side of the point.
    let at = ((s_rest - lo) / BIN_MM) as usize;
    let half = (0.5 / BIN_MM) as usize;
    let (g0, g1) = (at.saturating_sub(half), (at + half).min(n));
    let mut run = 0usize;
    let mut longest = 0usize;
    for &v in &bins[g0..g1] {
        if v < 0.5 * full {
            run += 1;
            longest = longest.max(run);
        } else {
            run = 0;
        }
    }
    rec.seam_gap_mm = longest as f64 * BIN_MM;
    let w = (SECTION_MM / BIN_MM).round() as usize;
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    for win in bins.windows(w) {
        let r = win.iter().sum::<f64>() / (bead_area * SECTION_MM);
        range = (range.0.min(r), range.1.max(r));
    }
    // Less than a window of bead around the point: nothing to measure the section on.
    rec.seam_section = if range.0.is_finite() {
        range
    } else {
        (1.0, 1.0)
    };
    rec.seam_measured = true;
}
