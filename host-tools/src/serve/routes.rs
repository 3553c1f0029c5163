//! The dashboard's HTTP API and pages: the router, and thin handlers that parse the
//! request, hand the work to `design`, `simulate_page`, `calibrate` or a board's worker
//! (blocking work off the async threads), and answer JSON, files, or server-sent events
//! (simulation progress, board status ten times a second). Every failure is an `ApiError`
//! the page shows.

use super::assets;
use super::boards::{Fallback, View, WorkerOrder};
use super::design::{self, Field, SliceForm, Upload};
use super::error::{ApiError, ApiResult};
use super::reply::{blocking, download, job_json, job_value, mime, stem};
use super::simulate_page::{self, SimRun};
use super::state::{lock, AppState, JobEntry};
use axum::extract::{DefaultBodyLimit, Multipart, Path, Query, State};
use axum::http::header;
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use futures_util::stream::Stream;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

type St = State<Arc<AppState>>;

/// The router of every page and API call.
pub fn router(state: Arc<AppState>) -> Router {
    Router::new()
        .route("/", get(assets::index))
        .route("/assets/app.js", get(assets::js))
        .route("/assets/app.css", get(assets::css))
        .route("/favicon.svg", get(assets::favicon))
        .route("/favicon.ico", get(assets::favicon))
        .route(
            "/login",
            get(super::gate::login_page).post(super::gate::login),
        )
        .route("/api/info", get(info))
        .route("/api/configs/{i}", get(config_get))
        .route("/api/config/check", post(config_check))
        .route("/api/designs/{i}", get(bundled_design))
        .route("/api/samples/{i}", get(sample))
        .route("/api/slice", post(slice))
        .route("/api/jobs/{id}", get(job_get))
        .route("/api/jobs/{id}/{file}", get(job_file))
        .route("/api/jobs/{id}/simulate", post(sim_start))
        .route("/api/sims/{id}", get(sim_get))
        .route("/api/sims/{id}/events", get(sim_events))
        .route("/api/sims/{id}/{file}", get(sim_file))
        .route("/api/calibrate/{what}", post(calibrate))
        .route("/api/boards/events", get(board_events))
        .route("/api/history", get(history))
        .route("/api/boards/{id}/{action}", post(board_action))
        .merge(super::files::routes())
        .merge(super::octoprint::routes())
        .merge(super::snapshot::routes())
        .fallback(|| async { ApiError::missing("no such page") })
        .layer(DefaultBodyLimit::max(super::MAX_UPLOAD))
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            super::gate::guard,
        ))
        .with_state(state)
}

async fn info(State(st): St) -> Json<serde_json::Value> {
    Json(json!({
        "configs": st.configs.iter().map(|c| c.name.clone()).collect::<Vec<_>>(),
        "designs": design::DESIGNS.iter().map(|d| d.0).collect::<Vec<_>>(),
        "max_upload_mb": super::MAX_UPLOAD >> 20,
        "camera_max_frames": super::calibrate::CAMERA_LIMITS.max_frames,
        "camera_max_pixels": super::calibrate::CAMERA_LIMITS.max_pixels,
        "demo_job": st.demo_job,
        "samples": super::samples::SAMPLES
            .iter()
            .map(|s| json!({ "name": s.name, "what": s.what, "with": s.with }))
            .collect::<Vec<_>>(),
        "boards": st.boards.len(),
        "camera": st.camera,
    }))
}

async fn history(State(st): St) -> Json<serde_json::Value> {
    Json(json!({
        "records": st.history.list(),
        "stats": st.history.stats(),
        "skipped": st.history.skipped,
    }))
}

#[derive(Serialize)]
struct ConfigView {
    name: String,
    text: String,
    fields: Vec<Field>,
    derived: Vec<(String, String)>,
}

async fn config_get(State(st): St, Path(i): Path<usize>) -> ApiResult<Json<ConfigView>> {
    let c = st
        .configs
        .get(i)
        .ok_or_else(|| ApiError::missing("no such config"))?;
    let checked = design::check(&c.text)?;
    Ok(Json(ConfigView {
        name: c.name.clone(),
        text: checked.text,
        fields: checked.fields,
        derived: checked.derived.figures,
    }))
}

#[derive(Deserialize)]
struct CheckReq {
    text: String,
    #[serde(default)]
    edits: Vec<Field>,
}

async fn config_check(Json(r): Json<CheckReq>) -> ApiResult<Json<ConfigView>> {
    let text = design::apply(&r.text, &r.edits)?;
    let checked = design::check(&text)?;
    Ok(Json(ConfigView {
        name: String::new(),
        text: checked.text,
        fields: checked.fields,
        derived: checked.derived.figures,
    }))
}

async fn bundled_design(Path(i): Path<usize>) -> ApiResult<Response> {
    let (name, bytes) = design::DESIGNS
        .get(i)
        .ok_or_else(|| ApiError::missing("no such design"))?;
    Ok((
        [
            (header::CONTENT_TYPE, mime(name)),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{name}\""),
            ),
        ],
        bytes.to_vec(),
    )
        .into_response())
}

async fn sample(Path(i): Path<usize>) -> ApiResult<Response> {
    let s = super::samples::SAMPLES
        .get(i)
        .ok_or_else(|| ApiError::missing("no such sample"))?;
    Ok(download(s.name.to_string(), s.bytes.to_vec()))
}

async fn slice(State(st): St, mut mp: Multipart) -> ApiResult<Response> {
    let mut uploads = Vec::new();
    let mut text = None;
    let mut form = SliceForm::default();
    while let Some(field) = mp.next_field().await? {
        match field.name().unwrap_or("") {
            "design" => {
                let name = field.file_name().unwrap_or("design").to_string();
                let bytes = field.bytes().await?;
                if !bytes.is_empty() {
                    uploads.push(Upload {
                        name,
                        bytes: bytes.to_vec(),
                    });
                }
            }
            "config" => text = Some(field.text().await?),
            "options" => {
                let t = field.text().await?;
                form = serde_json::from_str(&t)
                    .map_err(|e| ApiError::bad(format!("slicing options: {e}")))?;
            }
            _ => {}
        }
    }
    let text = text.ok_or_else(|| ApiError::bad("choose a machine config"))?;
    let checked = design::check(&text)?;
    let st2 = st.clone();
    let entry = blocking(move || {
        let sliced = design::slice(&uploads, &checked.config, &form)?;
        let job = st2.add_job(checked.config, checked.text, sliced);
        let kept = super::files::keep_sliced(&st2, &uploads, &job);
        Ok((job, kept))
    })
    .await?;
    // The kept job's name: a reload of the page opens it again.
    let (entry, kept) = entry;
    let mut v = job_value(&entry);
    v["kept"] = json!(kept);
    Ok(Json(v).into_response())
}

fn job_of(st: &AppState, id: u64) -> ApiResult<Arc<JobEntry>> {
    st.job(id).ok_or_else(|| {
        ApiError::missing(format!(
            "job {id} is no longer kept (the dashboard keeps the last {}); slice it again",
            super::state::KEEP
        ))
    })
}

async fn job_get(State(st): St, Path(id): Path<u64>) -> ApiResult<Response> {
    let e = job_of(&st, id)?;
    Ok(job_json(&e))
}

async fn job_file(State(st): St, Path((id, file)): Path<(u64, String)>) -> ApiResult<Response> {
    let e = job_of(&st, id)?;
    let stem = stem(&e);
    match file.as_str() {
        "job.dlp" => Ok(download(format!("{stem}.dlp"), e.sliced.to_bytes())),
        "config.toml" => Ok(download(
            format!("{stem}-machine.toml"),
            e.config_text.clone().into_bytes(),
        )),
        "preview.png" => {
            let bytes = blocking(move || {
                let img = crate::slicer::preview::draw(
                    &e.sliced.commands,
                    e.sliced.header.start_um,
                    &crate::slicer::preview::PreviewOptions {
                        bead_mm: e.config.channel.line_pitch_mm as f64,
                        ..Default::default()
                    },
                );
                super::reply::png(&img)
            })
            .await?;
            Ok(download(format!("{stem}-toolpath.png"), bytes))
        }
        "job.gcode" => {
            let text = blocking(move || {
                let names = crate::slicer::material_names(&e.config);
                crate::slicer::gcode_exec::export(
                    &e.config,
                    &e.sliced.commands,
                    e.sliced.header.start_um,
                    e.sliced.header.initial_material,
                    &names,
                    &crate::slicer::gcode_exec::RunExport::default(),
                )
                .map(|(t, _)| t)
                .map_err(|e| ApiError::bad(e.to_string()))
            })
            .await?;
            Ok(download(format!("{stem}.gcode"), text.into_bytes()))
        }
        _ => Err(ApiError::missing("no such file")),
    }
}

async fn sim_start(State(st): St, Path(id): Path<u64>) -> ApiResult<Json<serde_json::Value>> {
    let e = job_of(&st, id)?;
    let run = Arc::new(SimRun::new());
    let sim = st.add_sim(run.clone());
    let job = dollop_sim::Job {
        start_um: e.sliced.header.start_um,
        initial_material: e.sliced.header.initial_material,
        commands: e.sliced.commands.clone(),
    };
    std::thread::Builder::new()
        .name(format!("sim-{sim}"))
        .spawn(move || {
            // A panic in the run must not leave the page waiting for ever.
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| simulate_page::simulate(&run, &e.config, &job)));
            if r.is_err() {
                *lock(&run.state) = simulate_page::SimState::Failed("the simulation stopped on an internal error (a bug: please report it with the design and config)".into());
            }
        })
        .map_err(|e| ApiError::internal(format!("cannot start the simulation: {e}")))?;
    Ok(Json(json!({ "sim": sim })))
}

fn sim_of(st: &AppState, id: u64) -> ApiResult<Arc<SimRun>> {
    st.sim(id).ok_or_else(|| {
        ApiError::missing(format!("simulation {id} is no longer kept; run it again"))
    })
}

fn outcome(run: &SimRun) -> ApiResult<Arc<simulate_page::Outcome>> {
    match run.outcome() {
        Ok(Some(o)) => Ok(o),
        Ok(None) => Err(ApiError::conflict("the simulation is still running")),
        Err(m) => Err(ApiError::bad(format!("the simulation failed: {m}"))),
    }
}

async fn sim_get(State(st): St, Path(id): Path<u64>) -> ApiResult<Response> {
    let o = outcome(&*sim_of(&st, id)?)?;
    Ok(Json(json!({
        "report": o.report,
        "figures": o.figures,
        "series": o.series,
    }))
    .into_response())
}

async fn sim_file(State(st): St, Path((id, file)): Path<(u64, String)>) -> ApiResult<Response> {
    let o = outcome(&*sim_of(&st, id)?)?;
    match file.as_str() {
        "heatmap.png" => {
            Ok(([(header::CONTENT_TYPE, "image/png")], o.heatmap_png.clone()).into_response())
        }
        "trace.csv" => {
            let path = o.trace.path().to_path_buf();
            let bytes = tokio::fs::read(&path)
                .await
                .map_err(|e| ApiError::internal(format!("cannot read the trace: {e}")))?;
            Ok(download(format!("trace-{id}.csv"), bytes))
        }
        "report.txt" => Ok(download(
            format!("report-{id}.txt"),
            o.report.clone().into_bytes(),
        )),
        _ => Err(ApiError::missing("no such file")),
    }
}

async fn sim_events(
    State(st): St,
    Path(id): Path<u64>,
) -> ApiResult<Sse<impl Stream<Item = Result<Event, Infallible>>>> {
    let run = sim_of(&st, id)?;
    let stream = futures_util::stream::unfold(Some(run), |run| async move {
        let run = run?;
        tokio::time::sleep(Duration::from_millis(150)).await;
        let permille = run.permille.load(std::sync::atomic::Ordering::Relaxed);
        let ev = match run.outcome() {
            Ok(None) => {
                return Some((
                    Ok(Event::default()
                        .event("progress")
                        .data(permille.to_string())),
                    Some(run),
                ))
            }
            Ok(Some(_)) => Event::default().event("done").data("1000"),
            Err(m) => Event::default().event("failed").data(m),
        };
        Some((Ok(ev), None))
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

#[derive(Deserialize)]
struct TabQuery {
    tab: String,
}

/// Marks a tab's status stream closed when the stream is dropped (the tab went away).
struct TabGuard {
    st: Arc<AppState>,
    tab: String,
}

impl Drop for TabGuard {
    fn drop(&mut self) {
        self.st.tab_closed(&self.tab);
    }
}

async fn board_events(
    State(st): St,
    Query(q): Query<TabQuery>,
) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    st.tab_open(&q.tab);
    let guard = TabGuard {
        st: st.clone(),
        tab: q.tab,
    };
    let stream = futures_util::stream::unfold(guard, |g| async move {
        tokio::time::sleep(Duration::from_millis(100)).await;
        let views: Vec<View> =
            g.st.boards
                .iter()
                .map(|b| b.view.borrow().clone())
                .collect();
        let controllers: Vec<Option<String>> =
            g.st.boards
                .iter()
                .map(|b| lock(&b.controller).clone())
                .collect();
        // Only the newest trend sample and the console's number go with the status (the
        // page fetches the rest once), so each update stays the same size.
        let trend: Vec<Option<super::console::Sample>> = (0..g.st.boards.len())
            .map(|i| g.st.console.latest(i))
            .collect();
        let data = json!({
            "boards": views,
            "controllers": controllers,
            "trend": trend,
            "console_seq": g.st.console.seq(),
        })
        .to_string();
        Some((Ok(Event::default().event("boards").data(data)), g))
    });
    Sse::new(stream).keep_alive(KeepAlive::default())
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct ActionReq {
    tab: String,
    force: bool,
    job: Option<u64>,
    axis: Option<String>,
    mm: Option<f64>,
    inlet: Option<u8>,
    seconds: Option<f64>,
    /// The config chosen on the Design page (TOML), for home, jog and valve tests on a
    /// board without one.
    config: Option<String>,
}

async fn board_action(
    State(st): St,
    Path((id, action)): Path<(usize, String)>,
    Json(r): Json<ActionReq>,
) -> ApiResult<Json<serde_json::Value>> {
    let b = st
        .board(id)
        .ok_or_else(|| ApiError::missing(format!("there is no board {id}")))?;
    if r.tab.is_empty() {
        return Err(ApiError::bad(
            "the page did not say which tab it is; reload it",
        ));
    }
    // One tab commands a board at a time: another tab's orders are refused (its status
    // stays visible) until the commanding tab closes or this one takes over.
    {
        let mut ctl = lock(&b.controller);
        if let Some(owner) = ctl.as_ref() {
            if *owner != r.tab && st.tab_alive(owner) && !r.force {
                return Err(ApiError::conflict(
                    "another tab or browser is commanding this board; its orders are not mixed with yours. Close that tab, or press Take control here",
                ));
            }
        }
        *ctl = Some(r.tab.clone());
    }
    // Home, jog and valve tests before any job: the Design page's config, else --config.
    let fallback = || -> ApiResult<Fallback> {
        match r.config.as_deref() {
            Some(text) => design::check(text)
                .map(|c| Some(Box::new(c.config)))
                .map_err(|e| {
                    ApiError::bad(format!(
                        "the config chosen on the Design page does not check ({}); fix it there first",
                        e.message()
                    ))
                }),
            None => Ok(st.cli_config.clone().map(Box::new)),
        }
    };
    let order = match action.as_str() {
        "claim" => {
            return Ok(Json(
                json!({ "message": "this tab now commands the board" }),
            ))
        }
        "send" => {
            let id = r.job.ok_or_else(|| ApiError::bad("slice a job first"))?;
            WorkerOrder::Send(job_of(&st, id)?)
        }
        "start-next" => WorkerOrder::StartNext,
        "unqueue" => WorkerOrder::Unqueue(r.job.ok_or_else(|| ApiError::bad("which job?"))?),
        "pause" => WorkerOrder::Pause,
        "park" => WorkerOrder::Park,
        "resume" => WorkerOrder::Resume,
        "abort" => {
            let name = b.view.borrow().name.clone();
            return match b.abort().await {
                Ok(m) => {
                    st.console.info(&name, format!("abort: {m}"));
                    Ok(Json(json!({ "message": m })))
                }
                Err(m) => {
                    st.console.error(&name, format!("abort refused: {m}"));
                    Err(ApiError::conflict(m))
                }
            };
        }
        "home" => WorkerOrder::Home(fallback()?),
        "jog" => {
            let axis = match r.axis.as_deref() {
                Some("x") | Some("X") => dollop::Axis::X,
                Some("y") | Some("Y") => dollop::Axis::Y,
                Some("z") | Some("Z") => dollop::Axis::Z,
                _ => return Err(ApiError::bad("jog: choose the axis x, y or z")),
            };
            WorkerOrder::Jog(
                axis,
                r.mm.ok_or_else(|| ApiError::bad("jog: give a distance in mm"))?,
                fallback()?,
            )
        }
        "valve" => WorkerOrder::Valve(
            r.inlet
                .ok_or_else(|| ApiError::bad("valve test: choose an inlet"))?,
            r.seconds.unwrap_or(1.0),
            fallback()?,
        ),
        other => return Err(ApiError::missing(format!("no board action {other:?}"))),
    };
    let name = b.view.borrow().name.clone();
    match b.order(order).await {
        Ok(m) => {
            st.console.info(&name, format!("{action}: {m}"));
            Ok(Json(json!({ "message": m })))
        }
        Err(m) => {
            st.console.error(&name, format!("{action} refused: {m}"));
            Err(ApiError::conflict(m))
        }
    }
}

/// The Design page's config sent with a calibration (flow, camera), checked; none when
/// the page sent none.
fn design_config(text: Option<&str>) -> ApiResult<Option<dollop::config::Config>> {
    match text.filter(|t| !t.trim().is_empty()) {
        Some(t) => Ok(Some(
            design::check(t)
                .map_err(|e| {
                    ApiError::bad(format!(
                        "the Design page's config does not check ({}); fix it there first",
                        e.message()
                    ))
                })?
                .config,
        )),
        None => Ok(None),
    }
}

async fn calibrate(
    Path(what): Path<String>,
    mut mp: Multipart,
) -> ApiResult<Json<super::calibrate::Shown>> {
    use super::calibrate::{CameraForm, CAMERA_LIMITS};
    let mut data = None;
    let (mut kind, mut inlet, mut config, mut density) =
        (String::new(), String::new(), None, String::new());
    let mut frames: Vec<Upload> = Vec::new();
    let mut cam = CameraForm::default();
    let read = async {
        while let Some(field) = mp.next_field().await? {
            match field.name().unwrap_or("") {
                "data" => {
                    let name = field.file_name().unwrap_or("data.csv").to_string();
                    data = Some((name, field.bytes().await?.to_vec()));
                }
                "frames" => {
                    // Past the limit the rest is not read: the refusal comes at once.
                    if frames.len() >= CAMERA_LIMITS.max_frames {
                        return Err(super::calibrate::too_many_frames(CAMERA_LIMITS.max_frames));
                    }
                    let name = field.file_name().unwrap_or("frame").to_string();
                    let bytes = field.bytes().await?.to_vec();
                    frames.push(Upload { name, bytes });
                }
                "kind" => kind = field.text().await?,
                "inlet" => inlet = field.text().await?,
                "config" => config = Some(field.text().await?),
                "density" => density = field.text().await?,
                "fps" => cam.fps = field.text().await?,
                "mm_per_px" => cam.mm_per_px = field.text().await?,
                "target_width" => cam.target_width = field.text().await?,
                "nozzle" => cam.nozzle = field.text().await?,
                "roi" => cam.roi = field.text().await?,
                "window" => cam.window = field.text().await?,
                _ => {}
            }
        }
        Ok::<(), ApiError>(())
    }
    .await;
    if let Err(e) = read {
        // Frames over the byte limit: say what to do with frames, not with a design.
        return Err(
            if what == "camera" && e.status() == axum::http::StatusCode::PAYLOAD_TOO_LARGE {
                super::calibrate::frames_too_large()
            } else {
                e
            },
        );
    }
    if what == "camera" {
        let config = design_config(config.as_deref())?;
        return Ok(Json(
            blocking(move || super::calibrate::camera(&frames, &cam, config, CAMERA_LIMITS))
                .await?,
        ));
    }
    let (name, bytes) = data.ok_or_else(|| ApiError::bad("choose a measurement CSV"))?;
    Ok(Json(match what.as_str() {
        "rheology" => blocking(move || super::calibrate::rheology(&name, &bytes, &kind)).await?,
        "lag" => blocking(move || super::calibrate::lag(&name, &bytes, &inlet)).await?,
        "flow" => {
            let config = design_config(config.as_deref())?;
            let density = match density.trim() {
                "" => None,
                d => Some(d.parse::<f64>().map_err(|_| {
                    ApiError::bad(format!("density {d:?}: give a number in g/ml, e.g. 1.05"))
                })?),
            };
            blocking(move || super::calibrate::flow(&name, &bytes, config, density)).await?
        }
        other => {
            return Err(ApiError::missing(format!(
                "no calibration {other:?}: rheology, flow, lag or camera"
            )))
        }
    }))
}
