//! Bounded fuzz-style properties of everything that reads bytes from outside (runs in
//! the normal suite; `fuzz/` holds the open-ended cargo-fuzz targets): arbitrary and
//! mutated USB bytes never panic the board and are never taken as another message;
//! arbitrary job bodies never panic the decoder.

mod device_support;

use device_support::*;
use dollop::job::{BodyDecoder, JobHeader, FORMAT_VERSION, FORMAT_VERSION_SECTIONS};
use dollop::wire::*;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic_the_board(chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..600), 1..8)) {
        let mut b = board();
        let mut h = Host::default();
        h.hello(&mut b);
        for c in &chunks {
            b.receive(c);
            b.advance(200);
            let mut buf = [0u8; 4096];
            let _ = b.take_tx(&mut buf);
        }
        // Still answering, still safe.
        let _ = h.status(&mut b);
        assert_safe(&b);
    }

    #[test]
    fn a_mutated_frame_is_dropped_or_decodes_to_the_original(
        offset in 0u32..1_000_000,
        data in proptest::collection::vec(any::<u8>(), 1..MAX_CHUNK),
        flips in proptest::collection::vec((any::<usize>(), 1u8..=255), 1..4),
    ) {
        let mut buf = [0u8; MAX_FRAME + 1];
        let req = Request::Chunk { offset, data: &data };
        let n = encode(&HostHeader { session: 3, seq: 4 }, &req, &mut buf).unwrap();
        let mut frame = buf[..n - 1].to_vec();
        for (i, x) in flips {
            let k = i % frame.len();
            frame[k] ^= x;
        }
        // Cut at zero bytes the way a reader would; any part that decodes must be the
        // original message (CRC-32 catches up to three flipped bytes in a frame this short).
        for part in frame.split(|&b| b == 0) {
            let mut p = part.to_vec();
            if let Ok((h, r)) = decode::<HostHeader, Request<'_>>(&mut p) {
                prop_assert_eq!(h, HostHeader { session: 3, seq: 4 });
                prop_assert_eq!(r, Request::Chunk { offset, data: &data });
            }
        }
    }

    #[test]
    fn arbitrary_job_bodies_never_panic_the_decoder(
        body in proptest::collection::vec(any::<u8>(), 0..512),
        split in 0usize..512,
        commands in 0u32..100,
        sections in any::<bool>(),
    ) {
        let h = JobHeader {
            // Version 1 refuses a section command, version 2 takes it.
            format_version: if sections { FORMAT_VERSION_SECTIONS } else { FORMAT_VERSION },
            config_hash: 0,
            materials: heapless::Vec::new(),
            bounds_min_um: [0; 3],
            bounds_max_um: [0; 3],
            start_um: [0; 3],
            initial_material: 0,
            print_segments: 0,
            commands,
            body_len: body.len() as u32,
            body_crc: dollop::job::body_crc(&body),
        };
        let mut d = BodyDecoder::new(&h);
        let (a, b) = body.split_at(split.min(body.len()));
        let mut n = 0u32;
        let r1 = d.feed(a, |_| { n += 1; Ok::<(), ()>(()) });
        if r1.is_ok() {
            let _ = d.feed(b, |_| { n += 1; Ok::<(), ()>(()) });
        }
        let _ = d.finish();
        let _ = dollop::job::decode_preamble(&body);
    }
}
