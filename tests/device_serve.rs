//! The link loop (`dollop::device::serve`) on doubles of the board's USB port and
//! millisecond pace: it yields on every path (a closed port that reports "ready" at once
//! cannot make it spin: the USB livelock), and a host that stops reading cannot hold back
//! the link's background work, so the link-loss policy still closes a valve test.

mod device_support;

use core::future::Future;
use core::pin::pin;
use core::task::{Context, Poll, Waker};
use device_support::*;
use dollop::device::serve::{EitherPort, WRITE_TIMEOUT_TICKS};
use dollop::device::sim_board::SIM_INFO;
use dollop::device::{
    serve, BoardLink, ControlOrder, HostPort, Inputs, JobRecord, Pace, PortClosed, Queues,
    RamStore, ToControl,
};
use dollop::wire::*;
use std::cell::{Cell, RefCell};
use std::collections::VecDeque;
use std::rc::Rc;

/// What the doubles share with the test: the board, virtual time, and how many port
/// calls happened since the loop last yielded.
#[derive(Default)]
struct World {
    now_us: Cell<u64>,
    calls_since_yield: Cell<u32>,
    ticks: Cell<u64>,
}

impl World {
    fn port_call(&self) {
        let n = self.calls_since_yield.get() + 1;
        self.calls_since_yield.set(n);
        assert!(
            n < 10_000,
            "the link loop spins without yielding (livelock)"
        );
    }
}

#[derive(Default)]
struct Wire {
    incoming: RefCell<VecDeque<Vec<u8>>>,
    sent: RefCell<Vec<u8>>,
    open: Cell<bool>,
}

struct Port {
    w: Rc<World>,
    wire: Rc<Wire>,
    /// Writes never complete: a host that stopped reading.
    stuck: bool,
}

impl Port {
    fn new(w: &Rc<World>, open: bool, stuck: bool) -> (Port, Rc<Wire>) {
        let wire = Rc::new(Wire::default());
        wire.open.set(open);
        (
            Port {
                w: w.clone(),
                wire: wire.clone(),
                stuck,
            },
            wire,
        )
    }
}

impl HostPort for Port {
    fn is_open(&mut self) -> bool {
        self.w.port_call();
        self.wire.open.get()
    }
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortClosed> {
        self.w.port_call();
        if !self.wire.open.get() {
            // As a USB endpoint no host configured: the read fails at once.
            return Err(PortClosed);
        }
        let wire = self.wire.clone();
        core::future::poll_fn(move |_| match wire.incoming.borrow_mut().pop_front() {
            Some(p) => {
                let n = p.len().min(buf.len());
                buf[..n].copy_from_slice(&p[..n]);
                Poll::Ready(Ok(n))
            }
            None => Poll::Pending,
        })
        .await
    }
    async fn write(&mut self, data: &[u8]) -> Result<(), PortClosed> {
        self.w.port_call();
        if self.stuck {
            return core::future::pending().await;
        }
        self.wire.sent.borrow_mut().extend_from_slice(data);
        Ok(())
    }
    fn needs_zero_length_end(&self) -> bool {
        true
    }
}

/// A pace whose tick yields once, then advances virtual time by 1 ms.
struct Millis {
    w: Rc<World>,
}

impl Pace for Millis {
    fn now_us(&mut self) -> u64 {
        self.w.now_us.get()
    }
    async fn tick(&mut self) {
        let mut yielded = false;
        core::future::poll_fn(|_| {
            if yielded {
                Poll::Ready(())
            } else {
                yielded = true;
                self.w.calls_since_yield.set(0);
                Poll::Pending
            }
        })
        .await;
        self.w.ticks.set(self.w.ticks.get() + 1);
    }
}

/// Polls `fut` `polls` times (a single-threaded executor with nothing else to run); runs
/// `between` after each poll (the board's control loop in virtual time).
fn drive<F: Future>(fut: F, polls: u32, mut between: impl FnMut()) {
    let mut fut = pin!(fut);
    let mut cx = Context::from_waker(Waker::noop());
    for _ in 0..polls {
        assert!(fut.as_mut().poll(&mut cx).is_pending());
        between();
    }
}

/// The link's end of the queues, shared with the control loop the test runs.
struct LinkEnd(Rc<RefCell<Queues>>);

impl ToControl for LinkEnd {
    fn order(&mut self, o: ControlOrder) -> Result<(), ControlOrder> {
        self.0.borrow_mut().order(o)
    }
    fn command(&mut self, r: JobRecord) -> Result<(), JobRecord> {
        self.0.borrow_mut().command(r)
    }
    fn command_room(&self) -> usize {
        self.0.borrow().command_room()
    }
    fn post_config(&mut self, c: &dollop::device::BoardMachine) -> bool {
        self.0.borrow_mut().post_config(c)
    }
    fn snapshot(&self) -> Snapshot {
        self.0.borrow().snapshot()
    }
}

/// Runs the loop on a board whose link and control loop are taken from `b`, for `ms`
/// milliseconds, the control loop ticking ten times a millisecond.
fn serve_board(b: &mut Board, w: &Rc<World>, mut port: impl HostPort, ms: u32) {
    let mut link = std::mem::replace(
        &mut b.link,
        BoardLink::new(RamStore::new(Vec::new()), SIM_INFO),
    );
    let queues = Rc::new(RefCell::new(std::mem::take(&mut b.queues)));
    let mut end = LinkEnd(queues.clone());
    let mut pace = Millis { w: w.clone() };
    w.now_us.set(b.now_us);
    {
        let fut = serve(&mut port, &mut pace, &mut link, &mut end);
        let control = &mut b.control;
        let out = &mut b.out;
        drive(fut, ms, || {
            for _ in 0..10 {
                let t = w.now_us.get() + 100;
                w.now_us.set(t);
                control.tick(t, Inputs::default(), &mut *queues.borrow_mut(), out);
            }
        });
    }
    b.now_us = w.now_us.get();
    b.link = link;
    b.queues = std::mem::take(&mut *queues.borrow_mut());
}

#[test]
fn a_closed_port_that_is_always_ready_does_not_stop_the_loop_yielding() {
    let w = Rc::new(World::default());
    let mut b = board();
    let (port, _) = Port::new(&w, false, false);
    serve_board(&mut b, &w, port, 200);
    // Every poll yielded (the double panics after 10 000 port calls without a yield), and
    // each poll was one pace tick: the USB stack and the control loop get their turn.
    assert!(w.ticks.get() >= 199, "{}", w.ticks.get());
}

fn hello(h: &Host) -> Vec<u8> {
    h.frame(
        h.seq,
        &Request::Hello {
            version: PROTOCOL_VERSION,
        },
    )
}

/// A ready board in a valve test with valve 0 open, and its host.
fn valve_test_open() -> (Board, Host) {
    let mut b = board();
    let mut h = Host::ready(&mut b, 1);
    h.ok(
        &mut b,
        &Request::Valve {
            inlet: 0,
            open: true,
        },
    );
    b.advance(300);
    assert_eq!(b.out.valves, 1);
    (b, h)
}

/// The replies sent on `wire` so far.
fn replies(wire: &Wire) -> Vec<Reply> {
    let sent = wire.sent.borrow().clone();
    let mut r = FrameReader::new();
    let mut out = Vec::new();
    let mut rest = &sent[..];
    while !rest.is_empty() {
        let (n, ev) = r.feed(rest);
        rest = &rest[n..];
        if let Some(dollop::wire::frame::Event::Frame(len)) = ev {
            out.push(decode::<DeviceHeader, Reply>(r.frame(len)).unwrap().1);
        }
    }
    out
}

#[test]
fn an_open_idle_port_answers_requests_and_keeps_yielding() {
    let w = Rc::new(World::default());
    let mut b = board();
    let h = Host::default();
    let (port, wire) = Port::new(&w, true, false);
    wire.incoming.borrow_mut().push_back(hello(&h));
    serve_board(&mut b, &w, port, 50);
    assert!(w.ticks.get() >= 49);
    let r = replies(&wire);
    assert!(matches!(r[..], [Reply::Hello(_)]), "{r:?}");
}

#[test]
fn a_host_that_stops_reading_cannot_keep_a_valve_test_open() {
    let w = Rc::new(World::default());
    let (mut b, h) = valve_test_open();
    // The host asks for its status and then reads nothing: the reply's write never ends.
    let (port, wire) = Port::new(&w, true, true);
    wire.incoming
        .borrow_mut()
        .push_back(h.frame(h.seq, &Request::Status));
    serve_board(&mut b, &w, port, WRITE_TIMEOUT_TICKS + 20);
    assert_eq!(
        b.out.valves, 0,
        "the valve test outlived a host that stopped reading"
    );
    assert!(b.link.job() != JobSlot::Empty);
}

#[test]
fn two_ports_share_one_link_and_replies_go_where_the_request_came_from() {
    let w = Rc::new(World::default());
    let mut b = board();
    // USB not open (no host), the UART always is.
    let (usb, usb_wire) = Port::new(&w, false, false);
    let (uart, uart_wire) = Port::new(&w, true, false);
    let mut h = Host::default();
    uart_wire.incoming.borrow_mut().push_back(hello(&h));
    serve_board(&mut b, &w, EitherPort::new(usb, uart), 20);
    assert!(matches!(replies(&uart_wire)[..], [Reply::Hello(_)]));
    assert!(replies(&usb_wire).is_empty());

    // A host opens USB and asks for the status in the same session: answered on USB.
    h.seq += 1;
    let (usb, usb_wire) = Port::new(&w, true, false);
    let (uart, uart_wire) = Port::new(&w, true, false);
    usb_wire
        .incoming
        .borrow_mut()
        .push_back(h.frame(h.seq, &Request::Status));
    serve_board(&mut b, &w, EitherPort::new(usb, uart), 20);
    let r = replies(&usb_wire);
    assert!(matches!(r[..], [Reply::Status(_)]), "{r:?}");
    assert!(replies(&uart_wire).is_empty());
}

#[test]
fn the_same_rules_hold_on_the_uart_a_silent_host_closes_a_valve_test() {
    let w = Rc::new(World::default());
    let (mut b, _host) = valve_test_open();
    // Over the UART (always open) the host falls silent: the link's timeout applies.
    let (usb, _) = Port::new(&w, false, false);
    let (uart, _) = Port::new(&w, true, false);
    serve_board(&mut b, &w, EitherPort::new(usb, uart), LINK_TIMEOUT_MS + 50);
    assert_eq!(b.out.valves, 0, "the valve test outlived a silent host");
}
