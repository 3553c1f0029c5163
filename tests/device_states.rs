//! Bounded stateful property test of the board (the CI counterpart of the
//! `board_states` fuzz target, sharing its driver): random request sequences, raw frames
//! and board events, with the outputs checked after every control cycle.

#[path = "../fuzz/fuzz_targets/board/driver.rs"]
mod driver;

use dollop::wire::Mode;
use proptest::prelude::*;

#[test]
fn the_scripted_start_reaches_a_running_print_and_abort_closes_the_valves() {
    // Script byte: bit 0 scripted start, config 0 (seed valves), 1 row, start.
    let mut d = driver::Driver::new();
    d.run(&[0x81]);
    assert_eq!(
        d.board.control.mode(),
        Mode::Job,
        "{:?}",
        d.board.snapshot()
    );
    let mut opened = false;
    // Up to 15 s of board time.
    for _ in 0..3000 {
        d.status();
        d.run_for(5_000);
        opened |= d.board.out.valves != 0;
        if opened {
            break;
        }
    }
    assert!(
        opened,
        "the print never opened a valve: {:?}",
        d.board.snapshot()
    );
    // Step 8 is Abort; the checks after each cycle hold the valves shut after it.
    d.run(&[0, 8, 15, 100]);
    assert_eq!(d.board.out.valves, 0, "{:?}", d.board.snapshot());
}

#[test]
fn the_syringe_config_reaches_a_running_print() {
    // Config 1 is configs/syringes.toml.
    let mut d = driver::Driver::new();
    d.run(&[0x83]);
    assert_eq!(
        d.board.control.mode(),
        Mode::Job,
        "{:?}",
        d.board.snapshot()
    );
}

#[test]
#[should_panic(expected = "a valve open while not printing")]
fn the_check_catches_a_valve_left_open_when_idle() {
    let mut d = driver::Driver::new();
    d.run(&[0x01]);
    assert_eq!(d.board.control.mode(), Mode::Idle);
    d.board.out.valves = 1;
    driver::check(&d.board);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_request_sequences_leave_the_outputs_safe(
        data in proptest::collection::vec(any::<u8>(), 1..160)
    ) {
        let mut d = driver::Driver::new();
        d.run(&data);
    }

    #[test]
    fn arbitrary_requests_during_a_print_leave_the_outputs_safe(
        cfg in 0u8..3,
        data in proptest::collection::vec(any::<u8>(), 1..120)
    ) {
        let mut input = vec![0x81 | (cfg << 1)];
        input.extend_from_slice(&data);
        let mut d = driver::Driver::new();
        d.run(&input);
    }
}
