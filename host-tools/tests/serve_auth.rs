//! `dollop serve --auth`: every route (page, script, API, status stream, board orders)
//! refuses a request without the key; the key as a bearer header or a signed-in session
//! cookie is let through; a wrong key on the sign-in form is refused; listening beyond
//! loopback without `--auth` does not start. Plain HTTP/1.1 over a socket, no browser.

mod serve_common;

use dollop_host::serve;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};

fn args(listen: &str, auth: Option<&str>) -> serve::Args {
    serve::Args {
        listen: listen.parse().expect("address"),
        auth: auth.map(String::from),
        sim_speed: 1.0,
        ..serve_common::args()
    }
}

/// Sends one request; returns the status line's code and the head (headers) as text.
fn request(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[&str],
    body: &str,
) -> (u16, String) {
    let mut s = TcpStream::connect(addr).expect("connects");
    s.set_read_timeout(Some(std::time::Duration::from_secs(10)))
        .expect("timeout");
    let mut req = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for h in headers {
        req.push_str(h);
        req.push_str("\r\n");
    }
    req.push_str(&format!("Content-Length: {}\r\n\r\n{body}", body.len()));
    s.write_all(req.as_bytes()).expect("sends");
    // Enough to see the status and the headers (the status stream never ends).
    let mut buf = vec![0u8; 4096];
    let mut got = 0;
    while got < buf.len() {
        match s.read(&mut buf[got..]) {
            Ok(0) | Err(_) => break,
            Ok(n) => got += n,
        }
        if buf[..got].windows(4).any(|w| w == b"\r\n\r\n") {
            break;
        }
    }
    let text = String::from_utf8_lossy(&buf[..got]).into_owned();
    let code = text
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status in {text:?}"));
    (code, text)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_route_refuses_a_request_without_the_key() {
    let r = serve::start(args("127.0.0.1:0", Some("correct horse")))
        .await
        .expect("starts");
    let a = r.addr;
    tokio::task::spawn_blocking(move || {
        let json = "Content-Type: application/json";
        let refused: [(&str, &str, &[&str], &str); 6] = [
            ("GET", "/assets/app.js", &[], ""),
            ("GET", "/api/info", &[], ""),
            ("GET", "/api/boards/events?tab=t", &[], ""),
            ("POST", "/api/boards/0/abort", &[json], "{\"tab\":\"t\"}"),
            (
                "GET",
                "/api/info",
                &["Authorization: Bearer wrong horse"],
                "",
            ),
            (
                "GET",
                "/api/info",
                &["Cookie: dollop_session=0123456789abcdef"],
                "",
            ),
        ];
        for (m, p, h, b) in refused {
            let (code, head) = request(a, m, p, h, b);
            assert_eq!(code, 401, "{m} {p} {h:?}: {head}");
        }
        // A browser's page load goes to the sign-in form, which (and the icon) is open.
        let (code, head) = request(a, "GET", "/", &["Accept: text/html"], "");
        assert_eq!(code, 303, "{head}");
        assert!(head.to_lowercase().contains("location: /login"), "{head}");
        assert_eq!(request(a, "GET", "/login", &[], "").0, 200);
        assert_eq!(request(a, "GET", "/favicon.svg", &[], "").0, 200);
        // The key, as a header.
        let (code, head) = request(
            a,
            "GET",
            "/api/info",
            &["Authorization: Bearer correct horse"],
            "",
        );
        assert_eq!(code, 200, "{head}");
        assert_eq!(
            request(
                a,
                "GET",
                "/api/boards/events?tab=t",
                &["X-Api-Key: correct horse"],
                ""
            )
            .0,
            200
        );
        // The form: a wrong key refused, the right one signs in with a session cookie.
        let form = "Content-Type: application/x-www-form-urlencoded";
        assert_eq!(
            request(a, "POST", "/login", &[form], "key=wrong+horse").0,
            401
        );
        let (code, head) = request(a, "POST", "/login", &[form], "key=correct+horse");
        assert_eq!(code, 303, "{head}");
        let cookie = head
            .lines()
            .find_map(|l| {
                l.to_lowercase()
                    .starts_with("set-cookie:")
                    .then(|| l[11..].trim().to_string())
            })
            .expect("a session cookie");
        assert!(
            cookie.contains("HttpOnly") && !cookie.contains("horse"),
            "{cookie}"
        );
        let session = cookie.split(';').next().expect("name=value");
        let (code, head) = request(a, "GET", "/", &[&format!("Cookie: {session}")], "");
        assert_eq!(code, 200, "{head}");
    })
    .await
    .expect("the checks ran");
}

#[tokio::test]
async fn beyond_loopback_it_needs_a_key_and_the_port_option_sets_the_port() {
    let e = serve::start(args("0.0.0.0:0", None))
        .await
        .err()
        .expect("refused without --auth");
    assert!(e.to_string().contains("--auth"), "{e}");
    let e = serve::start(args("127.0.0.1:0", Some("short")))
        .await
        .err()
        .expect("a short key refused");
    assert!(e.to_string().contains("8 characters"), "{e}");
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port();
    let mut a = args("127.0.0.1:7125", None);
    a.port = Some(port);
    let r = serve::start(a).await.expect("starts");
    assert_eq!(r.addr.port(), port);
}
