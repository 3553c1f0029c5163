//! Which of a board's controls can act now, and why not: one rule per action read from
//! the board's last status (mode, run state, homed, connected, queue). The worker refuses
//! an order by the same rule (a Pause on an idle board is an error, not a success), and
//! the page disables the button with the reason on hover. Abort is never refused here:
//! it is the emergency stop, and on a board with nothing to stop it does no harm.

use super::view::View;
use dollop::wire::Mode;
use dollop::RunState;
use std::collections::BTreeMap;

/// The actions the page offers on a board (as in `/api/boards/{id}/{action}`).
pub const ACTIONS: [&str; 8] = [
    "start-next",
    "pause",
    "park",
    "resume",
    "home",
    "jog",
    "valve",
    "abort",
];

/// What the board is busy with, in words, when it is neither idle nor printing.
pub fn busy_words(mode: Option<Mode>) -> Option<&'static str> {
    match mode? {
        Mode::Homing => Some("the board is homing"),
        Mode::Jogging => Some("the board is moving by hand (jog)"),
        Mode::ValveTest => Some("a valve test is under way"),
        _ => None,
    }
}

fn ended(run: Option<RunState>) -> bool {
    matches!(
        run,
        Some(RunState::Done | RunState::Aborted | RunState::Faulted)
    )
}

fn paused(run: Option<RunState>) -> bool {
    matches!(run, Some(RunState::Paused | RunState::Pausing))
}

/// Why `action` cannot act on the board `v` now (with `queued` jobs waiting), or None when
/// it can. Unknown actions are not this function's to refuse.
pub fn refusal(v: &View, queued: usize, action: &str) -> Option<String> {
    if action == "abort" {
        return None;
    }
    if !v.connected {
        return Some("the board is not connected; check its cable and power".into());
    }
    if v.upload.is_some() || v.activity == "uploading" {
        return Some("a job is being uploaded to the board; wait, or Abort".into());
    }
    let printing = v.mode == Some(Mode::Job);
    let halted = v.mode == Some(Mode::Halted);
    let no_print = || -> String {
        if halted {
            "the board is halted: press Abort to clear it".into()
        } else {
            "no print is running".into()
        }
    };
    match action {
        "start-next" => {
            if queued == 0 {
                Some("no job is waiting in this board's queue".into())
            } else if printing {
                Some("the board is printing; wait for the print to end, or Abort".into())
            } else if halted {
                Some("the board is halted: press Abort to clear it, then Home".into())
            } else {
                busy_words(v.mode).map(|b| format!("{b}; the job starts when it is done"))
            }
        }
        "pause" => {
            if !printing || ended(v.run) {
                Some(no_print())
            } else if paused(v.run) {
                Some("the print is already paused; Resume goes on".into())
            } else {
                None
            }
        }
        "park" => {
            let off_point = v.run == Some(RunState::Paused)
                && v.pause_point.is_some_and(|p| {
                    let d: f64 = (0..3).map(|i| (v.position[i] - p[i]).powi(2)).sum();
                    d.sqrt() > 0.001
                });
            if !printing || ended(v.run) {
                Some(no_print())
            } else if off_point {
                Some("the head is parked (or on its way); Resume brings it back".into())
            } else {
                None
            }
        }
        "resume" => {
            if !printing || ended(v.run) {
                Some(no_print())
            } else if !paused(v.run) {
                Some("the print is not paused".into())
            } else {
                None
            }
        }
        "home" => {
            if printing {
                Some("a print is running; Abort it first".into())
            } else if halted {
                Some("the board is halted: press Abort to clear it first".into())
            } else {
                busy_words(v.mode).map(String::from)
            }
        }
        "jog" => {
            if printing {
                Some("a print is running".into())
            } else if halted {
                Some("the board is halted: press Abort to clear it, then Home".into())
            } else if let Some(b) = busy_words(v.mode) {
                Some(b.into())
            } else if !v.homed {
                Some("the machine is not homed: press Home first".into())
            } else {
                None
            }
        }
        "valve" => {
            if printing {
                Some("a print is running".into())
            } else if halted {
                Some("the board is halted: press Abort to clear it first".into())
            } else {
                busy_words(v.mode).map(String::from)
            }
        }
        _ => None,
    }
}

/// Every action's refusal (absent: it can act), for the page.
pub fn refusals(v: &View, queued: usize) -> BTreeMap<String, String> {
    ACTIONS
        .iter()
        .filter_map(|a| refusal(v, queued, a).map(|r| (a.to_string(), r)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(mode: Mode, run: RunState) -> View {
        View {
            connected: true,
            homed: true,
            mode: Some(mode),
            run: Some(run),
            activity: "x".into(),
            ..Default::default()
        }
    }

    #[test]
    fn an_idle_board_refuses_pause_and_resume_and_takes_home_jog_and_valves() {
        let v = view(Mode::Idle, RunState::Idle);
        let r = refusals(&v, 0);
        assert_eq!(
            r.get("pause").map(String::as_str),
            Some("no print is running")
        );
        assert_eq!(
            r.get("resume").map(String::as_str),
            Some("no print is running")
        );
        assert!(
            r.contains_key("park") && r.contains_key("start-next"),
            "{r:?}"
        );
        for ok in ["home", "jog", "valve", "abort"] {
            assert!(!r.contains_key(ok), "{ok}: {r:?}");
        }
        assert_eq!(refusal(&v, 1, "start-next"), None);
    }

    #[test]
    fn printing_takes_pause_and_park_then_resume_once_paused() {
        let v = view(Mode::Job, RunState::Printing);
        let r = refusals(&v, 1);
        for ok in ["pause", "park", "abort"] {
            assert!(!r.contains_key(ok), "{ok}: {r:?}");
        }
        for no in ["resume", "home", "jog", "valve", "start-next"] {
            assert!(r.contains_key(no), "{no}: {r:?}");
        }
        let v = view(Mode::Job, RunState::Paused);
        assert_eq!(refusal(&v, 0, "resume"), None);
        assert!(refusal(&v, 0, "pause").is_some_and(|m| m.contains("already paused")));
        // Done: the print has ended though the board still reads its job.
        let v = view(Mode::Job, RunState::Done);
        assert!(refusal(&v, 0, "pause").is_some());
    }

    #[test]
    fn busy_halted_unhomed_and_unconnected_boards_say_why() {
        let v = view(Mode::Homing, RunState::Idle);
        assert!(refusal(&v, 1, "start-next").is_some_and(|m| m.contains("homing")));
        assert!(refusal(&v, 0, "home").is_some_and(|m| m.contains("homing")));
        let v = view(Mode::Halted, RunState::Faulted);
        assert!(refusal(&v, 0, "home").is_some_and(|m| m.contains("Abort")));
        assert_eq!(refusal(&v, 0, "abort"), None);
        let mut v = view(Mode::Idle, RunState::Idle);
        v.homed = false;
        assert!(refusal(&v, 0, "jog").is_some_and(|m| m.contains("Home")));
        v.connected = false;
        assert!(refusal(&v, 0, "home").is_some_and(|m| m.contains("not connected")));
        assert_eq!(refusal(&v, 0, "abort"), None);
    }
}
