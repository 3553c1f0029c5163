//! Fits a sampled executor run (`gcode_step::Step`s) to a firmware's acceleration limit
//! where the executor changes speed at once (a valve whose flow starts, stops or changes
//! at once, as ideal valves do): speed jumps inside a bead are re-centred so that the
//! firmware's ramp is half before and half after the change, and beads that start or end
//! at speed get a short run-up or run-out off the bead. Where the executor's speed changes
//! gradually (real valves), nothing changes. Stops at reshaping moves: writing them is
//! `gcode_dialect`'s.

use super::gcode_step::Step;

/// Shortest speed ramp worth re-centring, mm.
const JUMP_MIN_MM: f64 = 0.004;

/// Shortest piece a move is cut into, mm: coordinates are written to 0.1 um, so a piece
/// this long points within 0.05 rad of its true direction, which a junction-deviation
/// planner takes at speed.
const MIN_PIECE_MM: f64 = 0.002;

/// Shortest run-up or run-out worth writing, mm.
const RAMP_MIN_MM: f64 = 0.002;

/// Acceleration a firmware allows along unit direction `u`, mm/s^2.
fn accel_along(u: [f64; 3], accel: [f64; 3]) -> f64 {
    u.iter()
        .zip(accel)
        .filter(|(c, _)| c.abs() > 1e-12)
        .map(|(c, a)| a / c.abs())
        .fold(f64::INFINITY, f64::min)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(d: [f64; 3]) -> f64 {
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

fn lerp(a: [f64; 3], b: [f64; 3], f: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * f,
        a[1] + (b[1] - a[1]) * f,
        a[2] + (b[2] - a[2]) * f,
    ]
}

/// The head's position before each step, and after the last.
fn positions(steps: &[Step], start: [f64; 3]) -> Vec<[f64; 3]> {
    let mut at = Vec::with_capacity(steps.len() + 1);
    let mut p = start;
    for st in steps {
        at.push(p);
        if let Step::Move { to, .. } = st {
            p = *to;
        }
    }
    at.push(p);
    at
}

/// Distance a speed change between `lo` and `hi` must be moved (earlier when speeding up,
/// later when slowing down) for a firmware ramping at `a` to be half-way through its ramp,
/// in time, where the executor's speed jumps, mm: the flow jumps there, so the paste the
/// head leaves short before the jump (`dv^2 / 8a` of bead) equals what it leaves over
/// after, and no 0.2 mm of bead holds more than that of either. The ramp lasts
/// `T = dv / a`; in its half on the low side the head covers `T/2 (lo + dv/4)`.
fn centring_shift(lo: f64, hi: f64, a: f64) -> f64 {
    let dv = hi - lo;
    (dv / (2.0 * a) * (lo + 0.25 * dv)).max(0.0)
}

/// Where the executor's speed jumps between two print moves (only valve changes between),
/// a firmware ramps over `|v2^2 - v1^2| / 2a` after the junction (speeding up) or before
/// it (slowing down), and the bead is thick or thin over the whole ramp. Moving the speed
/// change by `centring_shift` centres the ramp on the jump: thin on one side, thick on
/// the other, each a quarter of what one-sided ramp leaves (the head arrives a fraction of
/// a millisecond early, which nothing keyed to the path notices).
pub fn centre_jumps(steps: &[Step], start: [f64; 3], accel: [f64; 3]) -> Vec<Step> {
    let at = positions(steps, start);
    // Chains of print moves with only valve changes between; along each, its path length.
    let mut out = Vec::with_capacity(steps.len() + 16);
    let mut k = 0;
    while k < steps.len() {
        if !matches!(steps[k], Step::Move { travel: false, .. }) {
            out.push(steps[k]);
            k += 1;
            continue;
        }
        // The chain from k: moves and the valve changes between them.
        let mut end = k;
        let mut j = k;
        while j < steps.len() {
            match steps[j] {
                Step::Move { travel: false, .. } => {
                    end = j;
                    j += 1;
                }
                Step::Valves(_) => j += 1,
                _ => break,
            }
        }
        let chain = &steps[k..=end];
        // (index in chain, start s, end s, feed, unit direction) of each move.
        let mut moves = Vec::new();
        let mut s = 0.0;
        for (i, st) in chain.iter().enumerate() {
            if let Step::Move { to, v, .. } = *st {
                let len = norm(sub(to, at[k + i]));
                moves.push((i, s, s + len, v, len));
                s += len;
            }
        }
        let faster = faster_ranges(chain, &at[k..], &moves, accel);
        // Ranges by their start; a move looks only at those that can reach it, so a
        // layer-long chain costs its length, not its square.
        let mut first = 0usize;
        let mut mi = 0usize;
        let mut cuts: Vec<f64> = Vec::new();
        for st in chain {
            let Step::Move { to, v, .. } = *st else {
                out.push(*st);
                continue;
            };
            let (i, s0, s1, _, len) = moves[mi];
            mi += 1;
            if len <= 0.0 {
                continue;
            }
            // Ranges ending before this move end before every later one too.
            while first < faster.len() && faster[first].1 < s0 {
                first += 1;
            }
            let near = faster[first..]
                .iter()
                .take_while(|r| r.0 <= s1)
                .filter(|r| r.1 >= s0);
            cuts.clear();
            cuts.extend(
                near.clone()
                    .flat_map(|r| [r.0, r.1])
                    .filter(|&c| c > s0 + MIN_PIECE_MM && c < s1 - MIN_PIECE_MM),
            );
            cuts.push(s1);
            cuts.sort_by(f64::total_cmp);
            let from = at[k + i];
            let mut a = s0;
            for &c in &cuts {
                if c <= a {
                    continue;
                }
                let mid = 0.5 * (a + c);
                let feed = near
                    .clone()
                    .filter(|r| r.0 <= mid && mid <= r.1)
                    .map(|r| r.2)
                    .fold(v, f64::max);
                let end_pt = if c >= s1 {
                    to
                } else {
                    lerp(from, to, (c - s0) / len)
                };
                out.push(Step::Move {
                    to: end_pt,
                    v: feed,
                    travel: false,
                });
                a = c;
            }
        }
        k = end + 1;
    }
    out
}

/// The stretches of a chain of print moves (`at`: each step's start point; `moves`: each
/// move's index in the chain, start and end path length, feed and length) that run at a
/// higher feed, centred on the jump between two moves' feeds: (from s, to s, feed),
/// sorted by their start.
fn faster_ranges(
    chain: &[Step],
    at: &[[f64; 3]],
    moves: &[(usize, f64, f64, f64, f64)],
    accel: [f64; 3],
) -> Vec<(f64, f64, f64)> {
    let mut faster: Vec<(f64, f64, f64)> = Vec::new();
    for w in moves.windows(2) {
        let (ia, _, sj, v1, la) = w[0];
        let (ib, _, _, v2, lb) = w[1];
        if la <= 0.0 || lb <= 0.0 || v1 <= 0.0 || v2 <= 0.0 {
            continue;
        }
        let m = if v2 > v1 { ib } else { ia };
        let Step::Move { to, .. } = chain[m] else {
            continue;
        };
        let u = sub(to, at[m]).map(|c| c / norm(sub(to, at[m])));
        let a = accel_along(u, accel);
        let (lo, hi) = (v1.min(v2), v1.max(v2));
        if (hi * hi - lo * lo) / (2.0 * a) < JUMP_MIN_MM {
            continue;
        }
        let shift = centring_shift(lo, hi, a);
        if v2 > v1 {
            faster.push((sj - shift, sj, v2));
        } else {
            faster.push((sj, sj + shift, v1));
        }
    }
    faster.sort_by(|x, y| x.0.total_cmp(&y.0));
    faster
}

/// The block before print move `k` that a run-up of `t_ramp` s may take over: its
/// valve changes and the dwells that fit in the time (leading dwells stay before it).
/// Returns its first step and the dwell time it holds.
fn block_before(steps: &[Step], k: usize, t_ramp: f64) -> (usize, f64) {
    let mut first = k;
    let mut stood = 0.0;
    while first > 0 {
        match steps[first - 1] {
            Step::Valves(_) => first -= 1,
            Step::Dwell(d) if stood + d <= t_ramp => {
                stood += d;
                first -= 1;
            }
            _ => break,
        }
    }
    // Leading dwells stay before the run-up.
    while first < k && matches!(steps[first], Step::Dwell(_)) {
        if let Step::Dwell(d) = steps[first] {
            stood -= d;
        }
        first += 1;
    }
    (first, stood)
}

/// The block after print move `k` that a run-out of `t_ramp` s may take over (as
/// [`block_before`], trailing dwells left after it). Returns its last step and the
/// dwell time it holds.
fn block_after(steps: &[Step], k: usize, t_ramp: f64) -> (usize, f64) {
    let mut last = k;
    let mut stood = 0.0;
    while last + 1 < steps.len() {
        match steps[last + 1] {
            Step::Valves(_) => last += 1,
            Step::Dwell(d) if stood + d <= t_ramp => {
                stood += d;
                last += 1;
            }
            _ => break,
        }
    }
    while last > k && matches!(steps[last], Step::Dwell(_)) {
        if let Step::Dwell(d) = steps[last] {
            stood -= d;
        }
        last -= 1;
    }
    (last, stood)
}

/// Writes a run-up to `bead_start` from `back` at feed `v` after `out`, taking its time
/// `t` from the dwells just before (latest first); a travel that ends at the bead's start
/// goes to the run-up's start instead.
fn write_run_up(out: &mut Vec<Step>, back: [f64; 3], bead_start: [f64; 3], v: f64, t: f64) {
    let mut need = t;
    let mut i = out.len();
    while need > 0.0 && i > 0 && matches!(out[i - 1], Step::Dwell(_)) {
        if let Step::Dwell(d) = &mut out[i - 1] {
            let take = d.min(need);
            *d -= take;
            need -= take;
        }
        i -= 1;
    }
    // A travel that ends at the bead's start (dwells after it aside) goes to the
    // run-up's start directly.
    let last_move = out.iter_mut().rev().find(|s| !matches!(s, Step::Dwell(_)));
    match last_move {
        Some(Step::Move {
            to, travel: true, ..
        }) if *to == bead_start => *to = back,
        _ => out.push(Step::Move {
            to: back,
            v,
            travel: true,
        }),
    }
    out.push(Step::Move {
        to: bead_start,
        v,
        travel: true,
    });
}

/// Where the executor starts a bead at speed (a valve whose flow starts at once), a
/// firmware needs `v^2 / 2a` to get to that speed: the head runs up to the bead's start
/// from that far back along it, with the valve changes of the last `v / a` seconds before
/// the start made as it arrives (at most that much late); where a bead ends at speed it
/// runs out as far past the end, the valve changes of the first `v / a` seconds after
/// made at the end. Both are `G0` at the bead's speed and take their time from the
/// executor's standing there where it stood.
pub fn run_ups(steps: &[Step], start: [f64; 3], accel: [f64; 3]) -> Vec<Step> {
    let n = steps.len();
    let at = positions(steps, start);
    let moves: Vec<usize> = (0..n)
        .filter(|&k| matches!(steps[k], Step::Move { .. }))
        .collect();
    let is_print = |k: usize| matches!(steps[k], Step::Move { travel: false, .. });
    let rests_between =
        |a: usize, b: usize| steps[a + 1..b].iter().any(|s| matches!(s, Step::Dwell(_)));
    // Run-ups: (first step of the block moved behind it, move, back point, feed, time);
    // run-outs: (move, last step of the block moved before it, past point, feed, time).
    let mut ups: Vec<(usize, usize, [f64; 3], f64, f64)> = Vec::new();
    let mut outs: Vec<(usize, usize, [f64; 3], f64, f64)> = Vec::new();
    for (j, &k) in moves.iter().enumerate() {
        if !is_print(k) {
            continue;
        }
        let Step::Move { to, v, .. } = steps[k] else {
            continue;
        };
        let from = at[k];
        let len = norm(sub(to, from));
        if len <= 0.0 {
            continue;
        }
        let u = sub(to, from).map(|c| c / len);
        let a = accel_along(u, accel);
        let dr = v * v / (2.0 * a);
        let t_ramp = v / a;
        if dr < RAMP_MIN_MM {
            continue;
        }
        let from_rest = match j.checked_sub(1).map(|i| moves[i]) {
            None => true,
            Some(prev) => !is_print(prev) || rests_between(prev, k),
        };
        if from_rest {
            let (first, stood) = block_before(steps, k, t_ramp);
            let back = lerp(from, to, -dr / len);
            ups.push((first, k, back, v, (t_ramp - stood).max(0.0)));
        }
        let next = moves.get(j + 1).copied();
        let to_rest = match next {
            None => true,
            Some(nx) => !is_print(nx) || rests_between(k, nx),
        };
        if to_rest {
            let (last, stood) = block_after(steps, k, t_ramp);
            let past = lerp(to, from, -dr / len);
            outs.push((k, last, past, v, (t_ramp - stood).max(0.0)));
        }
    }
    let mut out: Vec<Step> = Vec::with_capacity(n + 3 * (ups.len() + outs.len()));
    let (mut ui, mut oi) = (0, 0);
    // Time a run-out still owes the dwells after it.
    let mut owed = 0.0f64;
    // Dwells before this step belong to a run-up's block (absorbed in it).
    let mut absorb_dwells_until = 0usize;
    // A run-out's block (after its move, through its last step): already written.
    let mut out_block = (0usize, 0usize);
    for k in 0..n {
        if ui < ups.len() && ups[ui].0 == k {
            let (_, m, back, v, t) = ups[ui];
            write_run_up(&mut out, back, at[m], v, t);
            absorb_dwells_until = m;
            ui += 1;
        }
        let written = k > out_block.0 && k <= out_block.1;
        if !written {
            match steps[k] {
                Step::Dwell(_) if k < absorb_dwells_until => {}
                Step::Dwell(d) if owed > 0.0 => {
                    let take = d.min(owed);
                    owed -= take;
                    out.push(Step::Dwell(d - take));
                }
                Step::Move { .. } => {
                    owed = 0.0;
                    out.push(steps[k]);
                }
                st => out.push(st),
            }
        }
        if oi < outs.len() && outs[oi].0 == k {
            let (_, last, past, v, t) = outs[oi];
            // The block's valve changes go before the run-out; its dwells are absorbed.
            for st in &steps[k + 1..=last] {
                if let Step::Valves(_) = st {
                    out.push(*st);
                }
            }
            out_block = (k, last);
            out.push(Step::Move {
                to: past,
                v,
                travel: true,
            });
            owed = t;
            oi += 1;
        }
    }
    out.retain(|s| !matches!(s, Step::Dwell(d) if *d <= 0.0));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A firmware ramp from `lo` to `hi` at `a` that starts `centring_shift` before a
    /// flow jump: the bead it leaves short before the jump (head faster than the old flow)
    /// equals what it leaves over after (head slower than the new), each `dv^2 / 8a`.
    #[test]
    fn the_shift_puts_the_jump_half_way_through_the_ramp() {
        for (lo, hi, a) in [
            (10.0, 21.8, 2000.0),
            (4.0, 30.0, 500.0),
            (20.0, 20.5, 5000.0),
        ] {
            let d = centring_shift(lo, hi, a);
            let dt = 1e-7;
            let (mut t, mut x, mut short, mut over) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            while t < (hi - lo) / a {
                let v = lo + a * (t + 0.5 * dt);
                if x < d {
                    short += (v - lo) * dt;
                } else {
                    over += (hi - v) * dt;
                }
                x += v * dt;
                t += dt;
            }
            let want = (hi - lo) * (hi - lo) / (8.0 * a);
            assert!(
                (short - want).abs() < 1e-3 * want + 1e-8,
                "{lo} {hi}: {short} vs {want}"
            );
            assert!(
                (over - want).abs() < 1e-3 * want + 1e-8,
                "{lo} {hi}: {over} vs {want}"
            );
        }
    }
}
