//! "Inspect this print" on the dashboard: `dollop serve --camera URL` takes one picture
//! from a camera (here a small HTTP server in the test serving the bundled photo of a
//! chessboard printed with a 20 % longer channel, as a snapshot and as an MJPEG stream)
//! and measures it against the job opened from the Files (the chessboard's `.dlp`), as
//! `dollop inspect --suggest` does: every boundary found and the channel corrected. A
//! camera that answers 404 and a dashboard without a camera are refused in words.

mod serve_common;

use dollop_host::serve;
use serde_json::Value;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

/// A camera: `/snap.jpg` the photo, `/stream` one MJPEG frame of it, anything else 404.
fn camera() -> SocketAddr {
    let photo = std::fs::read(root().join("data/inspect/chessboard-photo.jpg")).unwrap();
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = l.local_addr().unwrap();
    std::thread::spawn(move || {
        for s in l.incoming() {
            let Ok(mut s) = s else { continue };
            let mut line = String::new();
            let mut r = BufReader::new(s.try_clone().unwrap());
            if r.read_line(&mut line).is_err() {
                continue;
            }
            loop {
                let mut h = String::new();
                if r.read_line(&mut h).unwrap_or(0) <= 2 {
                    break;
                }
            }
            let path = line.split(' ').nth(1).unwrap_or("").to_string();
            let _ = match path.as_str() {
                "/snap.jpg" => s
                    .write_all(
                        format!(
                            "HTTP/1.1 200 OK\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
                            photo.len()
                        )
                        .as_bytes(),
                    )
                    .and_then(|_| s.write_all(&photo)),
                "/stream" => s
                    .write_all(b"HTTP/1.1 200 OK\r\nContent-Type: multipart/x-mixed-replace; boundary=frame\r\nConnection: close\r\n\r\n--frame\r\nContent-Type: image/jpeg\r\n\r\n")
                    .and_then(|_| s.write_all(&photo))
                    .and_then(|_| s.write_all(b"\r\n--frame\r\n")),
                _ => s.write_all(
                    b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
                ),
            };
        }
    });
    addr
}

fn args(data: &Path, camera: Option<String>) -> serve::Args {
    serve::Args {
        config: Some(root().join("../configs/seed-paper-valves.toml")),
        data: Some(data.to_path_buf()),
        camera,
        ..serve_common::args()
    }
}

/// One request (`Connection: close`): the status and the body as JSON.
fn request(addr: SocketAddr, method: &str, path: &str, headers: &str, body: &[u8]) -> (u16, Value) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(120)))
        .unwrap();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n{headers}Content-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(body).unwrap();
    let mut all = Vec::new();
    s.read_to_end(&mut all).unwrap();
    let end = all.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    let head = String::from_utf8_lossy(&all[..end]).into_owned();
    let code = head.split(' ').nth(1).unwrap().parse().unwrap();
    let body = &all[end + 4..];
    let v = serde_json::from_slice(body)
        .unwrap_or_else(|_| Value::String(String::from_utf8_lossy(body).into_owned()));
    (code, v)
}

fn post_json(addr: SocketAddr, path: &str, v: Value) -> (u16, Value) {
    request(
        addr,
        "POST",
        path,
        "Content-Type: application/json\r\n",
        v.to_string().as_bytes(),
    )
}

/// The chessboard's job kept in the Files and opened: its job id.
fn open_job(addr: SocketAddr) -> u64 {
    let dlp = std::fs::read(root().join("data/inspect/chessboard.dlp")).unwrap();
    let b = "----dollopInspectBoundary";
    let mut body = format!("--{b}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"chessboard.dlp\"\r\nContent-Type: application/octet-stream\r\n\r\n").into_bytes();
    body.extend_from_slice(&dlp);
    body.extend_from_slice(format!("\r\n--{b}--\r\n").as_bytes());
    let (code, v) = request(
        addr,
        "POST",
        "/api/store",
        &format!("Content-Type: multipart/form-data; boundary={b}\r\n"),
        &body,
    );
    assert!(code < 300, "{code} {v}");
    let (code, v) = post_json(
        addr,
        "/api/store/chessboard.dlp/open",
        serde_json::json!({}),
    );
    assert_eq!(code, 200, "{v}");
    v["id"].as_u64().unwrap_or_else(|| panic!("{v}"))
}

/// A dashboard on `data` with `camera`: the chessboard's job opened, then inspected.
async fn inspect_with(data: &Path, camera: Option<String>) -> (u16, Value) {
    let r = serve::start(args(data, camera)).await.unwrap();
    let addr = r.addr;
    tokio::task::spawn_blocking(move || {
        let id = open_job(addr);
        post_json(addr, "/api/inspect", serde_json::json!({ "job": id }))
    })
    .await
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_print_is_inspected_from_the_camera() {
    let cam = camera();
    let data = tempfile::tempdir().unwrap();
    for (url, what) in [
        (format!("http://{cam}/snap.jpg"), "snapshot"),
        (format!("http://{cam}/stream"), "MJPEG stream"),
    ] {
        let (code, v) = inspect_with(data.path(), Some(url)).await;
        assert_eq!(code, 200, "{what}: {v}");
        let report = v["report"].as_str().unwrap();
        assert!(
            report.contains("boundaries        51 of 51 found"),
            "{what}: {report}"
        );
        assert!(
            report.contains("registered by     the four corner markers"),
            "{what}: {report}"
        );
        let fragment = v["fragment"]
            .as_str()
            .unwrap_or_else(|| panic!("{what}: {v}"));
        // Configured 2.4 mm; the print's channel is 2.88 mm.
        let line = fragment
            .lines()
            .find(|l| l.starts_with("channel_length_mm = "))
            .unwrap_or_else(|| panic!("{fragment}"));
        let l: f64 = line["channel_length_mm = ".len()..].parse().unwrap();
        assert!((l - 2.88).abs() < 0.03, "{what}: {line}");
        assert!(v["picture"]
            .as_str()
            .unwrap()
            .starts_with("data:image/png;base64,"));
        eprintln!("{what}: {line}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_missing_camera_is_refused_in_words() {
    let cam = camera();
    let data = tempfile::tempdir().unwrap();
    for (camera, needle) in [
        (Some(format!("http://{cam}/nothing.jpg")), "answered 404"),
        (None, "start the dashboard with --camera URL"),
        (
            Some("https://camera.invalid/snap.jpg".to_string()),
            "http:// only",
        ),
    ] {
        let (code, v) = inspect_with(data.path(), camera).await;
        assert_eq!(code, 400, "{v}");
        assert!(v.to_string().contains(needle), "{needle}: {v}");
    }
}
