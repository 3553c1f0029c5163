//! `dollop serve` in a real browser: Debian's headless Chromium driven through chromedriver
//! (WebDriver, the `fantoccini` client) against the server started in-process. Covers a
//! corrupt upload refused, a config error shown at its field, a bundled design uploaded
//! through the file picker and sliced with its preview drawn, a simulation with its report
//! and heatmap, a print on the simulated board followed to 100 % with the status pushed
//! live (the flow shown being the reference plant's), pause, resume and abort, a second
//! tab refused until it takes control, rheology, flow, lag and camera calibrations applied
//! to the config (the bundled frames through the file picker; a corrupt frame dropped on
//! the page, a missing scale, more frames or bytes than the limits refused), a small 3MF dropped on the page (a synthetic drop event
//! carrying the file) sliced and previewed, and a browser closed mid-print: a new session
//! finds the print going on and follows it to the end. Saves screenshots of the main pages
//! under the target directory (`tmp/serve-screenshots`). Without chromedriver it says it
//! skipped, except in CI (`CI=true`), where that is a failure.

mod serve_common;

use dollop_host::serve;
use fantoccini::{Client, ClientBuilder, Locator};
use serde_json::{json, Value};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const CHROMEDRIVER: &str = "/usr/bin/chromedriver";
const CHROMIUM: &str = "/usr/bin/chromium";

/// Kills chromedriver (and with it the browser) when the test ends, however it ends.
struct Driver(Child);

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("no free port on 127.0.0.1")
}

fn shots_dir() -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("serve-screenshots");
    std::fs::create_dir_all(&d).expect("cannot create the screenshot folder");
    d
}

async fn shot(c: &Client, name: &str) {
    let png = c.screenshot().await.expect("screenshot");
    let path = shots_dir().join(name);
    std::fs::write(&path, png).expect("cannot write the screenshot");
    eprintln!("screenshot: {}", path.display());
}

/// Evaluates `expr` in the page until it is truthy; returns its value.
async fn wait_for(c: &Client, expr: &str, secs: u64, what: &str) -> Value {
    let end = Instant::now() + Duration::from_secs(secs);
    let script = format!("return ({expr});");
    let mut last;
    loop {
        match c.execute(&script, vec![]).await {
            Ok(v) => {
                let truthy = match &v {
                    Value::Null => false,
                    Value::Bool(b) => *b,
                    Value::String(s) => !s.is_empty(),
                    Value::Number(n) => n.as_f64().is_some_and(|x| x != 0.0),
                    _ => true,
                };
                if truthy {
                    return v;
                }
                last = v;
            }
            Err(e) => last = json!(e.to_string()),
        }
        if Instant::now() >= end {
            shot(c, "failure.png").await;
        }
        assert!(
            Instant::now() < end,
            "waited {secs} s for {what} ({expr}); last value {last}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

async fn js(c: &Client, expr: &str) -> Value {
    c.execute(&format!("return ({expr});"), vec![])
        .await
        .expect("script")
}

async fn click(c: &Client, css: &str) {
    c.find(Locator::Css(css))
        .await
        .unwrap_or_else(|e| panic!("no {css} on the page: {e}"))
        .click()
        .await
        .unwrap_or_else(|e| panic!("cannot click {css}: {e}"));
}

async fn choose_file(c: &Client, path: &Path) {
    // A `multiple` picker adds to what it holds: empty it first, as a new choice does.
    js(
        c,
        "(document.getElementById('design-files').value = '', true)",
    )
    .await;
    c.find(Locator::Id("design-files"))
        .await
        .expect("file picker")
        .send_keys(&path.display().to_string())
        .await
        .expect("choosing a file");
}

async fn board_field(c: &Client, key: &str) -> String {
    js(
        c,
        &format!("document.querySelector('.board[data-board=\"0\"]').dataset.{key}"),
    )
    .await
    .as_str()
    .unwrap_or_default()
    .to_string()
}

/// A 6 mm cube as a 3MF (one object, no materials), written with the threemf crate.
fn cube_3mf(path: &Path) {
    use threemf::model::{
        Build, Item, Model, Object, Resources, Triangle, Triangles, Unit, Vertex, Vertices,
    };
    let s = 6.0;
    let vertex: Vec<Vertex> = (0..8)
        .map(|i| Vertex {
            x: if i & 1 != 0 { s } else { 0.0 },
            y: if i & 2 != 0 { s } else { 0.0 },
            z: if i & 4 != 0 { s } else { 0.0 },
        })
        .collect();
    // Two triangles a face, wound outwards.
    let faces = [
        [0, 2, 3, 1], // bottom (-z)
        [4, 5, 7, 6], // top (+z)
        [0, 1, 5, 4], // -y
        [2, 6, 7, 3], // +y
        [0, 4, 6, 2], // -x
        [1, 3, 7, 5], // +x
    ];
    let triangle = faces
        .iter()
        .flat_map(|f| {
            [
                Triangle {
                    v1: f[0],
                    v2: f[1],
                    v3: f[2],
                },
                Triangle {
                    v1: f[0],
                    v2: f[2],
                    v3: f[3],
                },
            ]
        })
        .collect();
    let model = Model {
        resources: Resources {
            object: vec![Object {
                id: 1,
                mesh: Some(threemf::Mesh {
                    vertices: Vertices { vertex },
                    triangles: Triangles { triangle },
                }),
                ..Default::default()
            }],
            basematerials: None,
        },
        build: Build {
            item: vec![Item {
                objectid: 1,
                transform: None,
                partnumber: None,
            }],
        },
        unit: Unit::Millimeter,
        ..Default::default()
    };
    let f = std::fs::File::create(path).expect("cannot create the 3MF");
    threemf::write(f, model).expect("cannot write the 3MF");
}

/// Board 0's elapsed time stands still over a second (the print has stopped).
async fn stopped_clock(c: &Client, what: &str) {
    let a = board_field(c, "elapsed").await;
    tokio::time::sleep(Duration::from_millis(1000)).await;
    let b = board_field(c, "elapsed").await;
    assert!(!a.is_empty() && a != "0", "{what}: elapsed {a}");
    assert_eq!(a, b, "{what}: the elapsed time went on");
}

/// Presses the mouse on `css`, holds it `ms`, releases it.
async fn held_click(c: &Client, css: &str, ms: u64) {
    use fantoccini::actions::{InputSource, MouseActions, PointerAction, MOUSE_BUTTON_LEFT};
    let e = c
        .find(Locator::Css(css))
        .await
        .unwrap_or_else(|e| panic!("no {css} on the page: {e}"));
    let press = MouseActions::new("mouse".into())
        .then(PointerAction::MoveToElement {
            element: e,
            duration: None,
            x: 0.0,
            y: 0.0,
        })
        .then(PointerAction::Down {
            button: MOUSE_BUTTON_LEFT,
        })
        .then(PointerAction::Pause {
            duration: Duration::from_millis(ms),
        })
        .then(PointerAction::Up {
            button: MOUSE_BUTTON_LEFT,
        });
    c.perform_actions(press).await.expect("a held click");
    c.release_actions().await.expect("release");
}

/// A board's data attribute (`activity`, `progress`, `seq`).
async fn field_of(c: &Client, board: usize, key: &str) -> String {
    js(
        c,
        &format!("document.querySelector('.board[data-board=\"{board}\"]')?.dataset.{key}"),
    )
    .await
    .as_str()
    .unwrap_or_default()
    .to_string()
}

#[test]
fn dashboard_in_a_real_browser() {
    if !Path::new(CHROMEDRIVER).exists() || !Path::new(CHROMIUM).exists() {
        if std::env::var("CI").as_deref() == Ok("true") {
            panic!("{CHROMEDRIVER} or {CHROMIUM} missing in CI: apt-get install chromium chromium-driver");
        }
        eprintln!("skipped: {CHROMEDRIVER} or {CHROMIUM} not installed (apt-get install chromium chromium-driver)");
        return;
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    rt.block_on(run());
}

async fn run() {
    let _ = std::fs::remove_file(shots_dir().join("failure.png"));
    // The server, in-process, on a free port; the simulated board 3 times real time; its
    // data folder (the print history) read again by a second server at the end.
    let data = tempfile::tempdir().expect("data folder");
    let server = serve::start(serve::Args {
        sim_speed: 3.0,
        sim_boards: 2,
        data: Some(data.path().to_path_buf()),
        ..serve_common::args()
    })
    .await
    .expect("server starts");
    let base = format!("http://{}/", server.addr);

    let port = free_port();
    let _driver = Driver(
        Command::new(CHROMEDRIVER)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver starts"),
    );
    let profile = tempfile::tempdir().expect("profile folder");
    let caps: serde_json::Map<String, Value> = json!({
        "goog:chromeOptions": {
            "binary": CHROMIUM,
            "args": [
                "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--disable-dev-shm-usage", "--window-size=1400,1000",
                format!("--user-data-dir={}", profile.path().display()),
            ]
        }
    })
    .as_object()
    .cloned()
    .expect("capabilities");
    let url = format!("http://127.0.0.1:{port}");
    let c = session(&url, &caps).await;
    let result = tokio::time::timeout(Duration::from_secs(500), pages(&c, &base)).await;
    let before = match result {
        Ok(p) => p,
        Err(_) => {
            let _ = c.close().await;
            panic!("the browser test took over 500 s");
        }
    };
    // A browser closed mid-print: the session ends (its status stream with it) while the
    // second board prints; a new session finds the print going on, then finished.
    c.close().await.expect("the browser closes");
    let c = session(&url, &caps).await;
    let result = tokio::time::timeout(Duration::from_secs(200), reopened(&c, &base, before)).await;
    let guarded = tokio::time::timeout(Duration::from_secs(60), signed_in(&c, data.path())).await;
    let _ = c.close().await;
    result.expect("following the print in a new browser took over 200 s");
    guarded.expect("the --auth check took over 60 s");
}

/// A dashboard started with `--auth`: the browser is sent to the sign-in form, a wrong
/// key is refused (and the API with it), the right one opens the dashboard.
async fn signed_in(c: &Client, data: &Path) {
    let server = serve::start(serve::Args {
        auth: Some("browser key 1".into()),
        sim_speed: 1.0,
        data: Some(data.to_path_buf()),
        camera: Some(snapshot_server().await),
        ..serve_common::args()
    })
    .await
    .expect("the guarded server starts");
    let base = format!("http://{}/", server.addr);
    c.goto(&base).await.expect("open the guarded dashboard");
    let url = c.current_url().await.expect("url");
    assert!(url.path() == "/login", "not sent to sign in: {url}");
    let status = js(c, &format!("fetch('{base}api/info').then(r => r.status)")).await;
    assert_eq!(status, json!(401), "the API without the key");
    let key = c.find(Locator::Id("key")).await.expect("the key field");
    key.send_keys("wrong key 1").await.expect("type");
    click(c, "#sign-in").await;
    wait_for(
        c,
        "document.getElementById('refused')",
        10,
        "a wrong key refused",
    )
    .await;
    let key = c.find(Locator::Id("key")).await.expect("the key field");
    key.send_keys("browser key 1").await.expect("type");
    click(c, "#sign-in").await;
    wait_for(
        c,
        "document.querySelectorAll('.field').length > 10",
        20,
        "the dashboard, signed in",
    )
    .await;
    wait_for(
        c,
        "document.querySelector('.board[data-board=\"0\"]')?.dataset.activity",
        20,
        "the status stream, signed in",
    )
    .await;
    // The same data folder: the first server's prints are in this one's history.
    click(c, "#nav-print").await;
    wait_for(c, "document.querySelectorAll('#history tr[data-outcome=\"finished\"]').length >= 2 && document.querySelectorAll('#history tr[data-outcome=\"aborted\"]').length >= 1", 20, "the history read back by a new server").await;
    shot(c, "history.png").await;
    // The camera panel shows the snapshot the test serves (a bundled design as the photo).
    wait_for(
        c,
        "!document.getElementById('camera-panel').hidden && document.getElementById('camera-img').naturalWidth > 50",
        20,
        "the camera's snapshot on the Print page",
    )
    .await;
    kept_files(c, data).await;
}

/// The Files page of the second server on the first one's data folder: the job the Design
/// page sliced is still listed; a `.dlp` uploaded is decoded and listed, the console says
/// so, and Delete removes it; the page fits a phone.
async fn kept_files(c: &Client, data: &Path) {
    click(c, "#nav-files").await;
    wait_for(
        c,
        "document.querySelector('#files tr[data-file=\"chessboard.dlp\"][data-kind=\"job\"]')",
        20,
        "the first server's sliced job, kept across the restart",
    )
    .await;
    // A job made for a bundled config, as `dollop slice` would write it.
    let (name, text) = serve::design::BUNDLED[0];
    let checked = serve::design::check(text).unwrap_or_else(|e| panic!("{name}: {e}"));
    let design = [serve::design::Upload {
        name: "logo.png".into(),
        bytes: serve::design::DESIGNS[0].1.to_vec(),
    }];
    let form = serve::design::SliceForm {
        width_mm: Some(20.0),
        ..Default::default()
    };
    let sliced = serve::design::slice(&design, &checked.config, &form).expect("slices");
    let upload = tempfile::tempdir().expect("folder");
    let path = upload.path().join("uploaded-copy.dlp");
    std::fs::write(&path, sliced.to_bytes()).expect("writes the job");
    c.find(Locator::Id("files-upload"))
        .await
        .expect("the upload picker")
        .send_keys(&path.display().to_string())
        .await
        .expect("choosing the job");
    wait_for(
        c,
        "document.querySelector('#files tr[data-file=\"uploaded-copy.dlp\"][data-kind=\"job\"]')",
        30,
        "the uploaded job listed",
    )
    .await;
    wait_for(
        c,
        "Array.from(document.querySelectorAll('#console li')).some(l => l.textContent.includes('kept uploaded-copy.dlp'))",
        20,
        "the console saying the upload was kept",
    )
    .await;
    assert!(data.join("files/uploaded-copy.dlp").is_file());
    shot(c, "files.png").await;
    js(c, "(window.confirm = () => true, true)").await;
    click(c, "#files tr[data-file=\"uploaded-copy.dlp\"] .file-delete").await;
    wait_for(
        c,
        "!document.querySelector('#files tr[data-file=\"uploaded-copy.dlp\"]')",
        20,
        "the deleted job gone from the list",
    )
    .await;
    assert!(!data.join("files/uploaded-copy.dlp").exists());
    // A reload whose last job was deleted meanwhile says so, rather than silently opening
    // another in its place.
    js(
        c,
        "(localStorage.setItem('dollop-design', JSON.stringify({kept: 'uploaded-copy.dlp', options: {}})), true)",
    )
    .await;
    c.refresh().await.expect("reloads");
    wait_for(
        c,
        "document.getElementById('toast').textContent.includes('uploaded-copy.dlp, could not be reopened')",
        20,
        "the reload saying the last job could not be reopened",
    )
    .await;
    // The header's Abort: greyed exactly while the board has no config (nothing to stop).
    let consistent = wait_for(
        c,
        "(() => { const b = lastBoards && lastBoards.boards[0]; const s = document.querySelector('#header-boards .badge[data-board=\"0\"] .abort-now'); return b && s && b.mode && (s.disabled === (b.mode === 'Unconfigured')) && b.mode; })()",
        20,
        "the header's Abort matching board 0's mode",
    )
    .await;
    eprintln!("header Abort checked with board 0 {consistent}");
}

/// A static snapshot endpoint, as a camera's: every request answers the same PNG. Its URL.
async fn snapshot_server() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").expect("snapshot listener");
    let addr = l.local_addr().expect("address");
    std::thread::spawn(move || {
        use std::io::{Read, Write};
        let png = serve::design::DESIGNS[0].1;
        for mut s in l.incoming().flatten() {
            let mut buf = [0u8; 2048];
            let _ = s.read(&mut buf);
            let head = format!(
                "HTTP/1.1 200 OK\r\nContent-Type: image/png\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
                png.len()
            );
            let _ = s.write_all(head.as_bytes());
            let _ = s.write_all(png);
        }
    });
    format!("http://{addr}/snapshot.png")
}

/// A WebDriver session (a fresh browser), retried while chromedriver starts.
async fn session(url: &str, caps: &serde_json::Map<String, Value>) -> Client {
    let connector = hyper_util::client::legacy::connect::HttpConnector::new();
    let start = Instant::now();
    loop {
        match ClientBuilder::new(connector.clone())
            .capabilities(caps.clone())
            .connect(url)
            .await
        {
            Ok(c) => return c,
            Err(e) => {
                assert!(
                    start.elapsed() < Duration::from_secs(30),
                    "chromedriver did not take a session: {e}"
                );
                tokio::time::sleep(Duration::from_millis(200)).await;
            }
        }
    }
}

/// In a new browser: board 1 still printing (from at least `before`) or finished, its
/// status live; then to 100 %.
async fn reopened(c: &Client, base: &str, before: f64) {
    c.goto(base).await.expect("open the dashboard again");
    click(c, "#nav-print").await;
    wait_for(
        c,
        "document.querySelector('.board[data-board=\"1\"]')?.dataset.activity",
        20,
        "board 1 in the new browser",
    )
    .await;
    let activity = field_of(c, 1, "activity").await;
    let p: f64 = field_of(c, 1, "progress").await.parse().unwrap_or(0.0);
    eprintln!("browser closed at {before:.3}; the new one finds board 1 {activity} at {p:.3}");
    assert!(
        (activity == "printing" && p >= before) || activity.starts_with("finished"),
        "{activity} at {p} (was {before})"
    );
    shot(c, "reopened.png").await;
    // The live plots: samples a second, fetched on load and added from the status.
    wait_for(
        c,
        "app.trend[1] && app.trend[1].length >= 3 && document.querySelector('.board[data-board=\"1\"] canvas.trend-plot').width > 0",
        20,
        "board 1's live plots filling",
    )
    .await;
    wait_for(c, "document.querySelector('.board[data-board=\"1\"]').dataset.activity.startsWith('finished') && document.querySelector('.board[data-board=\"1\"] .live').textContent.startsWith('100.0 %')", 180, "the print finished, seen from the new browser").await;
}

/// The pages, in one browser; returns the progress of board 1's print, left running.
async fn pages(c: &Client, base: &str) -> f64 {
    c.goto(base).await.expect("open the dashboard");
    wait_for(
        c,
        "document.querySelectorAll('.field').length > 10",
        20,
        "the config editor",
    )
    .await;
    let designs = Path::new(env!("CARGO_MANIFEST_DIR")).join("designs");

    // A corrupt upload is refused with a message naming the file.
    let tmp = tempfile::tempdir().expect("temp folder");
    let corrupt = tmp.path().join("corrupt.png");
    std::fs::write(&corrupt, b"\x89PNG\r\n\x1a\nthis is not a picture").expect("write");
    choose_file(c, &corrupt).await;
    click(c, "#slice").await;
    let msg = wait_for(c, "!document.getElementById('slice-error').hidden && document.getElementById('slice-error').textContent", 30, "the corrupt upload's message").await;
    let msg = msg.as_str().unwrap_or_default();
    assert!(
        msg.contains("corrupt.png") && msg.contains("unreadable image"),
        "{msg}"
    );
    shot(c, "corrupt-upload.png").await;

    // An upload over the stated limit is refused with the limit named.
    js(
        c,
        "(setFiles([new File([new Uint8Array(65 * 1024 * 1024)], 'huge.png')]), true)",
    )
    .await;
    click(c, "#slice").await;
    let msg = wait_for(c, "!document.getElementById('slice-error').hidden && document.getElementById('slice-error').textContent.includes('64 MiB') && document.getElementById('slice-error').textContent", 60, "the oversize upload's message").await;
    eprintln!("oversize upload: {msg}");

    // A config error is shown at its field.
    click(c, "#config-details summary").await;
    let pitch = c
        .find(Locator::Css(
            ".field[data-path=\"channel.line_pitch_mm\"] input",
        ))
        .await
        .expect("the line pitch field");
    pitch.clear().await.expect("clear");
    pitch.send_keys("-1").await.expect("type");
    click(c, "#config-check").await;
    let err = wait_for(
        c,
        "document.querySelector('.field.has-error[data-path=\"channel.line_pitch_mm\"] .field-error')?.textContent",
        20,
        "the error at channel.line_pitch_mm",
    )
    .await;
    assert!(
        err.as_str()
            .unwrap_or_default()
            .contains("must not be negative"),
        "{err}"
    );
    assert_eq!(
        js(c, "document.querySelectorAll('.field.has-error').length").await,
        json!(1)
    );
    shot(c, "config-error.png").await;
    pitch.clear().await.expect("clear");
    pitch.send_keys("0.8").await.expect("type");
    click(c, "#config-check").await;
    wait_for(c, "document.querySelectorAll('.field.has-error').length === 0 && document.querySelectorAll('#config-derived tr').length > 3", 20, "the error cleared and derived figures shown").await;
    click(c, "#config-details summary").await;

    // A small 3MF dropped on the page (a drop event carrying the file, as a drag from the
    // desktop does), sliced: figures, the executor's time, and the preview.
    let cube = tmp.path().join("cube.3mf");
    cube_3mf(&cube);
    let b64 = {
        use base64::Engine;
        base64::engine::general_purpose::STANDARD.encode(std::fs::read(&cube).expect("3MF"))
    };
    js(c, &format!("(() => {{ const b = Uint8Array.from(atob('{b64}'), (ch) => ch.charCodeAt(0)); const dt = new DataTransfer(); dt.items.add(new File([b], 'cube.3mf')); document.getElementById('drop').dispatchEvent(new DragEvent('drop', {{ dataTransfer: dt, bubbles: true, cancelable: true }})); return true; }})()")).await;
    wait_for(
        c,
        "document.getElementById('design-list')?.textContent.includes('cube.3mf')",
        10,
        "the dropped file listed",
    )
    .await;
    click(c, "#slice").await;
    wait_for(c, "document.getElementById('job-name').textContent.includes('cube.3mf') && document.querySelector('.fig-print-segments')?.textContent", 120, "the 3MF sliced").await;
    let est = js(
        c,
        "document.querySelector('.fig-estimated-print-time').textContent",
    )
    .await;
    assert!(
        est.as_str()
            .unwrap_or_default()
            .contains("a run of the executor"),
        "{est}"
    );
    let drawn = js(c, "(() => { const c = document.getElementById('preview'); const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let a = 0; for (let i = 0; i < d.length; i += 4) { if (d[i] === 122 && d[i+1] === 72 && d[i+2] === 36) a++; } return a; })()").await;
    assert!(
        drawn.as_u64().unwrap_or(0) > 200,
        "preview pixels of the 3MF: {drawn}"
    );
    eprintln!("3MF dropped and sliced: {est}");
    js(c, "(window.scrollTo(0, 0), true)").await;
    shot(c, "design-3mf.png").await;

    // A bundled design through the file picker, sliced 12 mm wide: the preview is drawn.
    choose_file(c, &designs.join("chessboard.png")).await;
    click(c, "#options-details summary").await;
    c.find(Locator::Id("opt-width_mm"))
        .await
        .expect("width option")
        .send_keys("12")
        .await
        .expect("type");
    click(c, "#slice").await;
    let segs = wait_for(
        c,
        "document.getElementById('job-name').textContent.includes('chessboard.png') && document.querySelector('.fig-print-segments')?.textContent",
        60,
        "the job's figures",
    )
    .await;
    let segs: u64 = segs.as_str().unwrap_or("0").parse().unwrap_or(0);
    assert!(segs > 10, "print segments {segs}");
    let name = js(c, "document.getElementById('job-name').textContent").await;
    assert!(
        name.as_str().unwrap_or_default().contains("chessboard.png"),
        "{name}"
    );
    // The canvas holds both materials' colours (brown and yellow beads).
    let colours = js(c, "(() => { const c = document.getElementById('preview'); const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let a = 0, b = 0; for (let i = 0; i < d.length; i += 4) { if (d[i] === 122 && d[i+1] === 72 && d[i+2] === 36) a++; if (d[i] === 236 && d[i+1] === 190 && d[i+2] === 70) b++; } return [a, b]; })()").await;
    let (a, b) = (
        colours[0].as_u64().unwrap_or(0),
        colours[1].as_u64().unwrap_or(0),
    );
    assert!(
        a > 500 && b > 500,
        "preview pixels of material 0: {a}, material 1: {b}"
    );
    let layers = js(c, "document.getElementById('layer-select').options.length").await;
    assert!(layers.as_u64().unwrap_or(0) >= 2, "layer choices {layers}");
    js(c, "(window.scrollTo(0, 0), true)").await;
    shot(c, "design.png").await;

    // Simulate: progress, then the report and the heatmap.
    click(c, "#nav-simulate").await;
    // No broken-picture icon before a run.
    assert_eq!(
        js(c, "document.getElementById('heatmap').hidden").await,
        json!(true)
    );
    click(c, "#simulate").await;
    wait_for(
        c,
        "document.getElementById('sim-report').textContent.includes('print time')",
        120,
        "the simulation report",
    )
    .await;
    wait_for(c, "document.getElementById('heatmap').complete && document.getElementById('heatmap').naturalWidth > 50", 20, "the heatmap").await;
    assert_eq!(
        js(c, "document.getElementById('sim-progress').value").await,
        json!(1000)
    );
    let report = js(c, "document.getElementById('sim-report').textContent").await;
    assert!(
        report.as_str().unwrap_or_default().contains("boundaries"),
        "{report}"
    );
    assert!(js(c, "document.getElementById('dl-trace') !== null").await == json!(true));
    shot(c, "simulate.png").await;

    // Print on the simulated board: the status is pushed live and reaches 100 %.
    click(c, "#nav-print").await;
    wait_for(c, "['idle', 'unconfigured'].includes(document.querySelector('.board[data-board=\"0\"]')?.dataset.activity)", 30, "the simulated board, connected").await;
    // A second simulated board: listed with its own state and an empty queue.
    wait_for(c, "['idle', 'unconfigured'].includes(document.querySelector('.board[data-board=\"1\"]')?.dataset.activity)", 30, "the second simulated board").await;
    // An idle board: nothing to pause or resume, and the buttons say so on hover.
    for action in ["pause", "resume", "park", "start-next"] {
        let sel = format!(".board[data-board=\"0\"] button[data-action=\"{action}\"]");
        let state = js(
            c,
            &format!("(b => b.disabled && b.title)(document.querySelector('{sel}'))"),
        )
        .await;
        assert!(
            state.as_str().is_some_and(|t| !t.is_empty()),
            "{action} on an idle board: {state}"
        );
    }
    assert_eq!(js(c, "document.querySelector('.board[data-board=\"0\"] button[data-action=\"abort\"]').disabled").await, json!(false));
    click(c, ".board[data-board=\"0\"] button[data-action=\"send\"]").await;
    let t = Instant::now();
    let mut progress_seen = std::collections::BTreeSet::new();
    let mut seq_at_printing = None;
    let mut shot_taken = false;
    loop {
        let p: f64 = board_field(c, "progress").await.parse().unwrap_or(0.0);
        let activity = board_field(c, "activity").await;
        let seq: u64 = board_field(c, "seq").await.parse().unwrap_or(0);
        if activity == "printing" {
            progress_seen.insert((p * 1000.0) as u64);
            seq_at_printing.get_or_insert((Instant::now(), seq));
            if !shot_taken && p > 0.3 {
                shot(c, "print.png").await;
                shot_taken = true;
            }
        }
        if p >= 1.0 && activity.starts_with("finished") {
            break;
        }
        assert!(
            t.elapsed() < Duration::from_secs(180),
            "the print did not finish: {activity} at {p}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let (t0, s0) = seq_at_printing.expect("the board was seen printing");
    let s1: u64 = board_field(c, "seq").await.parse().unwrap_or(0);
    let rate = (s1 - s0) as f64 / t0.elapsed().as_secs_f64();
    eprintln!(
        "print followed: {} distinct progress values while printing, status updates {rate:.1}/s",
        progress_seen.len()
    );
    assert!(
        progress_seen.len() >= 5,
        "progress values seen: {progress_seen:?}"
    );
    assert!(rate >= 5.0, "status pushed {rate:.1} times a second");
    let live = js(
        c,
        "document.querySelector('.board[data-board=\"0\"] .live').textContent",
    )
    .await;
    assert!(
        live.as_str().unwrap_or_default().starts_with("100.0 %"),
        "{live}"
    );
    assert!(
        live.as_str()
            .unwrap_or_default()
            .contains("reference plant"),
        "{live}"
    );
    if !shot_taken {
        shot(c, "print.png").await;
    }
    // Finished: every command done, the clock stopped, print controls off.
    let line = js(
        c,
        "document.querySelector('.board[data-board=\"0\"] .job-line').textContent",
    )
    .await;
    let line = line.as_str().unwrap_or_default().to_string();
    let counts: Vec<&str> = line
        .split(['(', ' '])
        .filter(|w| w.chars().all(|c| c.is_ascii_digit()) && !w.is_empty())
        .collect();
    assert!(
        counts.len() >= 2 && counts[0] == counts[1],
        "a finished job: {line}"
    );
    stopped_clock(c, "finished").await;
    assert_eq!(board_field(c, "eta").await, "0");
    assert_eq!(js(c, "document.querySelector('.board[data-board=\"0\"] button[data-action=\"pause\"]').disabled").await, json!(true));

    // Pause, resume, abort: the same job again (queued behind the finished one, started by
    // Start next once the plate is clear).
    click(c, ".board[data-board=\"0\"] button[data-action=\"send\"]").await;
    wait_for(c, "document.querySelector('.board[data-board=\"0\"] .queue').textContent.includes('chessboard')", 20, "the job queued").await;
    // A second copy queued, then removed by a click held 200 ms (as a person clicks)
    // while the status streams ten times a second.
    click(c, ".board[data-board=\"0\"] button[data-action=\"send\"]").await;
    wait_for(
        c,
        "document.querySelectorAll('.board[data-board=\"0\"] .queue .unqueue').length === 2",
        20,
        "two jobs queued",
    )
    .await;
    held_click(
        c,
        ".board[data-board=\"0\"] .queue .queued:last-child .unqueue",
        200,
    )
    .await;
    wait_for(
        c,
        "document.querySelectorAll('.board[data-board=\"0\"] .queue .unqueue').length === 1",
        20,
        "the second job removed by a held click",
    )
    .await;
    click(
        c,
        ".board[data-board=\"0\"] button[data-action=\"start-next\"]",
    )
    .await;
    wait_for(c, "document.querySelector('.board[data-board=\"0\"]').dataset.activity === 'printing' && Number(document.querySelector('.board[data-board=\"0\"]').dataset.progress) > 0.05", 60, "the second print running").await;
    click(c, ".board[data-board=\"0\"] button[data-action=\"pause\"]").await;
    wait_for(
        c,
        "document.querySelector('.board[data-board=\"0\"]').dataset.activity === 'paused'",
        30,
        "the print paused",
    )
    .await;
    let p_paused: f64 = board_field(c, "progress").await.parse().unwrap_or(0.0);
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let p_later: f64 = board_field(c, "progress").await.parse().unwrap_or(0.0);
    assert_eq!(p_paused, p_later, "progress moved while paused");
    shot(c, "paused.png").await;
    click(c, ".board[data-board=\"0\"] button[data-action=\"resume\"]").await;
    // Resumed, it goes on from where it paused (the pause ended a bead, so what is left
    // may be short): it runs to the end.
    wait_for(c, &format!("document.querySelector('.board[data-board=\"0\"]').dataset.activity !== 'paused' && Number(document.querySelector('.board[data-board=\"0\"]').dataset.progress) > {p_paused}"), 30, "the print resumed").await;
    // A bead ends the pause: the chessboard is two long beads, so the print may be near
    // its end now. Let it finish, then abort a third run early.
    wait_for(c, "document.querySelector('.board[data-board=\"0\"]').dataset.activity.startsWith('finished')", 60, "the resumed print finished").await;
    click(c, ".board[data-board=\"0\"] button[data-action=\"send\"]").await;
    wait_for(c, "document.querySelector('.board[data-board=\"0\"] .queue').textContent.includes('chessboard')", 20, "the job queued again").await;
    click(
        c,
        ".board[data-board=\"0\"] button[data-action=\"start-next\"]",
    )
    .await;
    wait_for(c, "document.querySelector('.board[data-board=\"0\"]').dataset.activity === 'printing' && Number(document.querySelector('.board[data-board=\"0\"]').dataset.progress) > 0.05", 60, "the third print running").await;
    click(c, ".board[data-board=\"0\"] button[data-action=\"abort\"]").await;
    wait_for(
        c,
        "document.querySelector('.board[data-board=\"0\"]').dataset.activity === 'aborted'",
        30,
        "the print aborted",
    )
    .await;
    let p_abort: f64 = board_field(c, "progress").await.parse().unwrap_or(1.0);
    assert!(p_abort < 1.0, "aborted at {p_abort}");
    // Aborted: the clock stops, no ETA, no speed, the print controls off.
    stopped_clock(c, "aborted").await;
    assert_eq!(board_field(c, "eta").await, "");
    let live = js(
        c,
        "document.querySelector('.board[data-board=\"0\"] .live').textContent",
    )
    .await;
    assert!(
        live.as_str().unwrap_or_default().contains(" 0.0 mm/s"),
        "after abort: {live}"
    );
    assert_eq!(js(c, "document.querySelector('.board[data-board=\"0\"] button[data-action=\"resume\"]').disabled").await, json!(true));
    // The history lists the two finished prints and the aborted one.
    wait_for(c, "document.querySelectorAll('#history tr[data-outcome=\"finished\"]').length === 2 && document.querySelectorAll('#history tr[data-outcome=\"aborted\"]').length === 1", 20, "the history of board 0").await;
    assert_eq!(
        js(
            c,
            "document.querySelector('.board[data-board=\"0\"] .board-msg').textContent"
        )
        .await,
        json!("")
    );

    // A second tab sees the board but may not command it until it takes control.
    let first = c.window().await.expect("this window");
    let second = c.new_window(true).await.expect("a second tab").handle;
    c.switch_to_window(second)
        .await
        .expect("switch to the second tab");
    c.goto(base).await.expect("open the dashboard again");
    click(c, "#nav-print").await;
    wait_for(
        c,
        "document.querySelector('.board[data-board=\"0\"]')?.dataset.activity === 'aborted'",
        20,
        "the board's state in the second tab",
    )
    .await;
    // A fresh page (as a reload): the same stopped status, no message left from before.
    stopped_clock(c, "aborted, seen from a fresh page").await;
    assert_eq!(
        js(c, "lastBoards.boards[0].message").await,
        Value::Null,
        "a stale message"
    );
    click(c, ".board[data-board=\"0\"] button[data-action=\"home\"]").await;
    let refused = wait_for(c, "document.getElementById('toast').textContent.includes('another tab') && document.getElementById('toast').textContent", 20, "the second tab refused").await;
    eprintln!("second tab: {refused}");
    assert!(!js(
        c,
        "document.querySelector('.board[data-board=\"0\"] .take').hidden"
    )
    .await
    .as_bool()
    .unwrap_or(true));
    shot(c, "second-tab.png").await;
    click(c, ".board[data-board=\"0\"] .take").await;
    wait_for(
        c,
        "document.querySelector('.board[data-board=\"0\"] .take').hidden",
        20,
        "control taken",
    )
    .await;
    click(c, ".board[data-board=\"0\"] button[data-action=\"home\"]").await;
    wait_for(
        c,
        "document.getElementById('toast').textContent === 'homing'",
        20,
        "homing ordered from the second tab",
    )
    .await;
    c.close_window().await.expect("close the second tab");
    c.switch_to_window(first)
        .await
        .expect("back to the first tab");

    // Calibrate: the bundled puree flow curve is fitted, and its fragment applied to
    // inlet 0 of the config in the editor.
    click(c, "#nav-calibrate").await;
    // Before any fit: no broken picture, and the bundled samples offered for the fit.
    assert_eq!(
        js(c, "document.getElementById('cal-plot').hidden").await,
        json!(true)
    );
    let samples = js(c, "Array.from(document.querySelectorAll('#cal-sample option')).map(o => o.textContent).join(' ')").await;
    assert!(
        samples
            .as_str()
            .unwrap_or_default()
            .contains("rheology-puree.csv"),
        "{samples}"
    );
    let csv = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/calibration/rheology-puree.csv");
    c.find(Locator::Id("cal-file"))
        .await
        .expect("CSV picker")
        .send_keys(&csv.display().to_string())
        .await
        .expect("choosing the CSV");
    click(c, "#cal-run").await;
    wait_for(c, "document.getElementById('cal-report').textContent.includes('power law') && document.getElementById('cal-plot').complete && document.getElementById('cal-plot').naturalWidth > 100", 60, "the rheology fits and plot").await;
    let fragment = js(c, "document.getElementById('cal-fragment').textContent").await;
    assert!(
        fragment
            .as_str()
            .unwrap_or_default()
            .contains("rheology = "),
        "{fragment}"
    );
    shot(c, "calibrate.png").await;
    click(c, "#cal-apply").await;
    wait_for(c, "document.querySelector('.field[data-path=\"inlet[0].rheology\"] input')?.value.includes('power_law')", 20, "the fragment in the config's inlet 0").await;

    // Flow: two pastes' flow against pressure (mass flows, with the density), fitted in
    // the channel of the Design page's config; the two [[inlet]] tables fill inlets 0, 1.
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/calibration");
    js(c, "(document.getElementById('cal-what').value = 'flow', document.getElementById('cal-what').dispatchEvent(new Event('change')), true)").await;
    c.find(Locator::Id("cal-density"))
        .await
        .expect("density")
        .send_keys("1.05")
        .await
        .expect("type");
    c.find(Locator::Id("cal-file"))
        .await
        .expect("CSV picker")
        .send_keys(&data.join("flow-two-pastes.csv").display().to_string())
        .await
        .expect("choosing the CSV");
    click(c, "#cal-run").await;
    wait_for(c, "document.getElementById('cal-report').textContent.includes('custard') && document.getElementById('cal-fragment').textContent.includes('[[inlet]]')", 60, "the flow fits").await;
    shot(c, "calibrate-flow.png").await;
    click(c, "#cal-apply").await;
    wait_for(c, "document.querySelector('.field[data-path=\"inlet[1].material\"] input')?.value.includes('custard') && document.querySelector('.field[data-path=\"inlet[0].material\"] input')?.value.includes('puree')", 20, "the flow fragment in inlets 0 and 1").await;

    // Lag: a valve's start-up curve gives its dead time and rise, applied to inlet 0.
    js(c, "(document.getElementById('cal-what').value = 'lag', document.getElementById('cal-what').dispatchEvent(new Event('change')), true)").await;
    c.find(Locator::Id("cal-file"))
        .await
        .expect("CSV picker")
        .send_keys(&data.join("lag-valve.csv").display().to_string())
        .await
        .expect("choosing the CSV");
    click(c, "#cal-run").await;
    let frag = wait_for(c, "document.getElementById('cal-fragment').textContent.includes('valve_open_delay_ms') && document.getElementById('cal-fragment').textContent", 60, "the lag fit").await;
    shot(c, "calibrate-lag.png").await;
    let delay = frag
        .as_str()
        .unwrap_or_default()
        .lines()
        .find_map(|l| l.strip_prefix("valve_open_delay_ms = "))
        .unwrap_or_default()
        .trim()
        .to_string();
    click(c, "#cal-apply").await;
    wait_for(c, &format!("document.querySelector('.field[data-path=\"inlet[0].valve_open_delay_ms\"] input')?.value === '{delay}'"), 20, "the lag fragment in inlet 0").await;

    // Camera frames: two dropped on the page (a drop event carrying the files), one of
    // them corrupt, are refused naming it; then the bundled frames through the multiple
    // picker (30 fps, 0.02 mm per pixel, a 1.2 mm line): a missing scale is refused, then
    // the speed and width are those the command measures, and the head speed for the
    // line is applied to [motion] of the config.
    let frames_dir = data.join("camera");
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&frames_dir)
        .expect("the bundled frames")
        .map(|e| e.expect("a frame").path())
        .collect();
    frames.sort();
    let b64 = {
        use base64::Engine;
        base64::engine::general_purpose::STANDARD
            .encode(std::fs::read(&frames[0]).expect("a frame"))
    };
    js(c, &format!("(() => {{ const b = Uint8Array.from(atob('{b64}'), (ch) => ch.charCodeAt(0)); const dt = new DataTransfer(); dt.items.add(new File([b], 'a.png')); dt.items.add(new File(['not a picture'], 'b.png')); document.getElementById('cal-drop').dispatchEvent(new DragEvent('drop', {{ dataTransfer: dt, bubbles: true, cancelable: true }})); return true; }})()")).await;
    assert_eq!(
        js(c, "document.getElementById('cal-what').value").await,
        json!("camera")
    );
    for (id, v) in [
        ("cam-fps", "30"),
        ("cam-mm_per_px", "0.02"),
        ("cam-target_width", "1.2"),
    ] {
        c.find(Locator::Id(id))
            .await
            .unwrap_or_else(|e| panic!("no {id}: {e}"))
            .send_keys(v)
            .await
            .expect("type");
    }
    click(c, "#cal-run").await;
    let msg = wait_for(c, "!document.getElementById('cal-error').hidden && document.getElementById('cal-error').textContent", 30, "the corrupt frame's message").await;
    let msg = msg.as_str().unwrap_or_default();
    assert!(
        msg.starts_with("b.png: ") && msg.contains("leave it out"),
        "{msg}"
    );
    eprintln!("corrupt frame: {msg}");
    js(
        c,
        "(document.getElementById('cal-frames').value = '', true)",
    )
    .await;
    c.find(Locator::Id("cal-frames"))
        .await
        .expect("frame picker")
        .send_keys(
            &frames
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join("\n"),
        )
        .await
        .expect("choosing the frames");
    wait_for(
        c,
        "document.getElementById('cal-frames-list').textContent.startsWith('12 frames')",
        10,
        "the frames listed",
    )
    .await;
    c.find(Locator::Id("cam-mm_per_px"))
        .await
        .expect("scale")
        .clear()
        .await
        .expect("clear");
    click(c, "#cal-run").await;
    let msg = wait_for(c, "!document.getElementById('cal-error').hidden && document.getElementById('cal-error').textContent.includes('mm per pixel') && document.getElementById('cal-error').textContent", 30, "the missing scale's message").await;
    eprintln!("missing scale: {msg}");
    c.find(Locator::Id("cam-mm_per_px"))
        .await
        .expect("scale")
        .send_keys("0.02")
        .await
        .expect("type");
    click(c, "#cal-run").await;
    let report = wait_for(c, "document.getElementById('cal-error').hidden && document.getElementById('cal-report').textContent.startsWith('camera: 12 frames') && document.getElementById('cal-plot').complete && document.getElementById('cal-plot').naturalWidth > 100 && document.getElementById('cal-report').textContent", 60, "the camera figures and plot").await;
    let report = report.as_str().unwrap_or_default();
    // Rendered at 4.5 px/frame and 48 px: 2.7 mm/s and 0.96 mm, as the command finds.
    assert!(
        report.contains("V_ex = 2.70") && report.contains("D_ex = 0.96"),
        "{report}"
    );
    let frag = js(c, "document.getElementById('cal-fragment').textContent").await;
    let speed = frag
        .as_str()
        .unwrap_or_default()
        .lines()
        .find_map(|l| l.strip_prefix("print_speed_mm_s = "))
        .unwrap_or_else(|| panic!("no print speed in {frag}"))
        .trim()
        .to_string();
    eprintln!("camera: {report}print_speed_mm_s = {speed}");
    // The lag's toast would cover the plot.
    js(
        c,
        "(window.scrollTo(0, 0), document.getElementById('toast').hidden = true, true)",
    )
    .await;
    shot(c, "calibrate-camera.png").await;
    click(c, "#cal-apply").await;
    wait_for(c, &format!("document.querySelector('.field[data-path=\"motion.print_speed_mm_s\"] input')?.value === '{speed}'"), 20, "the camera fragment in [motion]").await;
    let toast = js(c, "document.getElementById('toast').textContent").await;
    assert!(
        toast
            .as_str()
            .unwrap_or_default()
            .contains("motion.print_speed_mm_s"),
        "{toast}"
    );

    // Straight to the server, past the page's own checks: one frame over the count limit
    // is refused when it arrives, and frames over the byte limit get the frames' message.
    let post = |files: &str| {
        format!("(window.camPost = null, (async () => {{ const f = new FormData(); {files}; f.append('fps', '30'); f.append('mm_per_px', '0.02'); try {{ const r = await fetch('/api/calibrate/camera', {{ method: 'POST', body: f }}); window.camPost = [r.status, (await r.json()).error]; }} catch (e) {{ window.camPost = [0, String(e)]; }} }})(), true)")
    };
    js(c, &post("for (let i = 0; i <= 2000; i++) f.append('frames', new File([new Uint8Array(8)], `f${String(i).padStart(4, '0')}.png`))")).await;
    let v = wait_for(c, "window.camPost", 60, "the answer to 2001 frames").await;
    eprintln!("2001 frames: {v}");
    assert_eq!(v[0], json!(400), "{v}");
    assert!(
        v[1].as_str()
            .unwrap_or_default()
            .starts_with("more than 2000 frames"),
        "{v}"
    );
    js(
        c,
        &post("f.append('frames', new File([new Uint8Array(65 * 1024 * 1024)], 'big.png'))"),
    )
    .await;
    let v = wait_for(c, "window.camPost", 60, "the answer to 65 MiB of frames").await;
    eprintln!("65 MiB of frames: {v}");
    assert_eq!(v[0], json!(413), "{v}");
    assert!(
        v[1].as_str()
            .unwrap_or_default()
            .contains("the frames are larger than the 64 MiB"),
        "{v}"
    );

    // Board 1 prints the chessboard; the browser is closed mid-print by the caller.
    click(c, "#nav-print").await;
    click(c, ".board[data-board=\"1\"] button[data-action=\"send\"]").await;
    wait_for(c, "document.querySelector('.board[data-board=\"1\"]').dataset.activity === 'printing' && Number(document.querySelector('.board[data-board=\"1\"]').dataset.progress) > 0.05", 60, "board 1 printing").await;
    phone(c).await;
    field_of(c, 1, "progress").await.parse().unwrap_or(0.0)
}

/// At a phone's width (390 px) while board 1 prints: no page scrolls sideways, and its
/// Abort is on screen on every page (in the header) and on the Print page (on its card).
async fn phone(c: &Client) {
    c.set_window_size(390, 844).await.expect("phone width");
    wait_for(
        c,
        "window.innerWidth <= 400",
        10,
        "the window at phone width",
    )
    .await;
    // On screen: inside the viewport's width and height (the header stays on top).
    let on_screen = |css: &str| {
        format!("(e => {{ if (!e) return false; const r = e.getBoundingClientRect(); return r.width > 0 && r.left >= 0 && r.right <= window.innerWidth && r.top >= 0 && r.bottom <= window.innerHeight; }})(document.querySelector('{css}'))")
    };
    for page in ["design", "simulate", "calibrate", "files", "print"] {
        click(c, &format!("#nav-{page}")).await;
        let widths = js(
            c,
            "[document.documentElement.scrollWidth, window.innerWidth]",
        )
        .await;
        eprintln!("{page} at phone width: page and window widths {widths}");
        assert!(
            widths[0].as_f64() <= widths[1].as_f64(),
            "{page} scrolls sideways: {widths}"
        );
        let abort = on_screen("#header-boards .badge[data-board=\"1\"] .abort-now");
        assert_eq!(
            js(c, &abort).await,
            json!(true),
            "{page}: the header's Abort for board 1 off screen"
        );
        shot(c, &format!("phone-{page}.png")).await;
    }
    // The card's own print controls: scrolled to, within the width (no sideways scroll).
    js(c, "(document.querySelector('.board[data-board=\"1\"] button[data-action=\"abort\"]').scrollIntoView({block: 'center'}), true)").await;
    let abort = on_screen(".board[data-board=\"1\"] button[data-action=\"abort\"]");
    assert_eq!(js(c, &abort).await, json!(true), "the card's Abort");
    c.set_window_size(1400, 1000).await.expect("desktop width");
}
