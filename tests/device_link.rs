//! The board's side of the link protocol: sessions, sequence numbers, duplicates,
//! out-of-order and corrupted frames, credits, version mismatch, and the refusals a
//! host gets for bad configs, bad jobs and bad timing, each with a clear message.

mod device_support;

use device_support::*;
use dollop::device::JobStore;
use dollop::wire::*;
use dollop::{Axis, Command};

fn configured() -> (Board, Host) {
    let mut b = board();
    let mut h = Host::default();
    h.hello(&mut b);
    h.ok(&mut b, &Request::LoadConfig(config()));
    b.advance(1000);
    (b, h)
}

#[test]
fn requests_before_hello_are_refused_for_lack_of_a_session() {
    let mut b = board();
    let mut h = Host::default();
    assert!(matches!(
        h.req(&mut b, &Request::Status),
        Reply::Refused(Refusal::NoSession)
    ));
}

#[test]
fn a_version_mismatch_is_refused_naming_both_versions() {
    let mut b = board();
    let h = Host::default();
    let f = h.frame(
        1,
        &Request::Hello {
            version: PROTOCOL_VERSION + 1,
        },
    );
    let mut h = h;
    let replies = h.raw(&mut b, &f);
    let info = replies
        .iter()
        .find_map(|(_, r)| {
            if let Reply::Hello(i) = r {
                Some(i.clone())
            } else {
                None
            }
        })
        .unwrap();
    assert_eq!(info.version, PROTOCOL_VERSION);
    h.seq = 2;
    let r = h.refused(&mut b, &Request::Status);
    assert_eq!(
        r,
        Refusal::Version {
            device: PROTOCOL_VERSION,
            host: PROTOCOL_VERSION + 1
        }
    );
    let msg = r.to_string();
    assert!(
        msg.contains(&format!("version {}", PROTOCOL_VERSION))
            && msg.contains(&format!("version {}", PROTOCOL_VERSION + 1)),
        "{msg}"
    );
}

#[test]
fn a_duplicated_request_is_answered_again_but_acted_on_once() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 2);
    let x0 = h.status(&mut b).control.position_um[0];
    let seq = h.seq;
    let f = h.frame(
        seq,
        &Request::Jog {
            axis: Axis::X,
            um: 3_000,
        },
    );
    let first = h.raw(&mut b, &f);
    let again = h.raw(&mut b, &f);
    assert_eq!(first.len(), 1);
    assert_eq!(first, again, "the duplicate got another answer");
    h.seq = seq + 1;
    let s = h.wait(&mut b, |s| s.control.mode == Mode::Idle);
    assert_eq!(s.control.position_um[0], x0 + 3_000, "moved twice?");
    assert!(b.link.stats().duplicates >= 1);
}

#[test]
fn out_of_order_and_corrupted_chunks_are_never_written() {
    let (mut b, mut h) = configured();
    let (hd, body) = small_job(&config(), 20);
    h.ok(&mut b, &Request::BeginJob(hd.clone()));
    b.advance(1000);
    let seq = h.seq;
    let chunks: Vec<&[u8]> = body.chunks(MAX_CHUNK).collect();
    assert!(chunks.len() >= 3);
    // Chunk 1 before chunk 0: dropped, and the answer says which is expected.
    let f1 = h.frame(
        seq + 1,
        &Request::Chunk {
            offset: MAX_CHUNK as u32,
            data: chunks[1],
        },
    );
    let r = h.raw(&mut b, &f1);
    assert_eq!(r.len(), 1);
    assert_eq!(r[0].0.next, seq);
    assert_eq!(r[0].1, Reply::Ack);
    // Chunk 0 with a flipped bit: dropped unanswered.
    let mut f0 = h.frame(
        seq,
        &Request::Chunk {
            offset: 0,
            data: chunks[0],
        },
    );
    f0[40] ^= 0x10;
    assert!(h.raw(&mut b, &f0).is_empty());
    // Nothing was taken.
    match b.link.job() {
        JobSlot::Receiving { received, .. } => assert_eq!(received, 0),
        other => panic!("{other:?}"),
    }
    assert_eq!(b.link.stats().out_of_order, 1);
    assert_eq!(b.link.stats().bad, 1);
    // A chunk at the wrong offset with the right sequence number is refused.
    let r = h.refused(
        &mut b,
        &Request::Chunk {
            offset: 8,
            data: chunks[0],
        },
    );
    assert_eq!(
        r,
        Refusal::ChunkOffset {
            expected: 0,
            got: 8
        }
    );
}

#[test]
fn chunks_beyond_the_credit_are_not_taken() {
    let (mut b, mut h) = configured();
    let (hd, body) = small_job(&config(), 60);
    h.ok(&mut b, &Request::BeginJob(hd.clone()));
    b.advance(1000);
    let chunks: Vec<&[u8]> = body.chunks(MAX_CHUNK).collect();
    assert!(chunks.len() > WINDOW + 2);
    // All at once, without letting the board write anything in between.
    let mut bytes = Vec::new();
    for (i, c) in chunks.iter().enumerate().take(WINDOW + 2) {
        bytes.extend(h.frame(
            h.seq + i as u16,
            &Request::Chunk {
                offset: (i * MAX_CHUNK) as u32,
                data: c,
            },
        ));
    }
    b.receive(&bytes);
    // The first chunk past the credit is not taken; the one after it is then ahead of
    // the expected number and dropped as out of order.
    assert_eq!(b.link.stats().no_room, 1);
    assert_eq!(b.link.stats().out_of_order, 1);
    match b.link.job() {
        JobSlot::Receiving { received, .. } => assert_eq!(received as usize, WINDOW * MAX_CHUNK),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_late_hello_of_an_old_session_cannot_take_the_link_back() {
    let mut b = board();
    let mut old = Host {
        session: 1,
        ..Host::default()
    };
    old.hello(&mut b);
    let stale = old.frame(
        old.seq - 1,
        &Request::Hello {
            version: PROTOCOL_VERSION,
        },
    );
    let mut new = Host {
        session: 2,
        ..Host::default()
    };
    new.hello(&mut b);
    assert!(old.raw(&mut b, &stale).is_empty());
    let _ = new.status(&mut b);
}

#[test]
fn bad_configs_are_refused_naming_the_field() {
    let mut b = board();
    let mut h = Host::default();
    h.hello(&mut b);
    let mut c = config();
    c.channel.nozzle_diameter_mm = -1.0;
    let r = h.refused(&mut b, &Request::LoadConfig(c));
    assert!(r.to_string().contains("channel.nozzle_diameter_mm"), "{r}");
    let mut c = config();
    c.motion.max_step_rate_hz = 200_000.0;
    c.motion.max_speed_mm_s = [150.0, 150.0, 20.0];
    let r = h.refused(&mut b, &Request::LoadConfig(c));
    assert!(r.to_string().contains("max_step_rate_hz"), "{r}");
    assert_eq!(b.snapshot().mode, Mode::Unconfigured);
}

#[test]
fn bad_job_headers_are_refused_with_reasons() {
    let mut b = board();
    let mut h = Host::default();
    h.hello(&mut b);
    let cfg = config();
    let (hd, _) = small_job(&cfg, 2);
    assert_eq!(
        h.refused(&mut b, &Request::BeginJob(hd.clone())),
        Refusal::NoConfig
    );
    h.ok(&mut b, &Request::LoadConfig(cfg.clone()));
    b.advance(1000);
    let mut wrong = hd.clone();
    wrong.config_hash ^= 1;
    assert!(matches!(
        h.refused(&mut b, &Request::BeginJob(wrong)),
        Refusal::ConfigMismatch { .. }
    ));
    let mut big = hd.clone();
    big.body_len = b.link.store().capacity() + 1;
    assert!(matches!(
        h.refused(&mut b, &Request::BeginJob(big)),
        Refusal::JobTooLarge { .. }
    ));
    let mut ver = hd.clone();
    ver.format_version = dollop::job::FORMAT_VERSION_MAX + 1;
    let r = h.refused(&mut b, &Request::BeginJob(ver));
    assert!(r.to_string().contains("re-slice"), "{r}");
    let mut mat = hd.clone();
    mat.initial_material = 7;
    assert!(matches!(
        h.refused(&mut b, &Request::BeginJob(mat)),
        Refusal::JobHeader(_)
    ));
    assert_eq!(h.refused(&mut b, &Request::EndJob), Refusal::NotUploading);
    assert_eq!(h.refused(&mut b, &Request::Start), Refusal::NoJob);
}

#[test]
fn an_incomplete_or_corrupt_body_never_starts() {
    let (mut b, mut h) = configured();
    let (hd, body) = small_job(&config(), 4);
    h.ok(&mut b, &Request::BeginJob(hd.clone()));
    b.advance(1000);
    h.ok(
        &mut b,
        &Request::Chunk {
            offset: 0,
            data: &body[..MAX_CHUNK.min(body.len() - 4) / 4 * 4],
        },
    );
    let r = h.refused(&mut b, &Request::EndJob);
    assert!(
        matches!(r, Refusal::Job(JobFailure::BodyLength { .. })),
        "{r:?}"
    );
    // The whole body, but one byte differs from what the header's CRC says.
    let mut bad = body.clone();
    let n = bad.len();
    bad[n / 2] ^= 0x01;
    h.ok(&mut b, &Request::BeginJob(hd.clone()));
    b.advance(1000);
    h.chunks(&mut b, &bad, 0);
    h.ok(&mut b, &Request::EndJob);
    b.advance(50_000);
    let s = h.status(&mut b);
    assert!(matches!(s.job, JobSlot::Failed { .. }), "{s:?}");
    h.home(&mut b);
    let r = h.refused(&mut b, &Request::Start);
    assert!(matches!(r, Refusal::Job(_)), "{r:?}");
    assert!(r.to_string().contains("upload the job again"));
}

#[test]
fn uploads_are_refused_while_something_moves() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 20);
    h.ok(&mut b, &Request::Start);
    h.wait(&mut b, |s| s.control.mode == Mode::Job);
    let (hd, _) = small_job(&config(), 2);
    assert_eq!(
        h.refused(&mut b, &Request::BeginJob(hd)),
        Refusal::Busy { mode: Mode::Job }
    );
    assert!(matches!(
        h.refused(&mut b, &Request::LoadConfig(config())),
        Refusal::Busy { .. }
    ));
    assert!(matches!(
        h.refused(
            &mut b,
            &Request::Valve {
                inlet: 0,
                open: true
            }
        ),
        Refusal::Busy { .. }
    ));
    assert_eq!(
        h.refused(
            &mut b,
            &Request::Valve {
                inlet: 9,
                open: true
            }
        ),
        Refusal::NoSuchInlet {
            inlet: 9,
            inlets: 2
        }
    );
}

#[test]
fn the_stored_job_feeds_every_command_once_in_order() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 6);
    // Watch the job queue: what the link hands the control loop, in order.
    h.ok(&mut b, &Request::Start);
    let s = h.wait(&mut b, |s| s.control.mode != Mode::Job && s.fed > 0);
    let (hd, _) = small_job(&config(), 6);
    assert_eq!(s.fed, hd.commands);
    assert_eq!(s.control.command, hd.commands - 1);
    let _ = Command::End;
}
