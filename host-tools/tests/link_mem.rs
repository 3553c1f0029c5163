//! The USB link end to end over the in-memory link: uploads under every kind of fault
//! (drops, duplicates, corruption, reordering, truncation, stalls, disconnects) arrive
//! exactly once and intact or end in a clear error; the board writes only the expected
//! chunk at the expected offset; jobs start, print, pause and resume over the link.

use dollop::wire::{JobSlot, Mode, Request};
use dollop::{Config, RunState};
use dollop_host::link::job::zigzag;
use dollop_host::link::mem::LogStore;
use dollop_host::link::{mem_options, Client, Faults, JobFile, LinkError, MemLink, BENCH_CONFIG};

fn config() -> Config {
    toml::from_str(BENCH_CONFIG).unwrap()
}

fn client(faults: Faults, seed: u64) -> Client<MemLink> {
    Client::new(MemLink::new(faults, seed), mem_options(), seed ^ 0x9E37)
}

/// Every write landed right after the previous one, once, with the job's bytes; the
/// store ends holding exactly the body.
fn assert_exactly_once(store: &LogStore, job: &JobFile) {
    let mut at = 0usize;
    for (off, data) in &store.writes {
        assert_eq!(*off as usize, at, "write at {off}, expected {at}");
        assert_eq!(
            &job.body[at..at + data.len()],
            &data[..],
            "bytes at {at} differ"
        );
        at += data.len();
    }
    assert_eq!(
        at,
        job.body.len(),
        "written {at} of {} bytes",
        job.body.len()
    );
    assert_eq!(&store.bytes()[..job.body.len()], &job.body[..]);
}

fn upload(c: &mut Client<MemLink>, job: &JobFile) -> Result<(u32, u32), LinkError> {
    c.connect()?;
    c.command(&Request::LoadConfig(config()))?;
    c.upload(job, &mut |_| {})
}

#[test]
fn clean_upload_arrives_once_and_checks() {
    let job = zigzag(&config(), 2_000);
    let mut c = client(Faults::default(), 1);
    let (commands, segments) = upload(&mut c, &job).unwrap();
    assert_eq!(commands, job.header.commands);
    assert_eq!(segments, job.header.print_segments);
    let board = c.transport().board();
    assert_exactly_once(board.link.store(), &job);
    let s = board.link.stats();
    assert_eq!(s.no_room, 0, "the host overran its credit");
    assert_eq!(s.bad, 0);
}

#[test]
fn hundred_thousand_segments_under_faults_arrive_exactly_once() {
    let job = zigzag(&config(), 100_000);
    assert!(job.segments() >= 100_000);
    let mut c = client(Faults::harsh(), 7);
    let (commands, _) = upload(&mut c, &job).unwrap();
    assert_eq!(commands, job.header.commands);
    let link = c.transport();
    assert_exactly_once(link.board().link.store(), &job);
    let st = link.stats;
    eprintln!(
        "{st:?} client {:?} board {:?}",
        c.stats,
        link.board().link.stats()
    );
    assert!(st.dropped > 0 && st.corrupted > 0 && st.duplicated > 0 && st.reordered > 0);
    assert!(st.truncated > 0);
    assert_eq!(link.board().link.stats().no_room, 0);
}

#[test]
fn many_seeds_under_faults_each_arrive_exactly_once() {
    let job = zigzag(&config(), 3_000);
    for seed in 0..24u64 {
        let mut f = Faults::harsh();
        // More disconnects and stalls than the long run, to hit them in short uploads.
        f.disconnect = 0.01;
        f.stall = 0.01;
        let mut c = client(f, seed);
        match upload(&mut c, &job) {
            Ok((commands, _)) => {
                assert_eq!(commands, job.header.commands, "seed {seed}");
                assert_exactly_once(c.transport().board().link.store(), &job);
            }
            Err(e) => panic!("seed {seed}: {e}"),
        }
    }
}

#[test]
fn a_dead_link_ends_in_a_clear_error() {
    let job = zigzag(&config(), 500);
    let mut c = client(Faults::default(), 3);
    c.hello().unwrap();
    c.command(&Request::LoadConfig(config())).unwrap();
    c.transport_mut().set_faults(Faults {
        drop: 1.0,
        ..Faults::default()
    });
    let e = c.upload(&job, &mut |_| {}).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, LinkError::NoAnswer { .. }), "{msg}");
    assert!(msg.contains("did not answer"), "{msg}");
    // Nothing half-written was taken as a job.
    assert!(!matches!(
        c.transport().board().link.job(),
        JobSlot::Ready { .. }
    ));
}

#[test]
fn upload_resumes_after_disconnect_from_the_last_acknowledged_chunk() {
    let job = zigzag(&config(), 5_000);
    let chunks = job.body.len().div_ceil(dollop::wire::MAX_CHUNK) as u64;
    let mut c = client(Faults::default(), 11);
    c.connect().unwrap();
    c.command(&Request::LoadConfig(config())).unwrap();
    c.transport_mut().disconnect_at = Some(chunks / 2);
    c.upload(&job, &mut |_| {}).unwrap();
    assert_eq!(c.stats.reconnects, 1);
    assert_eq!(c.transport().stats.disconnects, 1);
    assert_exactly_once(c.transport().board().link.store(), &job);
}

#[test]
fn a_new_sender_continues_a_broken_upload_where_the_board_stopped() {
    let job = zigzag(&config(), 5_000);
    let chunks = job.body.len().div_ceil(dollop::wire::MAX_CHUNK) as u64;
    let mut c = client(Faults::default(), 13);
    c.connect().unwrap();
    c.command(&Request::LoadConfig(config())).unwrap();
    // The cable dies for good half way: the first sender gives up with a clear error.
    c.transport_mut().dead_after = Some(c.transport().stats.host_frames + chunks / 2);
    let e = c.upload(&job, &mut |_| {}).unwrap_err();
    assert!(
        matches!(e, LinkError::Stalled { .. } | LinkError::NoAnswer { .. }),
        "{e}"
    );
    assert!(
        e.to_string().contains("dollop send") || e.to_string().contains("did not answer"),
        "{e}"
    );
    let mut link = std::mem::replace(c.transport_mut(), MemLink::new(Faults::default(), 0));
    let received = match link.board().link.job() {
        JobSlot::Receiving { received, .. } => received as usize,
        other => panic!("{other:?}"),
    };
    assert!(received > 0 && received < job.body.len());
    link.dead_after = None;
    let before = link.stats.host_frames;
    // A second `dollop send` of the same job.
    let mut c2 = Client::new(link, mem_options(), 99);
    c2.connect().unwrap();
    c2.upload(&job, &mut |_| {}).unwrap();
    let sent = c2.transport().stats.host_frames - before;
    let left = (job.body.len() - received).div_ceil(dollop::wire::MAX_CHUNK) as u64;
    assert!(
        sent < left + 20,
        "sent {sent} frames for {left} chunks left: not resumed"
    );
    assert_exactly_once(c2.transport().board().link.store(), &job);
}

#[test]
fn a_corrupt_store_fails_the_check_and_cannot_start() {
    let job = zigzag(&config(), 400);
    let mut c = client(Faults::default(), 5);
    c.hello().unwrap();
    c.command(&Request::LoadConfig(config())).unwrap();
    c.transport_mut()
        .board_mut()
        .link
        .store_mut()
        .fail_next_write = true;
    let e = c.upload(&job, &mut |_| {}).unwrap_err();
    assert!(
        matches!(e, LinkError::JobFailed(_) | LinkError::Refused(_)),
        "{e}"
    );
    let e = c.command(&Request::Start).unwrap_err();
    assert!(e.to_string().contains("upload"), "{e}");
}

#[test]
fn a_job_prints_to_the_end_over_the_link() {
    let cfg = config();
    let job = zigzag(&cfg, 120);
    let mut c = client(Faults::default(), 21);
    upload(&mut c, &job).unwrap();
    c.command(&Request::Home).unwrap();
    wait(&mut c, |s| s.control.homed && s.control.mode == Mode::Idle);
    c.command(&Request::Start).unwrap();
    wait(&mut c, |s| s.control.mode == Mode::Job);
    let s = wait(&mut c, |s| s.control.mode != Mode::Job);
    assert_eq!(s.control.run, RunState::Done, "{s:?}");
    assert_eq!(s.fed, job.header.commands);
    assert_eq!(
        s.control.command,
        job.header.commands - 1,
        "did not reach the End"
    );
    let out = &c.transport().board().out;
    assert_eq!(out.valves, 0);
    assert!(out.pulses[0] > 0);
}

#[test]
fn pause_and_resume_over_the_link() {
    let cfg = config();
    let job = zigzag(&cfg, 400);
    let mut c = client(Faults::default(), 23);
    upload(&mut c, &job).unwrap();
    c.command(&Request::Home).unwrap();
    wait(&mut c, |s| s.control.homed && s.control.mode == Mode::Idle);
    c.command(&Request::Start).unwrap();
    wait(&mut c, |s| s.control.run == RunState::Printing);
    c.command(&Request::Pause).unwrap();
    let s = wait(&mut c, |s| s.control.run == RunState::Paused);
    assert_eq!(s.control.valves, 0, "paused with a valve open");
    c.command(&Request::Resume).unwrap();
    let s = wait(&mut c, |s| s.control.mode != Mode::Job);
    assert_eq!(s.control.run, RunState::Done);
}

fn wait(
    c: &mut Client<MemLink>,
    done: impl Fn(&dollop::wire::Status) -> bool,
) -> dollop::wire::Status {
    for _ in 0..20_000 {
        let s = c.status().unwrap();
        if done(&s) {
            return s;
        }
        assert_ne!(s.control.mode, Mode::Halted, "halted: {:?}", s.control.halt);
        c.sleep(std::time::Duration::from_millis(50));
    }
    panic!("condition not reached");
}

#[test]
fn the_link_benchmark_reports_its_figures() {
    let r = dollop_host::link::bench_link();
    eprintln!("{r}");
    assert!(r.contains("frames/s") && !r.contains("failed"), "{r}");
}

/// Homing waited out as one typed operation (`link::ops::home_and_wait`, what `dollop
/// send` and `dollop jog --home` run): refused without a config, at rest and homed after,
/// and a halt comes back as a value carrying the board's status.
#[test]
fn homing_is_waited_out_and_a_halt_is_typed() {
    use dollop_host::link::ops::{self, WaitError};
    let mut c = client(Faults::default(), 31);
    c.connect().unwrap();
    let e = ops::home_and_wait(&mut c).unwrap_err();
    assert!(matches!(e, WaitError::Link(LinkError::Refused(_))), "{e}");
    c.command(&Request::LoadConfig(config())).unwrap();
    let s = ops::home_and_wait(&mut c).unwrap();
    assert!(s.control.homed && s.control.mode == Mode::Idle, "{s:?}");
    c.command(&Request::EStop).unwrap();
    match ops::wait_idle(&mut c, std::time::Duration::from_secs(1)) {
        Err(WaitError::Halted(s)) => assert_eq!(s.control.mode, Mode::Halted),
        other => panic!("{other:?}"),
    }
}
