//! The host end of the link protocol (see `dollop::wire`): hello and version check,
//! request/reply with retries, job upload with a credit-limited sliding window and
//! go-back-N, resuming after a reconnect from the offset the board acknowledged, and
//! waiting for the board's check of the stored job. Transport-independent.

use super::job::JobFile;
use super::transport::{LinkError, Transport};
use dollop::wire::frame::Event;
use dollop::wire::{
    self, seq_after, DeviceHeader, FrameReader, HelloInfo, HostHeader, JobId, JobSlot, Refusal,
    Reply, Request, Status, MAX_CHUNK, MAX_FRAME, PROTOCOL_VERSION,
};
use rand::{RngExt, SeedableRng};
use std::collections::VecDeque;
use std::time::Duration;

/// Timing and persistence of the client.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// Time to wait for an answer before sending again.
    pub rto: Duration,
    /// Sends of one request before the client reconnects.
    pub tries: u32,
    /// Reconnects per operation before giving up.
    pub reconnects: u32,
    /// Longest an upload may go without progress.
    pub stall_limit: Duration,
    /// Status polling interval while waiting.
    pub poll: Duration,
}

impl Default for Options {
    /// For a USB serial port: answers take about a millisecond.
    fn default() -> Self {
        Options {
            rto: Duration::from_millis(300),
            tries: 8,
            reconnects: 10,
            stall_limit: Duration::from_secs(20),
            poll: Duration::from_millis(100),
        }
    }
}

/// Counters for tests and benchmarks.
#[derive(Clone, Copy, Debug, Default)]
pub struct ClientStats {
    /// Frames sent.
    pub sent: u64,
    /// Frames received that decoded.
    pub received: u64,
    /// Frames received that did not decode.
    pub bad: u64,
    /// Frames sent again.
    pub retransmits: u64,
    /// Reconnects.
    pub reconnects: u64,
}

/// Progress of an upload.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Body bytes the board acknowledged.
    pub acked: u64,
    /// Body bytes in all.
    pub total: u64,
}

/// A link to one board.
pub struct Client<T: Transport> {
    t: T,
    opts: Options,
    session: u16,
    seq: u16,
    credit: u8,
    reader: Box<FrameReader>,
    inbuf: Vec<u8>,
    inpos: usize,
    info: Option<HelloInfo>,
    rng: rand::rngs::StdRng,
    /// Hellos unanswered since the last answer (what `on_silence` is told).
    hellos_unanswered: u32,
    /// Told after each hello that went unanswered (see `on_silence`).
    silence: Option<Box<dyn FnMut(Silence) + Send>>,
    /// What happened so far.
    pub stats: ClientStats,
}

/// How long a board has been silent while the client says hello (`Client::on_silence`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Silence {
    /// Hellos sent so far in this connect, all unanswered.
    pub tries: u32,
    /// How many the connect sends before it gives up.
    pub of: u32,
}

impl<T: Transport> Client<T> {
    /// A client on `t`; `seed` picks session ids (any value; tests pass theirs).
    pub fn new(t: T, opts: Options, seed: u64) -> Self {
        Client {
            t,
            opts,
            session: 0,
            seq: 0,
            credit: 0,
            reader: Box::new(FrameReader::new()),
            inbuf: Vec::new(),
            inpos: 0,
            info: None,
            rng: rand::rngs::StdRng::seed_from_u64(seed),
            hellos_unanswered: 0,
            silence: None,
            stats: ClientStats::default(),
        }
    }

    /// Calls `f` after each hello the board leaves unanswered (every `rto`), so a command
    /// can say what it is waiting for instead of staying silent until the connect gives up.
    pub fn on_silence(&mut self, f: impl FnMut(Silence) + Send + 'static) {
        self.silence = Some(Box::new(f));
    }

    /// A client with a session-id seed from the clock.
    pub fn open(t: T, opts: Options) -> Self {
        let seed = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() as u64)
            .unwrap_or(1);
        Self::new(t, opts, seed ^ std::process::id() as u64)
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.t
    }
    /// The transport, to change.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.t
    }
    /// What the board said in the last hello.
    pub fn info(&self) -> Option<&HelloInfo> {
        self.info.as_ref()
    }
    /// Options in force.
    pub fn options(&self) -> Options {
        self.opts
    }

    fn send_frame(&mut self, seq: u16, req: &Request<'_>) -> Result<(), LinkError> {
        // A leading delimiter ends whatever noise or cut frame came before, so this frame
        // is never lost by merging with it.
        let mut buf = [0u8; MAX_FRAME + 2];
        let hdr = HostHeader {
            session: self.session,
            seq,
        };
        let n = wire::encode(&hdr, req, &mut buf[1..])
            .map_err(|e| LinkError::Protocol(format!("cannot encode request: {e}")))?;
        self.stats.sent += 1;
        self.t.send(&buf[..n + 1])
    }

    /// The next reply of our session, or None at `deadline`.
    fn next_frame(
        &mut self,
        deadline: Duration,
    ) -> Result<Option<(DeviceHeader, Reply)>, LinkError> {
        loop {
            while self.inpos < self.inbuf.len() {
                let (n, ev) = self.reader.feed(&self.inbuf[self.inpos..]);
                self.inpos += n;
                let Some(Event::Frame(len)) = ev else {
                    continue;
                };
                let frame = self.reader.frame(len);
                let Ok(payload) = wire::open(frame) else {
                    self.stats.bad += 1;
                    continue;
                };
                match wire::parse::<DeviceHeader, Reply>(payload) {
                    Ok((h, r)) if h.session == self.session => {
                        self.stats.received += 1;
                        return Ok(Some((h, r)));
                    }
                    Ok(_) => {}
                    Err(_) => match wire::peek_hello::<DeviceHeader>(payload) {
                        Some((h, v)) if h.session == self.session && v != PROTOCOL_VERSION => {
                            return Err(LinkError::Version {
                                device: v,
                                host: PROTOCOL_VERSION,
                            });
                        }
                        _ => self.stats.bad += 1,
                    },
                }
            }
            self.inbuf.clear();
            self.inpos = 0;
            let now = self.t.now();
            if now >= deadline {
                return Ok(None);
            }
            let mut buf = [0u8; 4096];
            let n = self.t.recv(&mut buf, deadline - now)?;
            self.inbuf.extend_from_slice(&buf[..n]);
        }
    }

    /// Opens a session: checks the protocol version, learns the board's state.
    pub fn hello(&mut self) -> Result<HelloInfo, LinkError> {
        self.session = self.rng.random();
        self.seq = self.rng.random();
        self.reader.clear();
        self.inbuf.clear();
        self.inpos = 0;
        let seq = self.seq;
        for _ in 0..self.opts.tries {
            self.send_frame(
                seq,
                &Request::Hello {
                    version: PROTOCOL_VERSION,
                },
            )?;
            let deadline = self.t.now() + self.opts.rto;
            while let Some((h, reply)) = self.next_frame(deadline)? {
                if let Reply::Hello(info) = reply {
                    if info.version != PROTOCOL_VERSION {
                        return Err(LinkError::Version {
                            device: info.version,
                            host: PROTOCOL_VERSION,
                        });
                    }
                    self.seq = seq.wrapping_add(1);
                    self.credit = h.credit;
                    self.hellos_unanswered = 0;
                    self.info = Some(info.clone());
                    return Ok(info);
                }
            }
            self.stats.retransmits += 1;
            self.hellos_unanswered += 1;
            if let Some(f) = self.silence.as_mut() {
                f(Silence {
                    tries: self.hellos_unanswered,
                    of: self.opts.tries * (self.opts.reconnects + 1),
                });
            }
        }
        Err(LinkError::NoAnswer {
            tries: self.opts.tries,
        })
    }

    /// Says hello, reconnecting on transient failures (up to `reconnects` times).
    pub fn connect(&mut self) -> Result<HelloInfo, LinkError> {
        let mut left = self.opts.reconnects;
        let mut r = self.hello();
        while let Err(e) = &r {
            if !e.is_transient() || left == 0 {
                break;
            }
            left -= 1;
            r = self.reconnect();
        }
        r
    }

    /// Reopens the transport and says hello again.
    pub fn reconnect(&mut self) -> Result<HelloInfo, LinkError> {
        self.stats.reconnects += 1;
        self.t.reconnect()?;
        self.hello()
    }

    /// One request and its reply, sent again on silence; no reconnecting.
    pub fn call_once(&mut self, req: &Request<'_>) -> Result<Reply, LinkError> {
        let seq = self.seq;
        let wants_status = matches!(req, Request::Status);
        for _ in 0..self.opts.tries {
            self.send_frame(seq, req)?;
            let deadline = self.t.now() + self.opts.rto;
            while let Some((h, reply)) = self.next_frame(deadline)? {
                self.credit = h.credit;
                match reply {
                    Reply::Refused(Refusal::NoSession) if h.answers == seq => {
                        return Err(LinkError::NoSession)
                    }
                    Reply::Refused(Refusal::Version { device, host }) => {
                        return Err(LinkError::Version { device, host })
                    }
                    _ if h.answers != seq || h.next != seq.wrapping_add(1) => continue,
                    Reply::Ack if wants_status => continue,
                    Reply::Hello(_) => continue,
                    r => {
                        self.seq = seq.wrapping_add(1);
                        return Ok(r);
                    }
                }
            }
            self.stats.retransmits += 1;
        }
        Err(LinkError::NoAnswer {
            tries: self.opts.tries,
        })
    }

    /// A request with reconnects on transient failures. Only for requests that may be
    /// carried out twice without harm (all but jogs).
    pub fn call(&mut self, req: &Request<'_>) -> Result<Reply, LinkError> {
        self.retrying(|c| c.call_once(req))
    }

    /// Runs `attempt`, reconnecting and running it again after each transient failure,
    /// up to `reconnects` times; a failed reconnect that is itself transient uses no try.
    fn retrying<V>(
        &mut self,
        mut attempt: impl FnMut(&mut Self) -> Result<V, LinkError>,
    ) -> Result<V, LinkError> {
        let mut left = self.opts.reconnects;
        loop {
            match attempt(self) {
                Err(e) if e.is_transient() && left > 0 => {
                    left -= 1;
                    match self.reconnect() {
                        Ok(_) => {}
                        Err(e) if e.is_transient() => continue,
                        Err(e) => return Err(e),
                    }
                }
                r => return r,
            }
        }
    }

    /// A request that must be done: `Ack`, or the board's refusal as an error.
    pub fn command(&mut self, req: &Request<'_>) -> Result<(), LinkError> {
        match self.call(req)? {
            Reply::Ack => Ok(()),
            Reply::Refused(r) => Err(LinkError::Refused(r)),
            other => Err(LinkError::Protocol(format!("{other:?}"))),
        }
    }

    /// The board's status.
    pub fn status(&mut self) -> Result<Status, LinkError> {
        match self.call(&Request::Status)? {
            Reply::Status(s) => Ok(s),
            Reply::Refused(r) => Err(LinkError::Refused(r)),
            other => Err(LinkError::Protocol(format!("{other:?}"))),
        }
    }

    fn status_once(&mut self) -> Result<Status, LinkError> {
        match self.call_once(&Request::Status)? {
            Reply::Status(s) => Ok(s),
            Reply::Refused(r) => Err(LinkError::Refused(r)),
            other => Err(LinkError::Protocol(format!("{other:?}"))),
        }
    }

    /// Waits `d` on the transport's clock.
    pub fn sleep(&mut self, d: Duration) {
        self.t.sleep(d);
    }

    /// Uploads `job` (continuing a partial upload of the same job if the board holds
    /// one), then waits until the board has checked it. Returns the commands and print
    /// segments the board counted.
    pub fn upload(
        &mut self,
        job: &JobFile,
        progress: &mut dyn FnMut(Progress),
    ) -> Result<(u32, u32), LinkError> {
        self.retrying(|c| {
            c.upload_once(job, progress)
                .and_then(|()| c.wait_checked(job))
        })
    }

    fn upload_once(
        &mut self,
        job: &JobFile,
        progress: &mut dyn FnMut(Progress),
    ) -> Result<(), LinkError> {
        let id = JobId::of(&job.header);
        let total = job.body.len() as u64;
        let start = match self.status_once()?.job {
            JobSlot::Verifying { id: i, .. } | JobSlot::Ready { id: i, .. } if i == id => {
                progress(Progress {
                    acked: total,
                    total,
                });
                return Ok(());
            }
            JobSlot::Receiving { id: i, received } if i == id => received as usize,
            JobSlot::Preparing { id: i } if i == id => 0,
            _ => {
                match self.call_once(&Request::BeginJob(job.header.clone()))? {
                    Reply::Ack => {}
                    Reply::Refused(r) => return Err(LinkError::Refused(r)),
                    other => return Err(LinkError::Protocol(format!("{other:?}"))),
                }
                0
            }
        };
        progress(Progress {
            acked: start as u64,
            total,
        });
        self.stream(&job.body, start, progress)?;
        match self.call_once(&Request::EndJob)? {
            Reply::Ack => Ok(()),
            Reply::Refused(r) => Err(LinkError::Refused(r)),
            other => Err(LinkError::Protocol(format!("{other:?}"))),
        }
    }

    /// Sends `body[start..]` in chunks, at most `credit` beyond the board's `next`,
    /// going back to the first unacknowledged chunk on silence or repeated acks.
    fn stream(
        &mut self,
        body: &[u8],
        start: usize,
        progress: &mut dyn FnMut(Progress),
    ) -> Result<(), LinkError> {
        let total = body.len() as u64;
        let mut base = start;
        let mut next_off = start;
        // (seq, offset, length) of chunks sent and not yet acknowledged.
        let mut inflight: VecDeque<(u16, usize, usize)> = VecDeque::new();
        let mut last_progress = self.t.now();
        let mut dups = 0u32;
        // Base offset of the last fast retransmit: once per lost chunk, or the answers to
        // the resent chunks would trigger the next resend (an ack storm).
        let mut fast_at: Option<usize> = None;
        while base < body.len() {
            while next_off < body.len() && inflight.len() < self.credit as usize {
                let n = MAX_CHUNK.min(body.len() - next_off);
                let seq = self.seq;
                self.send_frame(
                    seq,
                    &Request::Chunk {
                        offset: next_off as u32,
                        data: &body[next_off..next_off + n],
                    },
                )?;
                inflight.push_back((seq, next_off, n));
                self.seq = seq.wrapping_add(1);
                next_off += n;
            }
            let now = self.t.now();
            if now.saturating_sub(last_progress) > self.opts.stall_limit {
                return Err(LinkError::Stalled {
                    secs: (now - last_progress).as_secs_f64(),
                });
            }
            if inflight.is_empty() {
                // No credit (the board is still making room): ask again shortly.
                self.t.sleep(self.opts.poll / 4);
                let s = self.status_once()?;
                if !matches!(s.job, JobSlot::Preparing { .. } | JobSlot::Receiving { .. }) {
                    return Err(LinkError::JobLost);
                }
                continue;
            }
            let deadline = now + self.opts.rto;
            match self.next_frame(deadline)? {
                Some((h, reply)) => {
                    self.credit = h.credit;
                    if let Reply::Refused(r) = reply {
                        if inflight.iter().any(|f| f.0 == h.answers) {
                            return Err(match r {
                                Refusal::NoSession => LinkError::NoSession,
                                Refusal::NotUploading => LinkError::JobLost,
                                r => LinkError::Refused(r),
                            });
                        }
                        continue;
                    }
                    let mut moved = false;
                    while let Some(&(s, off, n)) = inflight.front() {
                        if seq_after(h.next, s) {
                            inflight.pop_front();
                            base = off + n;
                            moved = true;
                        } else {
                            break;
                        }
                    }
                    if moved {
                        dups = 0;
                        last_progress = self.t.now();
                        progress(Progress {
                            acked: base as u64,
                            total,
                        });
                    } else if inflight.front().is_some_and(|f| f.0 == h.next) {
                        // The board expects the first chunk in flight again: it was lost.
                        dups += 1;
                        if dups >= 2 && fast_at != Some(base) {
                            dups = 0;
                            fast_at = Some(base);
                            self.resend(body, &inflight)?;
                        }
                    }
                }
                None => self.resend(body, &inflight)?,
            }
        }
        Ok(())
    }

    fn resend(
        &mut self,
        body: &[u8],
        inflight: &VecDeque<(u16, usize, usize)>,
    ) -> Result<(), LinkError> {
        for &(seq, off, n) in inflight {
            self.stats.retransmits += 1;
            self.send_frame(
                seq,
                &Request::Chunk {
                    offset: off as u32,
                    data: &body[off..off + n],
                },
            )?;
        }
        Ok(())
    }

    /// Polls until the board has checked the stored job.
    fn wait_checked(&mut self, job: &JobFile) -> Result<(u32, u32), LinkError> {
        let id = JobId::of(&job.header);
        let mut last = self.t.now();
        let mut last_checked = u32::MAX;
        loop {
            match self.status_once()?.job {
                JobSlot::Ready {
                    id: i,
                    commands,
                    segments,
                } if i == id => return Ok((commands, segments)),
                JobSlot::Failed { id: i, why } if i == id => return Err(LinkError::JobFailed(why)),
                JobSlot::Verifying { id: i, checked } if i == id => {
                    if checked != last_checked {
                        last_checked = checked;
                        last = self.t.now();
                    }
                }
                JobSlot::Receiving { id: i, .. } if i == id => {}
                _ => return Err(LinkError::JobLost),
            }
            if self.t.now().saturating_sub(last) > self.opts.stall_limit {
                return Err(LinkError::Stalled {
                    secs: self.opts.stall_limit.as_secs_f64(),
                });
            }
            self.t.sleep(self.opts.poll / 4);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    /// A port with nothing behind it: sends vanish, nothing arrives, time is virtual.
    struct Silent {
        now: Duration,
    }

    impl Transport for Silent {
        fn send(&mut self, _: &[u8]) -> Result<(), LinkError> {
            Ok(())
        }
        fn recv(&mut self, _: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
            self.now += timeout;
            Ok(0)
        }
        fn now(&self) -> Duration {
            self.now
        }
        fn sleep(&mut self, d: Duration) {
            self.now += d;
        }
        fn reconnect(&mut self) -> Result<(), LinkError> {
            Ok(())
        }
    }

    #[test]
    fn a_silent_board_is_reported_at_every_unanswered_hello() {
        let opts = Options {
            tries: 3,
            reconnects: 1,
            ..Options::default()
        };
        let mut c = Client::new(
            Silent {
                now: Duration::ZERO,
            },
            opts,
            7,
        );
        let told = Arc::new(Mutex::new(Vec::new()));
        let log = told.clone();
        c.on_silence(move |s| log.lock().unwrap().push((s.tries, s.of)));
        let r = c.connect();
        assert!(matches!(r, Err(LinkError::NoAnswer { tries: 3 })), "{r:?}");
        let told = told.lock().unwrap();
        // Told after the first rto already, then after each hello, counting across the
        // reconnect, out of every hello the connect will send.
        assert_eq!(*told, vec![(1, 6), (2, 6), (3, 6), (4, 6), (5, 6), (6, 6)]);
    }
}
