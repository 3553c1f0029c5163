//! The live print's clock: the time since the print started (stopped when it stops), the
//! time spent paused, and the ETA from the executor's virtual-time estimate of the job
//! (its time at each command, worked out when the job was sliced) corrected by the pace
//! the board has kept so far. Arithmetic only: the board's worker feeds it and shows it.

use std::time::{Duration, Instant};

/// Below this much estimated time done (wall seconds), the pace is not judged yet.
const PACE_AFTER_S: f64 = 1.0;

/// How far the pace so far may move the estimate (a stall is a pause, not a pace).
const PACE_BOUNDS: (f64, f64) = (0.25, 4.0);

/// Seconds left of a job at `command` of `starts.len() - 1`: the estimate's remaining
/// virtual time over `speed` (a simulated board runs faster than the wall clock), scaled
/// by the pace so far (`printing_s`, wall seconds printing, over what the estimate gives
/// for the part done) trusted in proportion to the part done. `starts[i]` is the virtual
/// time at which command `i` began, `total_s` the job's end. Without a timeline (the
/// estimate could not be made) the part done is counted in commands of `commands`.
pub fn eta_s(
    starts: &[f64],
    total_s: f64,
    command: u32,
    commands: u32,
    printing_s: f64,
    speed: f64,
) -> Option<f64> {
    if !(total_s > 0.0 && speed > 0.0 && printing_s.is_finite()) {
        return None;
    }
    let done_v = match starts.last() {
        Some(_) => starts[(command as usize).min(starts.len() - 1)],
        None => total_s * (command as f64 / commands.max(1) as f64).min(1.0),
    }
    .clamp(0.0, total_s);
    let left = (total_s - done_v) / speed;
    let done_wall = done_v / speed;
    if done_wall < PACE_AFTER_S {
        return Some(left);
    }
    let pace = (printing_s / done_wall).clamp(PACE_BOUNDS.0, PACE_BOUNDS.1);
    let w = done_v / total_s;
    Some(left * (1.0 - w + w * pace))
}

/// When a print started, stopped and paused.
#[derive(Debug, Clone, Copy)]
pub struct PrintClock {
    started: Instant,
    ended: Option<Instant>,
    paused_since: Option<Instant>,
    paused: Duration,
}

impl PrintClock {
    /// A print starting now.
    pub fn start(now: Instant) -> Self {
        PrintClock {
            started: now,
            ended: None,
            paused_since: None,
            paused: Duration::ZERO,
        }
    }

    /// The board reads paused (or not) at `now`.
    pub fn paused(&mut self, paused: bool, now: Instant) {
        match (paused, self.paused_since) {
            (true, None) if self.ended.is_none() => self.paused_since = Some(now),
            (false, Some(t)) => {
                self.paused += now.saturating_duration_since(t);
                self.paused_since = None;
            }
            _ => {}
        }
    }

    /// The print ended (finished, aborted, faulted) at `now`; later calls keep the first.
    pub fn end(&mut self, now: Instant) {
        if self.ended.is_none() {
            self.paused(false, now);
            self.ended = Some(now);
        }
    }

    /// It has ended.
    pub fn ended(&self) -> bool {
        self.ended.is_some()
    }

    /// Seconds from the start to `now`, or to the end once ended.
    pub fn elapsed_s(&self, now: Instant) -> f64 {
        self.ended
            .unwrap_or(now)
            .saturating_duration_since(self.started)
            .as_secs_f64()
    }

    /// Seconds spent printing (elapsed less the pauses) up to `now`.
    pub fn printing_s(&self, now: Instant) -> f64 {
        let paused_now = match self.paused_since {
            Some(t) => now.saturating_duration_since(t),
            None => Duration::ZERO,
        };
        (self.elapsed_s(now) - (self.paused + paused_now).as_secs_f64()).max(0.0)
    }
}

/// Milliseconds since 1970 at `secs` from now (the page shows it as a clock time).
pub fn unix_ms_in(secs: f64) -> Option<f64> {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?;
    secs.is_finite()
        .then(|| now.as_secs_f64() * 1e3 + secs.max(0.0) * 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A job of 4 commands at 0, 10, 20, 30 s ending at 40 s.
    const STARTS: [f64; 5] = [0.0, 10.0, 20.0, 30.0, 40.0];

    #[test]
    fn eta_is_the_estimate_left_when_the_pace_matches() {
        assert_eq!(eta_s(&STARTS, 40.0, 0, 4, 0.0, 1.0), Some(40.0));
        assert_eq!(eta_s(&STARTS, 40.0, 2, 4, 20.0, 1.0), Some(20.0));
        // Ten times faster than the wall: a tenth of the time.
        let e = eta_s(&STARTS, 40.0, 2, 4, 2.0, 10.0).expect("eta");
        assert!((e - 2.0).abs() < 1e-12, "{e}");
        assert_eq!(eta_s(&STARTS, 40.0, 4, 4, 40.0, 1.0), Some(0.0));
    }

    #[test]
    fn a_slow_pace_lengthens_the_eta_in_proportion_to_the_part_done() {
        // Half done in twice the estimate: trusted half-way, 20 s * (0.5 + 0.5 * 2).
        let e = eta_s(&STARTS, 40.0, 2, 4, 40.0, 1.0).expect("eta");
        assert!((e - 30.0).abs() < 1e-9, "{e}");
        // Three quarters done at pace 1.5: 10 s * (0.25 + 0.75 * 1.5).
        let e = eta_s(&STARTS, 40.0, 3, 4, 45.0, 1.0).expect("eta");
        assert!((e - 13.75).abs() < 1e-9, "{e}");
        // A stall does not send it past four times the estimate.
        let e = eta_s(&STARTS, 40.0, 2, 4, 1e6, 1.0).expect("eta");
        assert!((e - 20.0 * (0.5 + 0.5 * 4.0)).abs() < 1e-9, "{e}");
    }

    #[test]
    fn without_a_timeline_commands_count_and_nonsense_gives_none() {
        assert_eq!(eta_s(&[], 40.0, 1, 4, 10.0, 1.0), Some(30.0));
        assert_eq!(eta_s(&STARTS, 0.0, 1, 4, 10.0, 1.0), None);
        assert_eq!(eta_s(&STARTS, 40.0, 1, 4, f64::NAN, 1.0), None);
        // A command count past the job (a stale status) reads as done.
        assert_eq!(eta_s(&STARTS, 40.0, 9, 4, 40.0, 1.0), Some(0.0));
    }

    #[test]
    fn the_clock_stops_at_the_end_and_leaves_pauses_out_of_the_printing_time() {
        let t0 = Instant::now();
        let s = |x: u64| t0 + Duration::from_secs(x);
        let mut c = PrintClock::start(t0);
        c.paused(true, s(10));
        assert_eq!(c.printing_s(s(15)), 10.0);
        c.paused(false, s(20));
        assert_eq!(c.printing_s(s(30)), 20.0);
        c.end(s(40));
        c.end(s(50));
        assert!(c.ended());
        assert_eq!(c.elapsed_s(s(100)), 40.0);
        assert_eq!(c.printing_s(s(100)), 30.0);
        // Paused when the print is aborted: the pause ends with it.
        let mut c = PrintClock::start(t0);
        c.paused(true, s(5));
        c.end(s(9));
        c.paused(true, s(12));
        assert_eq!((c.elapsed_s(s(60)), c.printing_s(s(60))), (9.0, 5.0));
    }
}
