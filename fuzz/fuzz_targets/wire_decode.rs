//! Fuzzes everything the board does with USB bytes: the frame reader and decoder for both
//! directions, and the device's link handler (which must never panic, whatever arrives).
#![no_main]

use dollop::device::{RamStore, SimBoard};
use dollop::wire::{decode, DeviceHeader, HostHeader, Reply, Request};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut a = data.to_vec();
    let _ = decode::<HostHeader, Request<'_>>(&mut a);
    let mut b = data.to_vec();
    let _ = decode::<DeviceHeader, Reply>(&mut b);
    let mut board = SimBoard::new(RamStore::new([0xFFu8; 4096]));
    for part in data.chunks(64) {
        board.receive(part);
        board.cycle();
        let mut out = [0u8; 1024];
        let _ = board.take_tx(&mut out);
    }
    assert_eq!(board.out.valves, 0);
});
