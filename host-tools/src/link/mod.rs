//! The host end of the USB link: the protocol client (`client`), transports (a serial
//! port found by USB VID/PID in `serial`, a simulated board with fault injection in
//! `mem`), job files (`job`), the board operations both front ends run (`ops`), and the
//! link's throughput benchmark. The wire format
//! itself is `dollop::wire`, shared with the firmware.

pub mod client;
pub mod job;
pub mod mem;
pub mod ops;
pub mod serial;
pub mod transport;

pub use client::{Client, Options, Progress};
pub use job::JobFile;
pub use mem::{Faults, MemLink};
pub use serial::SerialLink;
pub use transport::{Cancelled, LinkError, Transport};

use dollop::wire::{self, HostHeader, Request, MAX_CHUNK, MAX_FRAME};
use dollop::Config;
use std::time::{Duration, Instant};

/// The machine config the link tests and benchmark load (the seed printhead with valves).
pub const BENCH_CONFIG: &str = include_str!("../../../configs/seed-paper-valves.toml");

/// Client options for the in-memory link (virtual time, so short waits cost nothing).
pub fn mem_options() -> Options {
    Options {
        rto: Duration::from_millis(30),
        tries: 8,
        reconnects: 20,
        stall_limit: Duration::from_secs(20),
        poll: Duration::from_millis(20),
    }
}

/// Measures the link code on this machine (one core): frame encode+decode rate for full
/// chunks, and a whole upload through the protocol client and the simulated board's link
/// logic (clean in-memory link). Returns a human-readable report.
pub fn bench_link() -> String {
    let mut out = String::new();
    // Codec alone: a full chunk frame encoded and decoded.
    let data = [0x5Au8; MAX_CHUNK];
    let mut buf = [0u8; MAX_FRAME + 1];
    let n_codec = 50_000u32;
    let t = Instant::now();
    let mut ok = 0u32;
    for i in 0..n_codec {
        let req = Request::Chunk {
            offset: i * MAX_CHUNK as u32,
            data: &data,
        };
        let hdr = HostHeader {
            session: 1,
            seq: i as u16,
        };
        if let Ok(n) = wire::encode(&hdr, &req, &mut buf) {
            if wire::decode::<HostHeader, Request<'_>>(&mut buf[..n - 1]).is_ok() {
                ok += 1;
            }
        }
    }
    let s = t.elapsed().as_secs_f64();
    out.push_str(&format!(
        "link codec: {ok} chunk frames ({MAX_CHUNK} B) encoded+decoded in {s:.3} s = {:.0} frames/s ({:.1} MB/s)\n",
        ok as f64 / s,
        ok as f64 * MAX_CHUNK as f64 / s / 1e6
    ));
    // Whole upload over a clean in-memory link.
    let config: Config = match toml::from_str(BENCH_CONFIG) {
        Ok(c) => c,
        Err(e) => return format!("{out}link upload: bench config does not parse: {e}\n"),
    };
    let job = job::zigzag(&config, 100_000);
    let mut client = Client::new(MemLink::new(Faults::default(), 1), mem_options(), 1);
    let t = Instant::now();
    let r = client
        .hello()
        .and_then(|_| client.command(&Request::LoadConfig(config.clone())))
        .and_then(|()| client.upload(&job, &mut |_| {}));
    let s = t.elapsed().as_secs_f64();
    let link = client.transport();
    let frames = link.stats.host_frames + link.stats.board_frames;
    let virt = link.now().as_secs_f64();
    match r {
        Ok((commands, _)) => out.push_str(&format!(
            "link upload: {} segments ({} commands, {} B) through client + simulated board in {s:.3} s: {frames} frames = {:.0} frames/s, {:.2} MB/s (1 core; board time {virt:.2} s)\n",
            job.segments(),
            commands,
            job.body.len(),
            frames as f64 / s,
            job.body.len() as f64 / s / 1e6
        )),
        Err(e) => out.push_str(&format!("link upload failed: {e}\n")),
    }
    out
}
