//! Pause and resume through the board's link, on recorded outputs: Pausing then Paused
//! mid-bead with the valves shut and the drivers holding, resume refused with nothing
//! paused, pause while paused, link loss while paused, abort while paused, and link loss
//! while printing pausing mid-bead (the `Pause` policy) rather than at the bead's end.

mod device_support;

use device_support::*;
use dollop::wire::*;
use dollop::RunState;

/// Starts the job and runs it until the head is `mm` into the first 10 mm bead.
fn printing_at(b: &mut Board, h: &mut Host, mm: f64) -> f64 {
    h.ok(b, &Request::Start);
    h.wait(b, |s| {
        s.control.run == RunState::Printing && s.control.valves != 0
    });
    let x0 = 20.0;
    loop {
        let x = b.snapshot().position_um[0] as f64 * 1e-3;
        if x >= x0 + mm {
            return x;
        }
        b.advance(1000);
    }
}

/// Runs until Paused, checking that Pausing came first (when the request was made
/// here); returns the position at rest.
fn until_paused(b: &mut Board, pausing_first: bool) -> [i32; 3] {
    let mut saw_pausing = false;
    for _ in 0..20_000 {
        let s = b.snapshot();
        saw_pausing |= s.run == RunState::Pausing;
        if s.run == RunState::Paused {
            assert!(
                saw_pausing || !pausing_first,
                "Paused without Pausing first"
            );
            // The outputs may still settle for half a ramp window.
            b.advance(100_000);
            return b.snapshot().position_um;
        }
        b.advance(100);
    }
    panic!("never paused: {:?}", b.snapshot());
}

#[test]
fn pause_stops_mid_bead_and_resume_goes_on() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 2);
    assert!(matches!(
        h.refused(&mut b, &Request::Resume),
        Refusal::NotPaused { .. }
    ));
    let x_req = printing_at(&mut b, &mut h, 2.0);
    h.ok(&mut b, &Request::Pause);
    let at = until_paused(&mut b, true);
    let x = at[0] as f64 * 1e-3;
    // Mid-bead: past the request, well short of the bead's end at 30 mm.
    assert!(
        x >= x_req && x < 29.0,
        "paused at x = {x}, requested at {x_req}"
    );
    assert_eq!(b.out.valves, 0);
    assert!(b.out.drivers, "drivers must hold while paused");
    // Holds: no motion, valves shut; a second pause changes nothing.
    h.ok(&mut b, &Request::Pause);
    b.advance(500_000);
    let s = b.snapshot();
    assert_eq!(s.run, RunState::Paused);
    assert_eq!(s.position_um, at);
    assert_eq!(b.out.valves, 0);
    h.ok(&mut b, &Request::Resume);
    h.wait(&mut b, |s| s.control.run == RunState::Printing);
    h.wait(&mut b, |s| {
        s.control.position_um[0] > at[0] + 500 && s.control.valves != 0
    });
    h.wait(&mut b, |s| s.control.mode == Mode::Idle);
    assert!(matches!(
        h.refused(&mut b, &Request::Resume),
        Refusal::NotPaused { .. }
    ));
}

#[test]
fn link_loss_while_paused_stays_paused_and_abort_goes_safe() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 2);
    printing_at(&mut b, &mut h, 2.0);
    h.ok(&mut b, &Request::Pause);
    let at = until_paused(&mut b, true);
    // The host falls silent: still paused, where it was.
    b.advance((LINK_TIMEOUT_MS as u64 + 500) * 1000);
    let s = b.snapshot();
    assert_eq!(s.run, RunState::Paused, "{s:?}");
    assert_eq!(s.position_um, at);
    assert_eq!(b.out.valves, 0);
    // A new session aborts it.
    let mut h2 = Host {
        session: 0x777,
        ..Host::default()
    };
    h2.hello(&mut b);
    h2.ok(&mut b, &Request::Abort);
    b.advance(1000);
    assert_safe(&b);
}

#[test]
fn link_loss_while_printing_pauses_mid_bead() {
    let mut b = board();
    // Rows of 1.3 s (a 10 mm bead at 10 mm/s, the travel back): the link times out on
    // the third bead.
    let mut h = Host::ready(&mut b, 6);
    h.ok(&mut b, &Request::Start);
    h.wait(&mut b, |s| {
        s.control.run == RunState::Printing && s.control.valves != 0
    });
    // The host falls silent: the pause comes at the link timeout, mid-bead.
    b.advance((LINK_TIMEOUT_MS as u64 + 200) * 1000);
    let at = until_paused(&mut b, false);
    assert!(
        at[0] > 20_500 && at[0] < 29_000,
        "paused at {at:?}: at the bead's end, not where the link was lost"
    );
    assert_eq!(b.out.valves, 0);
    assert!(b.out.drivers);
}

/// Park through the link: the status reads Pausing from the first cycle after the
/// request (before the valve decision), then Paused with the pause point as a field; the
/// head lifts and goes to the park position (the config's default: the X/Y travel
/// minima, 5 mm up), a refill on this pneumatic board changes nothing, and resume comes
/// back over the pause point, lowers, and prints on from it.
#[test]
fn park_lifts_moves_away_and_comes_back() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 2);
    printing_at(&mut b, &mut h, 2.0);
    h.ok(&mut b, &Request::Park);
    b.advance(200);
    assert_eq!(
        b.snapshot().run,
        RunState::Pausing,
        "right after the request"
    );
    until_paused(&mut b, true);
    let point = b
        .snapshot()
        .pause_point_um
        .expect("pause point while paused");
    let parked = [0, 0, point[2] + 5_000];
    h.wait(&mut b, |s| s.control.position_um == parked);
    let s = b.snapshot();
    assert_eq!(s.run, RunState::Paused);
    assert_eq!(s.pause_point_um, Some(point));
    assert_eq!(b.out.valves, 0);
    assert!(b.out.drivers, "drivers must hold while parked");
    h.ok(&mut b, &Request::Refill);
    b.advance(100_000);
    assert_eq!(b.snapshot().position_um, parked);
    h.ok(&mut b, &Request::Resume);
    // Back over the point, to the step (the status counts steps of 12.5 um in X and Y).
    let near = |p: [i32; 3]| (0..3).all(|a| (p[a] - point[a]).abs() <= 13);
    h.wait(&mut b, |s| {
        near(s.control.position_um) && s.control.run == RunState::Paused
    });
    h.wait(&mut b, |s| {
        s.control.run == RunState::Printing && s.control.position_um[0] > point[0] + 500
    });
    assert_eq!(b.snapshot().pause_point_um, None);
    assert_eq!(b.snapshot().position_um[2], point[2]);
    h.wait(&mut b, |s| s.control.mode == Mode::Idle);
}
