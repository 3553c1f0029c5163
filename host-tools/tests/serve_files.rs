//! `dollop serve`'s kept files and its OctoPrint-shaped upload API, over plain HTTP/1.1:
//! the requests PrusaSlicer and Cura send (from their sources: PrusaSlicer's
//! `OctoPrint::test` GETs `api/version` with `X-Api-Key` and wants an `api` field and a
//! `text` starting "OctoPrint"; its upload POSTs `api/files/local` multipart with `print`
//! ("true"/"false"), `path` (the folder, often empty) and `file`; Cura's OctoPrint plugin
//! posts `select`, `print` and `file` to the same place), the key refused and accepted, a
//! bad file refused naming it; the Files API (a `.dlp` decoded, a broken one refused,
//! delete, no way out of the folder), configs saved by name, the console, and all of it
//! again from a second server on the same `--data`. Cura's OctoPrint plugin end to end on a
//! simulated board: its connect polls, select-and-print, the monitor's pause, resume,
//! cancel, home and jog, refusals in plain text. Plus the octorest client library from
//! PyPI (skipped with a message when it is not installed, except under CI).

mod serve_common;

use dollop_host::serve;
use serde_json::Value;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};

const KEY: &str = "correct horse";
const SQUARE: &str = include_str!("data/gcode-in/square-abs-e.gcode");

fn args(data: &std::path::Path, demo: bool) -> serve::Args {
    serve::Args {
        auth: Some(KEY.into()),
        demo,
        data: Some(data.to_path_buf()),
        ..serve_common::args()
    }
}

/// One request (`Connection: close`): the status and the body.
fn request(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[&str],
    body: &[u8],
) -> (u16, Vec<u8>) {
    let (code, _, body) = request_full(addr, method, path, headers, body);
    (code, body)
}

/// One request (`Connection: close`): the status, the head (lower case) and the body.
fn request_full(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[&str],
    body: &[u8],
) -> (u16, String, Vec<u8>) {
    let mut s = TcpStream::connect(addr).expect("connects");
    s.set_read_timeout(Some(std::time::Duration::from_secs(60)))
        .expect("timeout");
    let mut req = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for h in headers {
        req.push_str(h);
        req.push_str("\r\n");
    }
    req.push_str(&format!("Content-Length: {}\r\n\r\n", body.len()));
    s.write_all(req.as_bytes()).expect("sends");
    s.write_all(body).expect("sends the body");
    let mut all = Vec::new();
    s.read_to_end(&mut all).expect("reads");
    let head_end = all
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a head");
    let head = String::from_utf8_lossy(&all[..head_end]).to_ascii_lowercase();
    let code = head
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .expect("a status");
    let mut body = all[head_end + 4..].to_vec();
    if head.contains("transfer-encoding: chunked") {
        body = unchunk(&body);
    }
    (code, head, body)
}

fn unchunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    while let Some(eol) = b.windows(2).position(|w| w == b"\r\n") {
        let size = std::str::from_utf8(&b[..eol]).unwrap_or("0").trim();
        let n = usize::from_str_radix(size, 16).unwrap_or(0);
        if n == 0 {
            break;
        }
        out.extend_from_slice(&b[eol + 2..eol + 2 + n]);
        b = &b[eol + 2 + n + 2..];
    }
    out
}

fn json(body: &[u8]) -> Value {
    serde_json::from_slice(body)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(body)))
}

/// A multipart form: (field, file name, content).
fn multipart(parts: &[(&str, Option<&str>, &[u8])]) -> (String, Vec<u8>) {
    let boundary = "----dollopTestBoundary7MA4YWxk";
    let mut body = Vec::new();
    for (name, file, content) in parts {
        body.extend_from_slice(format!("--{boundary}\r\n").as_bytes());
        match file {
            Some(f) => body.extend_from_slice(
                format!("Content-Disposition: form-data; name=\"{name}\"; filename=\"{f}\"\r\nContent-Type: application/octet-stream\r\n\r\n").as_bytes(),
            ),
            None => body.extend_from_slice(
                format!("Content-Disposition: form-data; name=\"{name}\"\r\n\r\n").as_bytes(),
            ),
        }
        body.extend_from_slice(content);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{boundary}--\r\n").as_bytes());
    (
        format!("Content-Type: multipart/form-data; boundary={boundary}"),
        body,
    )
}

const AUTH: &str = "X-Api-Key: correct horse";

fn get(addr: SocketAddr, path: &str) -> (u16, Vec<u8>) {
    request(addr, "GET", path, &[AUTH], b"")
}

fn names(addr: SocketAddr) -> Vec<(String, String)> {
    let (code, body) = get(addr, "/api/store");
    assert_eq!(code, 200);
    json(&body)["files"]
        .as_array()
        .expect("files")
        .iter()
        .map(|f| {
            (
                f["name"].as_str().unwrap_or("").to_string(),
                f["kind"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect()
}

fn has(list: &[(String, String)], name: &str, kind: &str) -> bool {
    list.iter().any(|(n, k)| n == name && k == kind)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn slicer_uploads_files_and_configs_survive_a_restart() {
    let data = tempfile::tempdir().expect("folder");
    let r = serve::start(args(data.path(), true)).await.expect("starts");
    let (a, st) = (r.addr, r.state.clone());
    let demo = st.demo_job.expect("the demo job");
    let d = data.path().to_path_buf();
    tokio::task::spawn_blocking(move || {
        // The probe: refused without the key or with a wrong one, answered with it.
        assert_eq!(request(a, "GET", "/api/version", &[], b"").0, 401);
        assert_eq!(
            request(a, "GET", "/api/version", &["X-Api-Key: wrong horse"], b"").0,
            401
        );
        let (code, body) = get(a, "/api/version");
        assert_eq!(code, 200);
        let v = json(&body);
        assert!(v["api"].is_string(), "{v}");
        assert!(
            v["text"].as_str().unwrap_or("").starts_with("OctoPrint"),
            "{v}"
        );
        for p in [
            "/api/server",
            "/api/settings",
            "/api/printer",
            "/api/job",
            "/api/files/local",
        ] {
            assert_eq!(get(a, p).0, 200, "{p}");
        }

        // PrusaSlicer's upload: print=false, path (empty), file.
        let (ct, body) = multipart(&[
            ("print", None, b"false"),
            ("path", None, b""),
            ("file", Some("square.gcode"), SQUARE.as_bytes()),
        ]);
        assert_eq!(
            request(a, "POST", "/api/files/local", &[&ct], &body).0,
            401,
            "no key, no upload"
        );
        let (code, resp) = request(a, "POST", "/api/files/local", &[AUTH, &ct], &body);
        assert_eq!(code, 201, "{}", String::from_utf8_lossy(&resp));
        let v = json(&resp);
        assert_eq!(v["files"]["local"]["name"], "square.gcode", "{v}");
        assert_eq!(v["files"]["local"]["origin"], "local", "{v}");
        assert_eq!(v["done"], true, "{v}");
        let resource = v["files"]["local"]["refs"]["resource"]
            .as_str()
            .expect("refs")
            .to_string();
        assert_eq!(get(a, &resource).0, 200, "{resource}");
        assert!(has(&names(a), "square.gcode", "gcode"));

        // Cura's upload: select=true, print=true, file; the job goes to board 0.
        let (ct, body) = multipart(&[
            ("select", None, b"true"),
            ("print", None, b"true"),
            ("file", Some("cura square.gcode"), SQUARE.as_bytes()),
        ]);
        let (code, resp) = request(a, "POST", "/api/files/local", &[AUTH, &ct], &body);
        assert_eq!(code, 201, "{}", String::from_utf8_lossy(&resp));
        assert_eq!(json(&resp)["files"]["local"]["name"], "cura_square.gcode");
        let b = st.boards[0].clone();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
        loop {
            let v = b.view.borrow().clone();
            let on_board = v
                .job
                .iter()
                .chain(v.queue.iter())
                .any(|j| j.name.contains("square"));
            if on_board {
                break;
            }
            assert!(
                std::time::Instant::now() < deadline,
                "the upload never reached the board: {:?}",
                v.activity
            );
            std::thread::sleep(std::time::Duration::from_millis(100));
        }

        // A bad file is refused with a message naming it, and not kept: plain text, the
        // one body Cura's plugin shows (and PrusaSlicer shows as it is).
        let (ct, body) = multipart(&[("file", Some("bin.gcode"), &[0xff, 0xfe, 0x00])]);
        let (code, head, resp) = request_full(a, "POST", "/api/files/local", &[AUTH, &ct], &body);
        assert_eq!(code, 400);
        assert!(head.contains("content-type: text/plain\r\n"), "{head}");
        assert!(
            String::from_utf8_lossy(&resp).contains("bin.gcode"),
            "{}",
            String::from_utf8_lossy(&resp)
        );
        let (ct, body) = multipart(&[
            ("print", None, b"perhaps"),
            ("file", Some("x.gcode"), SQUARE.as_bytes()),
        ]);
        assert_eq!(
            request(a, "POST", "/api/files/local", &[AUTH, &ct], &body).0,
            400
        );
        let (ct, body) = multipart(&[("file", Some("notes.txt"), b"hello")]);
        assert_eq!(
            request(a, "POST", "/api/files/local", &[AUTH, &ct], &body).0,
            400
        );
        assert!(!names(a)
            .iter()
            .any(|(n, _)| n == "bin.gcode" || n == "notes.txt"));

        // A job downloaded from the dashboard uploads back as a .dlp (decoded, its config
        // found by hash); a broken copy is refused naming it.
        let (code, dlp) = get(a, &format!("/api/jobs/{demo}/job.dlp"));
        assert_eq!(code, 200);
        let (ct, body) = multipart(&[("file", Some("again.dlp"), &dlp)]);
        let (code, resp) = request(a, "POST", "/api/store", &[AUTH, &ct], &body);
        assert_eq!(code, 200, "{}", String::from_utf8_lossy(&resp));
        let job = json(&resp)["job"].as_u64().expect("a job");
        let (code, resp) = get(a, &format!("/api/jobs/{job}"));
        assert_eq!(code, 200);
        let (code, orig) = get(a, &format!("/api/jobs/{demo}"));
        assert_eq!(code, 200);
        assert_eq!(
            json(&resp)["figures"]["segments"],
            json(&orig)["figures"]["segments"]
        );
        let mut broken = dlp.clone();
        let last = broken.len() - 3;
        broken[last] ^= 0x5a;
        let (ct, body) = multipart(&[("file", Some("broken.dlp"), &broken)]);
        let (code, resp) = request(a, "POST", "/api/store", &[AUTH, &ct], &body);
        assert_eq!(code, 400);
        assert!(
            json(&resp)["error"]
                .as_str()
                .unwrap_or("")
                .contains("broken.dlp"),
            "{}",
            String::from_utf8_lossy(&resp)
        );
        assert!(has(&names(a), "again.dlp", "job"));
        // A kept G-code file opens as a job (what the Files page's Print and Re-slice do).
        let (code, resp) = request(
            a,
            "POST",
            "/api/store/square.gcode/open",
            &[AUTH, "Content-Type: application/json"],
            b"{}",
        );
        assert_eq!(code, 200, "{}", String::from_utf8_lossy(&resp));
        assert!(json(&resp)["figures"]["segments"].as_u64().unwrap_or(0) > 0);

        // No way out of the folder.
        std::fs::write(d.join("secret.gcode"), SQUARE).expect("writes");
        for p in [
            "/api/store/..%2Fsecret.gcode",
            "/api/store/%2E%2E%2Fsecret.gcode",
            "/api/store/..",
            "/api/store/history.jsonl",
        ] {
            assert_eq!(get(a, p).0, 404, "{p}");
        }

        // Configs by name: kept when they check, refused when not.
        let (_, c) = get(a, "/api/configs/0");
        let text = json(&c)["text"].as_str().expect("text").to_string();
        let put = serde_json::json!({ "text": text }).to_string();
        let j = "Content-Type: application/json";
        assert_eq!(
            request(
                a,
                "PUT",
                "/api/saved-configs/lab%20one",
                &[AUTH, j],
                put.as_bytes()
            )
            .0,
            200
        );
        let bad = serde_json::json!({ "text": "[channel]\nline_pitch_mm = -1\n" }).to_string();
        assert_eq!(
            request(
                a,
                "PUT",
                "/api/saved-configs/bad",
                &[AUTH, j],
                bad.as_bytes()
            )
            .0,
            400
        );
        let (code, resp) = get(a, "/api/saved-configs");
        assert_eq!(code, 200);
        assert_eq!(
            json(&resp)["configs"][0]["name"],
            "lab_one.toml",
            "{}",
            String::from_utf8_lossy(&resp)
        );

        // Delete.
        assert_eq!(
            request(a, "DELETE", "/api/store/again.dlp", &[AUTH], b"").0,
            200
        );
        assert_eq!(get(a, "/api/store/again.dlp").0, 404);
        assert_eq!(
            request(a, "DELETE", "/api/store/again.dlp", &[AUTH], b"").0,
            404
        );

        // The console saw the uploads, the refusal and the board's work, newest first.
        let (_, resp) = get(a, "/api/console");
        let lines = json(&resp)["lines"].as_array().expect("lines").clone();
        let text: Vec<String> = lines
            .iter()
            .map(|l| l["text"].as_str().unwrap_or("").to_string())
            .collect();
        assert!(
            text.iter()
                .any(|t| t.contains("upload from a slicer: square.gcode")),
            "{text:?}"
        );
        assert!(
            text.iter()
                .any(|t| t.contains("refused") && t.contains("bin.gcode")),
            "{text:?}"
        );
        let seqs: Vec<u64> = lines
            .iter()
            .map(|l| l["seq"].as_u64().unwrap_or(0))
            .collect();
        assert!(seqs.windows(2).all(|w| w[0] > w[1]), "{seqs:?}");
    })
    .await
    .expect("checks");

    // A second server on the same folder lists the same files and configs.
    let again = serve::start(args(data.path(), false))
        .await
        .expect("starts again");
    let a = again.addr;
    tokio::task::spawn_blocking(move || {
        let list = names(a);
        assert!(has(&list, "square.gcode", "gcode"), "{list:?}");
        assert!(has(&list, "cura_square.gcode", "gcode"), "{list:?}");
        assert!(!list.iter().any(|(n, _)| n == "again.dlp"), "{list:?}");
        let (code, resp) = get(a, "/api/saved-configs/lab_one");
        assert_eq!(code, 200, "{}", String::from_utf8_lossy(&resp));
        assert!(json(&resp)["fields"].is_array());
    })
    .await
    .expect("checks after the restart");
}

/// The octorest client (PyPI) probes the version with its key, uploads a file, and is
/// refused with a wrong key. `.ci/run` installs it; elsewhere the test says how.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_octorest_client_uploads_and_is_refused_without_the_key() {
    let has_it = std::process::Command::new("python3")
        .args(["-c", "import octorest"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_it {
        if std::env::var_os("CI").is_some() {
            panic!(
                "CI must run this test: .ci/run installs octorest (pip install --user octorest)"
            );
        }
        eprintln!(
            "SKIPPED: the Python client octorest is not installed (pip install --user octorest)"
        );
        return;
    }
    let data = tempfile::tempdir().expect("folder");
    let r = serve::start(args(data.path(), false))
        .await
        .expect("starts");
    let url = format!("http://{}", r.addr);
    let file = data.path().join("octorest-square.gcode");
    std::fs::write(&file, SQUARE).expect("writes");
    let script = r#"
import sys, octorest
url, key, path = sys.argv[1:4]
c = octorest.OctoRest(url=url, apikey=key)
print("version", c.version["api"], c.version["text"])
r = c.upload(path)
print("uploaded", r["files"]["local"]["name"], r["done"])
try:
    octorest.OctoRest(url=url, apikey="wrong horse")
    print("accepted a wrong key")
except RuntimeError as e:
    print("refused", e)
"#;
    let out = tokio::process::Command::new("python3")
        .args(["-c", script, &url, KEY])
        .arg(&file)
        .output()
        .await
        .expect("runs python3");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{text}\n{err}");
    assert!(text.contains("version 0.1 OctoPrint"), "{text}");
    assert!(
        text.contains("uploaded octorest-square.gcode True"),
        "{text}"
    );
    assert!(text.contains("refused"), "{text}");
    assert!(data.path().join("files/octorest-square.gcode").is_file());
}

/// Waits up to a minute for board 0's view to satisfy `ok`.
fn wait_for(st: &serve::state::AppState, what: &str, ok: impl Fn(&serve::view::View) -> bool) {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    loop {
        let v = st.boards[0].view.borrow().clone();
        if ok(&v) {
            return;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "{what} never came: {} ({:?})",
            v.activity,
            v.message
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// Cura's OctoPrint plugin, request by request as its source sends them
/// (`OctoPrintOutputDevice.py`): the connect sequence and the fields its handlers index
/// (a missing one is a Python `KeyError` there), an upload without `print` then
/// `select` + `print` on the `Location` it was given, the monitor's pause, resume and
/// cancel, its jog (`G91`, `G0 ... F`, `G90`) and anything else refused in plain text; an
/// upload to a folder naming no board is refused and keeps nothing.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cura_s_octoprint_plugin_connects_prints_pauses_and_jogs() {
    let data = tempfile::tempdir().expect("folder");
    // Real time, so that the print is still running when the pause comes.
    let mut a = args(data.path(), false);
    a.sim_speed = 1.0;
    let r = serve::start(a).await.expect("starts");
    let (a, st) = (r.addr, r.state.clone());
    tokio::task::spawn_blocking(move || {
        let (code, body) = get(a, "/api/settings");
        assert_eq!(code, 200);
        assert!(json(&body)["webcam"]["streamUrl"].is_string());
        let (code, body) = get(a, "/api/printerprofiles");
        assert_eq!(code, 200);
        let p = &json(&body)["profiles"]["_default"];
        assert_eq!(p["current"], true, "{p}");
        assert!(p["name"].is_string() && p["model"].is_string(), "{p}");
        wait_for(&st, "the board's link", |v| v.connected);
        let (code, body) = get(a, "/api/printer");
        assert_eq!(code, 200);
        let flags = &json(&body)["state"]["flags"];
        for f in [
            "error",
            "closedOrError",
            "paused",
            "pausing",
            "printing",
            "cancelling",
            "ready",
            "operational",
        ] {
            assert!(flags[f].is_boolean(), "{f}: {flags}");
        }
        let (code, body) = get(a, "/api/job");
        assert_eq!(code, 200);
        let j = json(&body);
        assert!(j["state"].is_string(), "{j}");
        assert!(j["job"]["file"].get("name").is_some(), "{j}");
        for k in ["printTime", "printTimeLeft", "completion"] {
            assert!(j["progress"].get(k).is_some(), "{k}: {j}");
        }

        // Upload only; then select and print on the Location given.
        let (ct, body) = multipart(&[
            ("path", None, b""),
            ("file", Some("square.gcode"), SQUARE.as_bytes()),
        ]);
        let (code, head, _) = request_full(a, "POST", "/api/files/local", &[AUTH, &ct], &body);
        assert_eq!(code, 201);
        let location = head
            .lines()
            .find_map(|l| l.strip_prefix("location: "))
            .expect("a Location")
            .trim()
            .to_string();
        assert_eq!(location, "/api/files/local/square.gcode");
        let post = |path: &str, body: &str| {
            request_full(
                a,
                "POST",
                path,
                &[AUTH, "Content-Type: application/json"],
                body.as_bytes(),
            )
        };
        let (code, _, resp) = post(&location, r#"{"command": "select", "print": true}"#);
        assert_eq!(code, 204, "{}", String::from_utf8_lossy(&resp));
        wait_for(&st, "the print", |v| {
            v.mode == Some(dollop::wire::Mode::Job) && v.activity.starts_with("printing")
        });

        // The monitor's buttons.
        let (code, _, resp) = post("/api/job", r#"{"command": "pause", "action": "pause"}"#);
        assert_eq!(code, 204, "{}", String::from_utf8_lossy(&resp));
        wait_for(&st, "the pause", |v| v.activity.starts_with("paused"));
        let (code, body) = get(a, "/api/job");
        assert_eq!((code, json(&body)["state"].as_str()), (200, Some("Paused")));
        let (code, _, resp) = post("/api/job", r#"{"command": "pause"}"#);
        assert_eq!(code, 204, "toggle: {}", String::from_utf8_lossy(&resp));
        wait_for(&st, "the resumed print", |v| {
            !v.activity.starts_with("paused")
        });
        let (code, _, resp) = post("/api/job", r#"{"command": "cancel"}"#);
        assert_eq!(code, 204, "{}", String::from_utf8_lossy(&resp));
        wait_for(&st, "the end of the job", |v| {
            v.mode != Some(dollop::wire::Mode::Job)
        });

        // Jog and home as Cura's controller sends them: after the cancel the board wants
        // homing first, and says so to the slicer; anything else refused, naming the line.
        let jog = r#"{"commands": ["G91", "G0 X1 Y0 Z0 F6000", "G90"]}"#;
        let (code, head, resp) = post("/api/printer/command", jog);
        assert_eq!(code, 409, "{}", String::from_utf8_lossy(&resp));
        assert!(head.contains("content-type: text/plain\r\n"), "{head}");
        assert!(String::from_utf8_lossy(&resp).contains("not homed"));
        let (code, _, resp) = post("/api/printer/command", r#"{"command": "G28 X Y"}"#);
        assert_eq!(code, 204, "{}", String::from_utf8_lossy(&resp));
        let x = st.boards[0].view.borrow().position[0];
        let (code, _, resp) = post("/api/printer/command", jog);
        assert_eq!(code, 204, "{}", String::from_utf8_lossy(&resp));
        wait_for(&st, "the jog", |v| (v.position[0] - x - 1.0).abs() < 0.01);
        let (code, head, resp) = post("/api/printer/command", r#"{"commands": ["M104 S200"]}"#);
        assert_eq!(code, 400);
        assert!(head.contains("content-type: text/plain\r\n"), "{head}");
        assert!(String::from_utf8_lossy(&resp).contains("M104 S200"));
        let (code, _, _) = post("/api/job", r#"{"command": "explode"}"#);
        assert_eq!(code, 400);
        let (code, _, _) = post("/api/job", "not json");
        assert_eq!(code, 400);

        // A print into a folder that names no board: refused before anything is kept.
        let (ct, body) = multipart(&[
            ("path", None, b"the other printer"),
            ("print", None, b"true"),
            ("file", Some("elsewhere.gcode"), SQUARE.as_bytes()),
        ]);
        let (code, _, resp) = request_full(a, "POST", "/api/files/local", &[AUTH, &ct], &body);
        assert_eq!(code, 400);
        assert!(
            String::from_utf8_lossy(&resp).contains("no board named"),
            "{}",
            String::from_utf8_lossy(&resp)
        );
        assert!(!names(a).iter().any(|(n, _)| n == "elsewhere.gcode"));
    })
    .await
    .expect("Cura's requests");
}

/// Waits up to a minute for board `i`'s view to satisfy `ok`.
fn wait_board(
    st: &serve::state::AppState,
    i: usize,
    what: &str,
    ok: impl Fn(&serve::view::View) -> bool,
) -> serve::view::View {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    loop {
        let v = st.boards[i].view.borrow().clone();
        if ok(&v) {
            return v;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "board {i}: {what} never came: {} ({:?})",
            v.activity,
            v.message
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// G-code from a slicer is imported for the machine it goes to: board 1 given another
/// config (the Design page's, loaded as it homes) prints an upload into its folder with
/// that config, not the first one offered; board 0, which has none, gets the first one.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_upload_is_imported_with_the_config_of_the_board_it_goes_to() {
    let data = tempfile::tempdir().expect("folder");
    let mut a = args(data.path(), false);
    a.sim_boards = 2;
    let r = serve::start(a).await.expect("starts");
    let (a, st) = (r.addr, r.state.clone());
    tokio::task::spawn_blocking(move || {
        let hash = |text: &str| {
            let c = serve::design::check(text).expect("config").config;
            dollop::job::config_hash(&c)
        };
        let (first, other) = (serve::design::BUNDLED[0].1, serve::design::BUNDLED[1].1);
        assert_ne!(hash(first), hash(other), "the test needs two machines");
        for i in 0..2 {
            wait_board(&st, i, "the link", |v| v.connected);
        }
        assert!(st.boards[1].config.get().is_none());
        let home = serde_json::json!({ "tab": "t", "config": other }).to_string();
        let (code, resp) = request(
            a,
            "POST",
            "/api/boards/1/home",
            &[AUTH, "Content-Type: application/json"],
            home.as_bytes(),
        );
        assert_eq!(code, 200, "{}", String::from_utf8_lossy(&resp));
        let loaded = st.boards[1].config.get().expect("board 1's config");
        assert_eq!(dollop::job::config_hash(&loaded.config), hash(other));
        wait_board(&st, 1, "the homing", |v| {
            v.homed && v.mode == Some(dollop::wire::Mode::Idle)
        });

        // Printed on each board through its folder (by name, then none: board 0).
        let name1 = st.boards[1].view.borrow().name.clone();
        for (board, folder, want) in [(1, name1.as_str(), other), (0, "", first)] {
            let (ct, body) = multipart(&[
                ("path", None, folder.as_bytes()),
                ("print", None, b"true"),
                ("file", Some("square.gcode"), SQUARE.as_bytes()),
            ]);
            let (code, resp) = request(a, "POST", "/api/files/local", &[AUTH, &ct], &body);
            assert_eq!(code, 201, "{}", String::from_utf8_lossy(&resp));
            let v = wait_board(&st, board, "the job", |v| v.job.is_some());
            let job = st.job(v.job.expect("a job").job).expect("kept");
            assert_eq!(
                dollop::job::config_hash(&job.config),
                hash(want),
                "board {board}: imported with another config"
            );
        }
    })
    .await
    .expect("uploads");
}

/// `POST /api/login` as Cura's OctoPrint plugin sends it (`{"passive": true}` with its
/// key), and with a user and password: OctoPrint's answers (the `_api` user; 403 for a
/// wrong password; 400 for neither), and the key checked as everywhere (401 without it or
/// with a wrong one, which Cura shows as "Unknown user").
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_login_cura_sends_is_answered_for_the_right_key_only() {
    let data = tempfile::tempdir().expect("folder");
    let r = serve::start(args(data.path(), false))
        .await
        .expect("starts");
    let a = r.addr;
    tokio::task::spawn_blocking(move || {
        let json_ct = "Content-Type: application/json";
        let login = |key: Option<&str>, body: &str| {
            let k = key.map(|k| format!("X-Api-Key: {k}"));
            let mut h = vec![json_ct];
            if let Some(k) = &k {
                h.push(k);
            }
            request_full(a, "POST", "/api/login", &h, body.as_bytes())
        };
        let passive = r#"{"passive": true}"#;
        let (code, _, body) = login(Some(KEY), passive);
        assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
        let u = json(&body);
        assert_eq!(u["name"], "_api", "{u}");
        assert_eq!(u["active"], true, "{u}");
        for bad in [Some("wrong horse"), None] {
            let (code, _, body) = login(bad, passive);
            assert_eq!(code, 401, "{bad:?}: {}", String::from_utf8_lossy(&body));
        }
        let (code, head, body) = login(Some(KEY), r#"{"user": "lab", "pass": "wrong"}"#);
        assert_eq!(code, 403, "{}", String::from_utf8_lossy(&body));
        assert!(head.contains("content-type: text/plain\r\n"), "{head}");
        let (code, _, body) = login(Some(KEY), &format!(r#"{{"user": "lab", "pass": "{KEY}"}}"#));
        assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
        let (code, _, body) = login(Some(KEY), "{}");
        assert_eq!(code, 400, "{}", String::from_utf8_lossy(&body));
        assert!(String::from_utf8_lossy(&body).contains("passive"));
    })
    .await
    .expect("logins");
}
