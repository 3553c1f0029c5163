//! Board operations both front ends run, once: abort (and clear a halt), a hand jog (its
//! distance checked, sent once), and homing waited out, each returning a typed outcome
//! whose words both `dollop abort`/`dollop jog`/`dollop send` and the dashboard show.
//! Where it stops: connecting, the config a jog needs and the messages around them are
//! the front ends'.

use super::{Client, LinkError, Transport};
use dollop::wire::{Mode, Reply, Request, Status, POLL_MS};
use dollop::Axis;
use std::time::Duration;

/// What an abort did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aborted {
    /// The board stopped: valves closed, drivers off.
    Stopped,
    /// The board was halted (a fault, an e-stop released): the halt is cleared.
    HaltCleared,
}

impl std::fmt::Display for Aborted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Aborted::Stopped => "aborted: valves closed, drivers off",
            Aborted::HaltCleared => "halt cleared; home the machine before the next job",
        })
    }
}

/// Aborts whatever runs, then clears a halt if the board is (still) halted.
pub fn abort_and_clear<T: Transport>(c: &mut Client<T>) -> Result<Aborted, LinkError> {
    abort(c)?;
    clear_if_halted(c)
}

/// The first half of `abort_and_clear`: the abort, taken by the board (for a caller that
/// notes the print's end in between).
pub fn abort<T: Transport>(c: &mut Client<T>) -> Result<(), LinkError> {
    c.command(&Request::Abort)?;
    // The board needs a control period to take the order: look after it had one.
    c.sleep(Duration::from_millis(5));
    Ok(())
}

/// The second half of `abort_and_clear`: clears a halt if the board is halted.
pub fn clear_if_halted<T: Transport>(c: &mut Client<T>) -> Result<Aborted, LinkError> {
    if c.status()?.control.mode == Mode::Halted {
        c.command(&Request::ClearFault)?;
        return Ok(Aborted::HaltCleared);
    }
    Ok(Aborted::Stopped)
}

/// Longest hand move taken, mm: past any machine's travel, short of a typo's thousands.
pub const MAX_JOG_MM: f64 = 2000.0;

/// Why a jog was not made.
#[derive(Debug, thiserror::Error)]
pub enum JogError {
    /// Not a number, or longer than `MAX_JOG_MM`.
    #[error("jog distance {0} mm is not a plausible move")]
    Implausible(f64),
    /// The board answered something else than yes or no.
    #[error("unexpected answer {0:?}")]
    Unexpected(Reply),
    /// The link failed, or the board refused.
    #[error(transparent)]
    Link(#[from] LinkError),
}

/// A jog distance checked, in µm as the board takes it.
pub fn jog_um(mm: f64) -> Result<i32, JogError> {
    if !mm.is_finite() || mm.abs() > MAX_JOG_MM {
        return Err(JogError::Implausible(mm));
    }
    Ok((mm * 1000.0).round() as i32)
}

/// Moves `axis` by `um` (from `jog_um`). Sent once: a jog repeated after a lost answer
/// would move twice. Returns once the board took it, not when the move ends.
pub fn jog<T: Transport>(c: &mut Client<T>, axis: Axis, um: i32) -> Result<(), JogError> {
    match c.call_once(&Request::Jog { axis, um })? {
        Reply::Ack => Ok(()),
        Reply::Refused(r) => Err(LinkError::Refused(r).into()),
        other => Err(JogError::Unexpected(other)),
    }
}

/// Why the board did not come to rest as asked.
#[derive(Debug, thiserror::Error)]
pub enum WaitError {
    /// The board halted (a fault, an e-stop): its status says why, in the front end's
    /// words (what clears a halt differs between them).
    #[error("the board halted")]
    Halted(Box<Status>),
    /// Still busy when the time allowed ran out.
    #[error("the board is still busy ({mode:?}) after {secs} s")]
    Busy {
        /// What it was doing.
        mode: Mode,
        /// The time allowed, s.
        secs: u64,
    },
    /// Homing came to rest without the machine homed.
    #[error("homing did not finish; check the endstops")]
    NotHomed,
    /// The link failed, or the board refused.
    #[error(transparent)]
    Link(#[from] LinkError),
}

/// Waits until the board is idle (or in a valve test), for at most `limit`.
pub fn wait_idle<T: Transport>(c: &mut Client<T>, limit: Duration) -> Result<Status, WaitError> {
    let start = c.transport().now();
    // The board needs a control period to take an order: look after it had one.
    c.sleep(Duration::from_millis(5));
    loop {
        let s = c.status()?;
        match s.control.mode {
            Mode::Idle | Mode::ValveTest => return Ok(s),
            Mode::Halted => return Err(WaitError::Halted(Box::new(s))),
            _ => {}
        }
        if c.transport().now().saturating_sub(start) > limit {
            return Err(WaitError::Busy {
                mode: s.control.mode,
                secs: limit.as_secs(),
            });
        }
        c.sleep(Duration::from_millis(POLL_MS as u64 / 2));
    }
}

/// Longest homing waited for.
pub const HOME_LIMIT: Duration = Duration::from_secs(300);

/// Homes all axes and waits (at most `HOME_LIMIT`) until the machine rests homed; returns
/// the status it rests in.
pub fn home_and_wait<T: Transport>(c: &mut Client<T>) -> Result<Status, WaitError> {
    c.command(&Request::Home)?;
    wait_idle(c, HOME_LIMIT)?;
    let s = c.status()?;
    if !s.control.homed {
        return Err(WaitError::NotHomed);
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jog_distances_are_checked() {
        assert_eq!(jog_um(1.2345).ok(), Some(1235));
        assert_eq!(jog_um(-2000.0).ok(), Some(-2_000_000));
        for bad in [f64::NAN, f64::INFINITY, 2000.5, -1e9] {
            let e = jog_um(bad).expect_err("refused");
            assert!(e.to_string().contains("not a plausible move"), "{e}");
        }
    }
}
