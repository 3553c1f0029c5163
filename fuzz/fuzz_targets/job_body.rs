//! Fuzzes the job file decoders: the preamble, and the streaming body decoder fed in two
//! pieces split anywhere.
#![no_main]

use dollop::job::{self, BodyDecoder};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok((header, n)) = job::decode_preamble(data) {
        let body = &data[n..];
        let mut d = BodyDecoder::new(&header);
        let split = body.len() / 3;
        if d.feed(&body[..split], |_| Ok::<(), ()>(())).is_ok() {
            let _ = d.feed(&body[split..], |_| Ok::<(), ()>(()));
        }
        let _ = d.finish();
    }
    if data.len() >= 4 {
        let (head, body) = data.split_at(4);
        let h = job::JobHeader {
            // Version 1 refuses `Command::Section`, version 2 takes it.
            format_version: if head[1] & 1 == 0 {
                job::FORMAT_VERSION
            } else {
                job::FORMAT_VERSION_SECTIONS
            },
            config_hash: 0,
            materials: heapless::Vec::new(),
            bounds_min_um: [0; 3],
            bounds_max_um: [0; 3],
            start_um: [0; 3],
            initial_material: 0,
            print_segments: 0,
            commands: head[0] as u32,
            body_len: body.len() as u32,
            body_crc: u32::from_le_bytes([head[0], head[1], head[2], head[3]]),
        };
        let mut d = BodyDecoder::new(&h);
        let _ = d.feed(body, |_| Ok::<(), ()>(()));
        let _ = d.finish();
    }
});
