//! Stateful fuzzing of the board: arbitrary request sequences, raw frames and board
//! events drive `SimBoard` through hello, configs (bundled, syringes included, and
//! hostile), homing, uploads, a running print, pause, abort and e-stop; after every
//! control cycle the outputs must be safe whenever the state says so (see `board/driver.rs`).
#![no_main]

#[path = "board/driver.rs"]
mod driver;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut d = driver::Driver::new();
    d.run(data);
});
