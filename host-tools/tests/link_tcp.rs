//! The board's link over TCP (`--port tcp:HOST:PORT`, what an emulated board's UART or a
//! serial server offers): the `dollop` command talks to a simulated board behind a local
//! socket; a bad address is refused with the form to use.

use dollop::device::{RamStore, SimBoard};
use std::io::{Read, Write};
use std::net::TcpListener;
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// A simulated board serving one TCP connection in real time until `stop`.
fn board_on_socket(listener: TcpListener, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        s.set_read_timeout(Some(Duration::from_millis(1))).unwrap();
        let mut b = SimBoard::new(RamStore::new(vec![0xFF; 64 * 1024]));
        let mut buf = [0u8; 512];
        while !stop.load(Ordering::Relaxed) {
            match s.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => b.receive(&buf[..n]),
                Err(_) => {}
            }
            b.advance(1000);
            let n = b.take_tx(&mut buf);
            if n > 0 && s.write_all(&buf[..n]).is_err() {
                break;
            }
        }
    })
}

#[test]
fn status_over_tcp_reaches_the_board() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let board = board_on_socket(listener, stop.clone());
    let out = Command::new(env!("CARGO_BIN_EXE_dollop"))
        .args(["status", "--port", &format!("tcp:{addr}")])
        .output()
        .unwrap();
    stop.store(true, Ordering::Relaxed);
    board.join().unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("sim"), "the board's name is missing: {text}");
}

#[test]
fn a_bad_tcp_address_says_the_form() {
    for port in ["tcp:nowhere", "tcp:127.0.0.1:1"] {
        let out = Command::new(env!("CARGO_BIN_EXE_dollop"))
            .args(["status", "--port", port])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(err.contains("tcp:HOST:PORT") && err.contains(port), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    }
}
