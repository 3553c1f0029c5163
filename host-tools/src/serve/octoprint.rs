//! The subset of OctoPrint's REST API that slicers' "send to printer" speaks
//! (PrusaSlicer's OctoPrint host, Cura's OctoPrint connection, client libraries such as
//! octorest): `GET /api/version` and `/api/server` (what they probe first), `/api/settings`,
//! `/api/printer` and `/api/job` (what Cura polls), `GET /api/files[/local[/NAME]]`, and
//! `POST /api/files/local` multipart with `file`, `path`, `select`, `print`. An upload is
//! checked and kept as the Files page's are (`files::take_upload`: G-code imported with
//! the default config, a `.dlp` decoded and matched to its config) and, with
//! `print=true`, queued on board 0 (it starts when the board is free). The key is
//! checked by `gate` (`X-Api-Key` against `--auth`). Folders (`path`) are not kept: every
//! file goes to the one folder. This file stops at the API's shapes.

use super::error::{ApiError, ApiResult};
use super::reply::blocking;
use super::state::AppState;
use axum::extract::{Multipart, Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use serde_json::{json, Value};
use std::sync::Arc;

type St = State<Arc<AppState>>;

/// The OctoPrint API version these answers follow.
pub const API_VERSION: &str = "0.1";
/// The OctoPrint server version claimed (slicers check only that `text` starts with
/// "OctoPrint").
pub const SERVER_VERSION: &str = "1.10.0";

/// The routes of this module.
pub fn routes() -> Router<Arc<AppState>> {
    Router::new()
        .route("/api/version", get(version))
        .route("/api/server", get(server))
        .route("/api/settings", get(settings))
        .route("/api/printer", get(printer))
        .route("/api/job", get(job))
        .route("/api/files", get(files))
        .route("/api/files/local", get(files).post(upload))
        .route("/api/files/local/{name}", get(file))
}

async fn version() -> Json<Value> {
    Json(json!({
        "api": API_VERSION,
        "server": SERVER_VERSION,
        "text": format!("OctoPrint {SERVER_VERSION} (the upload API of dollop serve {})", env!("CARGO_PKG_VERSION")),
    }))
}

async fn server() -> Json<Value> {
    Json(json!({ "version": SERVER_VERSION, "safemode": null }))
}

async fn settings() -> Json<Value> {
    Json(json!({
        "api": { "enabled": true },
        "feature": { "sdSupport": false },
        "webcam": { "webcamEnabled": false, "streamUrl": "", "snapshotUrl": "" },
    }))
}

/// Board 0's state in OctoPrint's words (`Operational`, `Printing`, `Paused`, `Error`,
/// `Offline`) and flags.
fn board_state(st: &AppState) -> (String, Value) {
    let Some(b) = st.boards.first() else {
        return ("Offline".into(), json!({ "operational": false }));
    };
    let v = b.view.borrow().clone();
    let printing = v.mode == Some(dollop::wire::Mode::Job);
    let paused = printing && v.activity.starts_with("paused");
    let text = if !v.connected {
        "Offline"
    } else if v.fault.is_some() {
        "Error"
    } else if paused {
        "Paused"
    } else if printing {
        "Printing"
    } else {
        "Operational"
    };
    let flags = json!({
        "operational": v.connected,
        "printing": printing && !paused,
        "paused": paused,
        "pausing": false,
        "cancelling": false,
        "ready": v.connected && !printing && v.fault.is_none(),
        "error": v.fault.is_some(),
        "closedOrError": !v.connected || v.fault.is_some(),
        "sdReady": false,
    });
    (text.into(), flags)
}

async fn printer(State(st): St) -> Json<Value> {
    let (text, flags) = board_state(&st);
    Json(json!({
        "state": { "text": text, "flags": flags },
        "temperature": {},
        "sd": { "ready": false },
    }))
}

async fn job(State(st): St) -> Json<Value> {
    let (text, _) = board_state(&st);
    let v = st.boards.first().map(|b| b.view.borrow().clone());
    let v = v.unwrap_or_default();
    Json(json!({
        "job": { "file": { "name": v.job.as_ref().map(|j| j.name.clone()), "origin": "local" } },
        "progress": {
            "completion": if v.job.is_some() { Some(v.progress * 100.0) } else { None },
            "printTime": v.elapsed_s,
            "printTimeLeft": v.eta_s,
        },
        "state": text,
    }))
}

fn file_json(e: &super::store::Entry) -> Value {
    json!({
        "name": e.name,
        "display": e.name,
        "path": e.name,
        "type": "machinecode",
        "origin": "local",
        "size": e.bytes,
        "date": e.modified_unix_s as i64,
        "refs": refs(&e.name),
    })
}

fn refs(name: &str) -> Value {
    json!({
        "resource": format!("/api/files/local/{name}"),
        "download": format!("/api/store/{name}"),
    })
}

async fn files(State(st): St) -> Json<Value> {
    let list: Vec<Value> = st.files.list().iter().map(file_json).collect();
    Json(json!({ "files": list, "free": null }))
}

async fn file(State(st): St, Path(name): Path<String>) -> ApiResult<Json<Value>> {
    st.files
        .list()
        .iter()
        .find(|e| e.name == name)
        .map(|e| Json(file_json(e)))
        .ok_or_else(|| ApiError::missing(format!("no file named {name:?}")))
}

/// `true`/`false` as OctoPrint's form fields send them.
fn flag(field: &str, v: &str) -> ApiResult<bool> {
    match v.trim().to_ascii_lowercase().as_str() {
        "true" | "1" | "yes" => Ok(true),
        "false" | "0" | "no" | "" => Ok(false),
        other => Err(ApiError::bad(format!(
            "the form field {field}={other:?}: send true or false"
        ))),
    }
}

async fn upload(State(st): St, mut mp: Multipart) -> ApiResult<Response> {
    let (mut file, mut print) = (None, false);
    while let Some(field) = mp.next_field().await? {
        match field.name().unwrap_or("") {
            "file" => {
                let name = field.file_name().unwrap_or("upload.gcode").to_string();
                file = Some((name, field.bytes().await?.to_vec()));
            }
            "print" => print = flag("print", &field.text().await?)?,
            // OctoPrint selects the file for printing: here every kept file is ready to
            // print, so `select` changes nothing (checked all the same).
            "select" => {
                flag("select", &field.text().await?)?;
            }
            // Folders are not kept; `path` and `userdata` are read and dropped.
            _ => {}
        }
    }
    let Some((name, bytes)) = file else {
        return Err(ApiError::bad(
            "no file in the upload: send it as the multipart field \"file\"",
        ));
    };
    let st2 = st.clone();
    let shown = name.clone();
    let taken = blocking(move || super::files::take_upload(&st2, &name, bytes, None)).await;
    let (kept, job) = match taken {
        Ok(t) => t,
        Err(e) => {
            st.console.error(
                "server",
                format!("upload from a slicer refused: {}", e.message()),
            );
            return Err(e);
        }
    };
    st.console.info(
        "server",
        format!(
            "upload from a slicer: {shown} kept as {kept}{}",
            if print { ", to print" } else { "" }
        ),
    );
    if print {
        let b = st
            .boards
            .first()
            .cloned()
            .ok_or_else(|| ApiError::conflict("there is no board to print on"))?;
        let name = b.view.borrow().name.clone();
        match b.order(super::boards::WorkerOrder::Send(job)).await {
            Ok(m) => st.console.info(&name, format!("send: {m}")),
            Err(m) => {
                st.console.error(&name, format!("send refused: {m}"));
                return Err(ApiError::conflict(format!(
                    "{kept} is kept (print it from the Files page) but the board did not take it: {m}"
                )));
            }
        }
    }
    let body = json!({
        "files": { "local": { "name": kept, "origin": "local", "refs": refs(&kept) } },
        "done": true,
    });
    Ok((
        StatusCode::CREATED,
        [(header::LOCATION, format!("/api/files/local/{kept}"))],
        Json(body),
    )
        .into_response())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn form_flags_read_as_octoprint_sends_them() {
        assert!(flag("print", "true").unwrap());
        assert!(flag("print", "True").unwrap());
        assert!(!flag("print", "false").unwrap());
        assert!(!flag("print", "").unwrap());
        let e = flag("print", "maybe").unwrap_err();
        assert!(e.message().contains("print=\"maybe\""), "{}", e.message());
    }
}
