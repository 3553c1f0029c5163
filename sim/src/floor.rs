//! The section floor (issue 22): how near the physics lets any head come to the bead's
//! section on a stretch of a run, against the flow the stretch landed (the valves keyed to
//! volume make the flow whatever the head does), along the stretch's own path, within the
//! X/Y limit (the speed's change and the path's turn by their vector sum). A second-order
//! cone program, solved with `clarabel`; the executor's figures in the same measure beside
//! it. It stops at the path: a wider fillet is another path.
//!
//! The measure is the spread (highest less lowest) of the head's lead on the paste over
//! every `window_mm` of bead, relative to it: the most the section over any part of that
//! bead can be off, in total. The section over each whole window alone is blind to a lead
//! that swings back and forth once a window, and a program minimising it finds exactly
//! that: a step of the flow "held" to 0.5 % where a centred ramp is off 2 %. Over the
//! spread a step costs what `Machine::section_bound` says, `dv^2 / (8 a W)` (tested).

use crate::{run_paused, Job, PausePlan, RunOptions, SimError};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use dollop::config::Config;
use std::f64::consts::{PI, TAU};

/// A stretch of a run: the commanded head position and the paste landed, each control cycle.
#[derive(Clone, Debug, Default)]
pub struct Stretch {
    /// Control period, s.
    pub dt: f64,
    /// Head position (X, Y), mm, one a cycle.
    pub pos: Vec<[f64; 2]>,
    /// Paste landed in each cycle, mm^3.
    pub landed: Vec<f64>,
    /// Bead section, mm^2.
    pub area: f64,
}

/// What the floor is taken under.
#[derive(Clone, Copy, Debug)]
pub struct FloorOptions {
    /// The X/Y acceleration limit, mm/s^2 (the vector sum of the speed's change and the
    /// path's turn).
    pub accel: f64,
    /// Length of bead each section is taken over, mm.
    pub window_mm: f64,
    /// A window whose path turns by more than this is a turn's, degrees.
    pub turn_deg: f64,
    /// Cycles a step of the program takes (0.5 ms at 10 kHz: 5).
    pub cycles_per_step: usize,
    /// The most the head may lead or lag the paste, mm; None: as far as the executor did
    /// on the stretch (at least `LAG_MM`).
    pub lag_mm: Option<f64>,
}

impl Default for FloorOptions {
    fn default() -> Self {
        FloorOptions {
            accel: 1000.0,
            window_mm: 0.2,
            turn_deg: 10.0,
            cycles_per_step: 5,
            lag_mm: None,
        }
    }
}

/// The floor and the executor's figures on the same stretch: spreads of the lead over a
/// window, relative to it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Floor {
    /// The least worst over every window, turns' too, the head never further from the
    /// paste than the executor's was (or `LAG_MM`): a lead or lag may drift slowly over
    /// many windows, each off by little, so without that bound the floor is the
    /// boundaries' loss. None where no profile within the limit meets it.
    pub all: Option<f64>,
    /// The least worst over straight windows, each turn's window no worse than the
    /// executor's there (nor than `all`; `TURN_ROOM` more) and the same bound on the lag:
    /// the trade the executor made, bettered on the straights without worsening a turn or
    /// the boundaries.
    pub straight: Option<f64>,
    /// The executor's worst over every window, over straight ones, and its largest lag
    /// behind (or lead on) the paste, mm.
    pub executor_all: f64,
    pub executor_straight: f64,
    pub executor_lag_mm: f64,
}

/// Why there is no floor.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FloorError {
    /// Fewer steps than the windows need.
    #[error("the stretch is too short: {0} steps of the program, at least 8 needed")]
    TooShort(usize),
    /// Positions and volumes that do not pair up or are not finite.
    #[error("the stretch is not finite or its section or period is not positive")]
    Invalid,
    /// The program could not be set up or solved, or its solution did not replay.
    #[error("the solver found no floor: {0}")]
    Solver(String),
}

/// Lag on the paste the floor always allows, mm: a head that rode the flow itself had
/// none, and held to none the program has no room at all.
pub const LAG_MM: f64 = 0.002;

/// Room over the executor's spread a turn's window gets in the straight floor, relative.
const TURN_ROOM: f64 = 1e-3;

/// The stretch resampled: steps of the program.
struct Steps {
    dt: f64,
    /// Paste speed (mm/s) and the head's, in each step.
    vf: Vec<f64>,
    ve: Vec<f64>,
    /// The head's lead on the paste at each step's start, mm (n + 1).
    lead: Vec<f64>,
    /// The path's curvature in each step, 1/mm.
    kappa: Vec<f64>,
    /// Windows: first and last step boundary, and whether the path turns over it.
    windows: Vec<(usize, usize, bool)>,
}

fn steps(s: &Stretch, o: &FloorOptions) -> Result<Steps, FloorError> {
    let m = o.cycles_per_step.max(1);
    let ok = s.dt > 0.0
        && s.area > 0.0
        && s.pos.len() == s.landed.len() + 1
        && s.pos.iter().all(|p| p[0].is_finite() && p[1].is_finite())
        && s.landed.iter().all(|v| v.is_finite());
    if !ok {
        return Err(FloorError::Invalid);
    }
    let n = s.landed.len() / m;
    if n < 8 {
        return Err(FloorError::TooShort(n));
    }
    let dt = s.dt * m as f64;
    let vf: Vec<f64> = (0..n)
        .map(|k| s.landed[k * m..(k + 1) * m].iter().sum::<f64>() / s.area / dt)
        .collect();
    let p: Vec<[f64; 2]> = (0..=n).map(|k| s.pos[k * m]).collect();
    let ds: Vec<f64> = (0..n)
        .map(|k| (p[k + 1][0] - p[k][0]).hypot(p[k + 1][1] - p[k][1]))
        .collect();
    let ve: Vec<f64> = ds.iter().map(|d| d / dt).collect();
    let mut paste = vec![0.0; n + 1];
    let mut head = vec![0.0; n + 1];
    for k in 0..n {
        paste[k + 1] = paste[k] + vf[k] * dt;
        head[k + 1] = head[k] + ds[k];
    }
    let lead: Vec<f64> = (0..=n).map(|k| head[k] - paste[k]).collect();
    // Heading per step, unwrapped; steps the head barely moves keep the last.
    let mut ang = vec![0.0; n];
    let mut last: Option<f64> = None;
    for k in 0..n {
        let a = if ds[k] > 1e-7 {
            let raw = (p[k + 1][1] - p[k][1]).atan2(p[k + 1][0] - p[k][0]);
            // The turn from the last heading, taken within half a turn either way.
            last.map_or(raw, |l| l + (raw - l + PI).rem_euclid(TAU) - PI)
        } else {
            last.unwrap_or(0.0)
        };
        ang[k] = a;
        last = Some(a);
    }
    let mut kappa = vec![0.0; n];
    for k in 1..n.saturating_sub(1) {
        let len = ds[k - 1] + ds[k + 1];
        if len > 1e-6 {
            kappa[k] = (ang[k + 1] - ang[k - 1]).abs() / len;
        }
    }
    let turn = o.turn_deg.to_radians();
    let mut windows = Vec::new();
    let mut j = 0;
    for k in 0..=n {
        while j <= n && paste[j] < paste[k] + o.window_mm {
            j += 1;
        }
        if j > n {
            break;
        }
        let seg = &ang[k.min(n - 1)..j.min(n).max(k.min(n - 1) + 1)];
        windows.push((k, j, spread(seg) > turn));
    }
    Ok(Steps {
        dt,
        vf,
        ve,
        lead,
        kappa,
        windows,
    })
}

/// Highest less lowest of `x` (a window's lead, or its headings).
fn spread(x: &[f64]) -> f64 {
    let hi = x.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let lo = x.iter().cloned().fold(f64::INFINITY, f64::min);
    hi - lo
}

/// Rows of `A x + s = b` by cone, gathered as triplets.
#[derive(Default)]
struct Rows {
    trip: Vec<(usize, usize, f64)>,
    b: Vec<f64>,
}

impl Rows {
    fn row(&mut self, terms: &[(usize, f64)], b: f64) {
        let r = self.b.len();
        for &(c, v) in terms {
            self.trip.push((r, c, v));
        }
        self.b.push(b);
    }
}

/// The least worst section error over the windows, the head's lead on the paste within
/// `lag` mm; `turn_caps` bounds each turn's window (relative, by window) instead of
/// counting it.
fn solve(
    st: &Steps,
    o: &FloorOptions,
    lag: f64,
    turn_caps: Option<&[f64]>,
) -> Result<f64, FloorError> {
    let n = st.vf.len();
    let dt = st.dt;
    let a = o.accel;
    let w_um = o.window_mm * 1000.0;
    // Variables: v (n), E in um (n + 1), w for turning steps, eps.
    let turning: Vec<usize> = (0..n - 1)
        .filter(|&k| 0.5 * (st.kappa[k] + st.kappa[k + 1]) > 1e-3)
        .collect();
    let iv = |k: usize| k;
    let ie = |k: usize| n + k;
    let iw0 = 2 * n + 1;
    // Each window's highest and lowest lead, then eps.
    let ihi = iw0 + turning.len();
    let ilo = ihi + st.windows.len();
    let ieps = ilo + st.windows.len();
    let nv = ieps + 1;
    let mut zero = Rows::default();
    for k in 0..n {
        // E[k+1] - E[k] - 1000 dt v[k] = -1000 dt vf[k]
        zero.row(
            &[(ie(k + 1), 1.0), (ie(k), -1.0), (iv(k), -1000.0 * dt)],
            -1000.0 * dt * st.vf[k],
        );
    }
    zero.row(&[(ie(0), 1.0)], 0.0);
    zero.row(&[(iv(0), 1.0)], st.ve[0]);
    let mut nonneg = Rows::default();
    for (i, &(k, j, turn)) in st.windows.iter().enumerate() {
        let (hi, lo) = (ihi + i, ilo + i);
        for e in k..=j {
            nonneg.row(&[(ie(e), 1.0), (hi, -1.0)], 0.0);
            nonneg.row(&[(lo, 1.0), (ie(e), -1.0)], 0.0);
        }
        match (turn, turn_caps) {
            (true, Some(caps)) => nonneg.row(&[(hi, 1.0), (lo, -1.0)], caps[i] * w_um),
            _ => nonneg.row(&[(hi, 1.0), (lo, -1.0), (ieps, -w_um)], 0.0),
        }
    }
    for k in 1..=n {
        nonneg.row(&[(ie(k), 1.0)], lag * 1000.0);
        nonneg.row(&[(ie(k), -1.0)], lag * 1000.0);
    }
    let mut is_turning = vec![false; n];
    for &k in &turning {
        is_turning[k] = true;
    }
    // Off the turns, |v[k+1] - v[k]| <= a dt (the turns' steps have their cones).
    for (k, _) in is_turning.iter().enumerate().take(n - 1).filter(|t| !*t.1) {
        nonneg.row(&[(iv(k + 1), 1.0), (iv(k), -1.0)], a * dt);
        nonneg.row(&[(iv(k + 1), -1.0), (iv(k), 1.0)], a * dt);
    }
    for k in 0..n {
        nonneg.row(&[(iv(k), -1.0)], 0.0);
    }
    let mut soc = Rows::default();
    for (i, &k) in turning.iter().enumerate() {
        let w = iw0 + i;
        let kap = 0.5 * (st.kappa[k] + st.kappa[k + 1]);
        // w >= vm^2, vm the step's mean speed: ||(2 vm, w - 1)|| <= w + 1.
        soc.row(&[(w, -1.0)], 1.0);
        soc.row(&[(iv(k), -1.0), (iv(k + 1), -1.0)], 0.0);
        soc.row(&[(w, -1.0)], -1.0);
        // ||(dv / dt, kappa w)|| <= a, scaled by a.
        soc.row(&[], 1.0);
        soc.row(
            &[(iv(k + 1), -1.0 / (dt * a)), (iv(k), 1.0 / (dt * a))],
            0.0,
        );
        soc.row(&[(w, -kap / a)], 0.0);
    }
    let (nz, nn, ns) = (zero.b.len(), nonneg.b.len(), soc.b.len());
    let mut trip = zero.trip;
    trip.extend(nonneg.trip.into_iter().map(|(r, c, v)| (r + nz, c, v)));
    trip.extend(soc.trip.into_iter().map(|(r, c, v)| (r + nz + nn, c, v)));
    let mut b = zero.b;
    b.extend(nonneg.b);
    b.extend(soc.b);
    let m = nz + nn + ns;
    let a_mat = csc(m, nv, trip);
    let p = CscMatrix::<f64>::zeros((nv, nv));
    let mut q = vec![0.0; nv];
    q[ieps] = 1.0;
    let mut cones = vec![
        SupportedConeT::ZeroConeT(nz),
        SupportedConeT::NonnegativeConeT(nn),
    ];
    cones.extend((0..2 * turning.len()).map(|_| SupportedConeT::SecondOrderConeT(3)));
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .max_iter(200)
        .build()
        .map_err(|e| FloorError::Solver(e.to_string()))?;
    let mut solver = DefaultSolver::new(&p, &q, &a_mat, &b, &cones, settings)
        .map_err(|e| FloorError::Solver(format!("{e:?}")))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => check(
            st,
            o,
            &solver.solution.x[..n],
            solver.solution.x[ieps],
            turn_caps,
        ),
        s => Err(FloorError::Solver(format!("{s:?}"))),
    }
}

/// The solver's head speeds `v` replayed: each step within the limit (the speed's change
/// and the path's turn by their vector sum) and the windows it counted within `eps`, to
/// the solver's tolerance; a profile that is not is no floor.
fn check(
    st: &Steps,
    o: &FloorOptions,
    v: &[f64],
    eps: f64,
    turn_caps: Option<&[f64]>,
) -> Result<f64, FloorError> {
    const SLACK: f64 = 1.01;
    let n = v.len();
    for k in 0..n - 1 {
        let at = (v[k + 1] - v[k]) / st.dt;
        let kap = 0.5 * (st.kappa[k] + st.kappa[k + 1]);
        let vm = 0.5 * (v[k] + v[k + 1]);
        let acc = at.hypot(vm * vm * kap);
        if acc.is_nan() || acc > o.accel * SLACK {
            return Err(FloorError::Solver(format!(
                "the solution's step {k} takes {acc:.0} mm/s^2"
            )));
        }
    }
    let mut lead = vec![0.0; n + 1];
    for k in 0..n {
        lead[k + 1] = lead[k] + (v[k] - st.vf[k]) * st.dt;
    }
    let mut worst = 0.0f64;
    for &(k, j, turn) in &st.windows {
        if turn && turn_caps.is_some() {
            continue;
        }
        worst = worst.max(spread(&lead[k..=j]) / o.window_mm);
    }
    if (worst - eps).abs() > 1e-4 + 1e-3 * eps {
        return Err(FloorError::Solver(format!(
            "the solution's windows are off {worst:.5}, not {eps:.5}"
        )));
    }
    Ok(worst)
}

/// A CSC matrix from triplets (duplicates summed).
fn csc(m: usize, n: usize, mut trip: Vec<(usize, usize, f64)>) -> CscMatrix<f64> {
    trip.sort_by_key(|x| (x.1, x.0));
    let mut colptr = vec![0usize; n + 1];
    let mut rowval = Vec::with_capacity(trip.len());
    let mut nzval: Vec<f64> = Vec::with_capacity(trip.len());
    let mut last: Option<(usize, usize)> = None;
    for (r, c, v) in trip {
        if last == Some((r, c)) {
            *nzval.last_mut().expect("a value before") += v;
            continue;
        }
        rowval.push(r);
        nzval.push(v);
        colptr[c + 1] += 1;
        last = Some((r, c));
    }
    for c in 0..n {
        colptr[c + 1] += colptr[c];
    }
    CscMatrix::new(m, n, colptr, rowval, nzval)
}

/// The floor of `stretch` under `o`, and the executor's figures beside it.
pub fn floor(stretch: &Stretch, o: &FloorOptions) -> Result<Floor, FloorError> {
    let st = steps(stretch, o)?;
    let w = o.window_mm;
    // The executor's spread of its lead over each window, relative.
    let spread: Vec<f64> = st
        .windows
        .iter()
        .map(|&(k, j, _)| spread(&st.lead[k..=j]) / w)
        .collect();
    let worst = |turns: bool| {
        st.windows
            .iter()
            .zip(&spread)
            .filter(|(win, _)| win.2 == turns)
            .fold(0.0f64, |m, (_, e)| m.max(*e))
    };
    let (ex_straight, ex_turn) = (worst(false), worst(true));
    let ex_all = ex_straight.max(ex_turn);
    let lag = st.lead.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let cap = o.lag_mm.unwrap_or(lag.max(LAG_MM));
    let all = solve(&st, o, cap, None).ok();
    // Each turn's window no worse than the executor's there (nor than `all`, which no
    // profile beats), with a little room for the executor's own rounding of the limit.
    let straight = all.and_then(|all| {
        let caps: Vec<f64> = spread.iter().map(|&e| e.max(all) + TURN_ROOM).collect();
        solve(&st, o, cap, Some(&caps)).ok()
    });
    Ok(Floor {
        all,
        straight,
        executor_all: ex_all,
        executor_straight: ex_straight,
        executor_lag_mm: lag,
    })
}

/// The stretch of a run of `job` on `config` (`opts`, `pauses` as the run that measured
/// it) from `before` cycles ahead of cycle `at` to `after` cycles past it, cut to the
/// printing around `at` (a bead's end or a travel is no bead to lay), run again up to
/// there: the runs are deterministic, and a whole job's cycles are too many to keep.
pub fn stretch_at(
    config: &Config,
    job: &Job,
    opts: &RunOptions,
    pauses: &PausePlan,
    at: u64,
    before: u64,
    after: u64,
) -> Result<Stretch, SimError> {
    let machine = config
        .validate::<f64, { dollop::DEFAULT_INLETS }>()
        .map_err(SimError::Config)?;
    let dt = machine.period_us as f64 * 1e-6;
    let first = at.saturating_sub(before);
    let last = at.saturating_add(after);
    // Each cycle's head position, paste landed and whether it printed.
    let mut cycles: Vec<([f64; 2], f64, bool)> = Vec::new();
    let mut cycle = 0u64;
    let opts = RunOptions {
        // A cycle past the stretch ends the run (as a timeout, expected).
        max_time_s: (last as f64 + 1.5) * dt,
        ..*opts
    };
    let run = run_paused::<f32>(config, config, job, &opts, pauses, |c| {
        if (first..=last).contains(&cycle) {
            let p = c.report.position;
            let printing = c.report.state == dollop::RunState::Printing;
            cycles.push(([p[0] as f64, p[1] as f64], c.landed_volume, printing));
        }
        cycle += 1;
    });
    let area = match run {
        Ok(r) => r.bead_area,
        Err(SimError::Timeout(_)) => machine.bead_area,
        Err(e) => return Err(e),
    };
    let mid = ((at - first) as usize).min(cycles.len().saturating_sub(1));
    let (mut lo, mut hi) = (mid, mid);
    while lo > 0 && cycles[lo - 1].2 {
        lo -= 1;
    }
    while hi + 1 < cycles.len() && cycles[hi + 1].2 {
        hi += 1;
    }
    let part = cycles.get(lo..=hi).unwrap_or(&[]);
    Ok(Stretch {
        dt,
        pos: part.iter().map(|c| c.0).collect(),
        landed: part.iter().skip(1).map(|c| c.1).collect(),
        area,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 1e-4;
    const AREA: f64 = 0.5;

    /// A stretch along `path(s)` (a point at path length `s`, mm) whose paste speed is
    /// `flow(t)` (mm/s), the head at the paste's own speed along the path.
    fn along(n: usize, flow: impl Fn(f64) -> f64, path: impl Fn(f64) -> [f64; 2]) -> Stretch {
        let mut s = Stretch {
            dt: DT,
            area: AREA,
            ..Default::default()
        };
        let mut at = 0.0;
        s.pos.push(path(0.0));
        for k in 0..n {
            let v = flow(k as f64 * DT);
            at += v * DT;
            s.landed.push(v * DT * AREA);
            s.pos.push(path(at));
        }
        s
    }

    fn straight(s: f64) -> [f64; 2] {
        [s, 0.0]
    }

    /// A step of the flow from `v1` to `v2` on a straight, the head ramping at `a`
    /// centred on it: that head is off by `dv^2 / (8 a W)` (`Machine::section_bound`) and
    /// leads the paste by at most `dv^2 / (8 a)`. Held to that lead, no head does better
    /// than half of it (a slow drift of the lead before the step takes up to half the
    /// ramp's swing, in windows of its own) and the floor lies between.
    #[test]
    fn a_step_of_the_flow_on_a_straight_costs_the_centred_ramp() {
        let (v1, v2, a, t0) = (10.0, 14.0, 500.0, 0.12);
        let half = (v2 - v1) / a / 2.0;
        let head = move |t: f64| {
            if t < t0 - half {
                v1
            } else if t < t0 + half {
                v1 + a * (t - (t0 - half))
            } else {
                v2
            }
        };
        let mut s = along(2400, |t| if t < t0 { v1 } else { v2 }, straight);
        let mut x = 0.0;
        for k in 0..2400 {
            x += head((k as f64 + 0.5) * DT) * DT;
            s.pos[k + 1] = [x, 0.0];
        }
        let o = FloorOptions {
            accel: a,
            ..Default::default()
        };
        let f = floor(&s, &o).expect("a floor");
        let closed = (v2 - v1) * (v2 - v1) / (8.0 * a * o.window_mm);
        let all = f.all.expect("a floor over every window");
        assert!(
            (f.executor_all - closed).abs() < 0.1 * closed,
            "the centred ramp is off {:.5}, the closed form {closed:.5}",
            f.executor_all
        );
        assert!(
            all <= f.executor_all + 1e-6 && all >= 0.97 * closed,
            "floor {all:.5}, the centred ramp's {:.5}",
            f.executor_all
        );
        assert!(f.straight.expect("a straight floor") <= all + 1e-6);
    }

    /// A flow faster than an arc allows: through its middle the head can go no faster
    /// than `sqrt(a r)`, so a window there is off by `1 - sqrt(a r) / v` however the
    /// speed is planned around it.
    #[test]
    fn an_arc_too_tight_for_the_flow_caps_the_head() {
        let (v, a, r) = (20.0, 500.0, 0.5);
        let arc = |s: f64| {
            if s < 2.0 {
                [s, 0.0]
            } else if s < 2.0 + std::f64::consts::PI * r {
                let th = (s - 2.0) / r;
                [2.0 + r * th.sin(), r - r * th.cos()]
            } else {
                [2.0 - (s - 2.0 - std::f64::consts::PI * r), 2.0 * r]
            }
        };
        let s = along(3000, |_| v, arc);
        let f = floor(
            &s,
            &FloorOptions {
                accel: a,
                lag_mm: Some(1.0),
                ..Default::default()
            },
        )
        .expect("a floor");
        let cap = 1.0 - (a * r).sqrt() / v;
        let all = f.all.expect("a floor over every window");
        assert!(
            all >= cap * 0.98 && all <= cap * 1.3,
            "floor {all:.4} against the arc's {cap:.4}"
        );
        // Held to the lag of a head that rode the flow (none), nothing within the limit
        // gets through the arc.
        let held = floor(
            &s,
            &FloorOptions {
                accel: a,
                ..Default::default()
            },
        )
        .expect("a stretch");
        assert_eq!(held.all, None);
    }

    #[test]
    fn bad_stretches_are_refused() {
        let mut s = along(100, |_| 10.0, straight);
        s.landed[3] = f64::NAN;
        assert_eq!(
            floor(&s, &FloorOptions::default()),
            Err(FloorError::Invalid)
        );
        let s = along(20, |_| 10.0, straight);
        assert_eq!(
            floor(&s, &FloorOptions::default()),
            Err(FloorError::TooShort(4))
        );
        let mut s = along(100, |_| 10.0, straight);
        s.pos.pop();
        assert_eq!(
            floor(&s, &FloorOptions::default()),
            Err(FloorError::Invalid)
        );
    }
}
