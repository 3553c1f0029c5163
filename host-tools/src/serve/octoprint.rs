//! The subset of OctoPrint's REST API that slicers' "send to printer" speaks
//! (PrusaSlicer's OctoPrint host, Cura's OctoPrint plugin, client libraries such as
//! octorest): `GET /api/version` and `/api/server` (what they probe first), `/api/settings`,
//! `/api/printerprofiles`, `/api/printer` and `/api/job` (what Cura polls), `POST
//! /api/login` (Cura asks whose key it holds; `octoprint_login`),
//! `GET /api/files[/local[/NAME]]`, and `POST /api/files/local` multipart with `file`,
//! `path`, `select`, `print`. An upload is checked and kept as the Files page's are
//! (`files::take_upload`: G-code imported with the config of the board it goes to, a
//! `.dlp` decoded and matched to its config) and, with `print=true`, queued on a board (it
//! starts when the board is free): the one the upload's folder (`path`) names, by name or
//! number, else board 0; a folder is otherwise ignored (files all go to one). The board's
//! config is the one this dashboard last loaded on it (`board_config`), else the first
//! offered. The status answers are
//! board 0's (an OctoPrint instance has one printer). The key is checked by `gate`
//! (`X-Api-Key` against `--auth`). Every refusal is plain text (`Plain`), the one error
//! body both slicers show as it is. The commands (job, file select, jog and home) are in
//! `octoprint_control`. This file stops at the API's shapes.

use super::error::ApiError;
use super::octoprint_common::{board_for, job_flags, OpResult, Plain};
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

/// The routes of this module and of `octoprint_control`.
pub fn routes() -> Router<Arc<AppState>> {
    Router::new()
        .route("/api/version", get(version))
        .route("/api/server", get(server))
        .route("/api/settings", get(settings))
        .route(
            "/api/login",
            axum::routing::post(super::octoprint_login::login),
        )
        .route("/api/printerprofiles", get(printer_profiles))
        .route("/api/printer", get(printer))
        .route("/api/job", get(job).post(super::octoprint_control::job))
        .route("/api/files", get(files))
        .route("/api/files/local", get(files).post(upload))
        .route(
            "/api/files/local/{name}",
            get(file).post(super::octoprint_control::file_command),
        )
        .route(
            "/api/printer/command",
            axum::routing::post(super::octoprint_control::printer_command),
        )
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
    let (printing, paused) = job_flags(&v);
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

/// One printer profile, board 0's name: Cura shows it as the printer's name and model.
async fn printer_profiles(State(st): St) -> Json<Value> {
    let name = st
        .boards
        .first()
        .map(|b| b.view.borrow().name.clone())
        .unwrap_or_else(|| "no board".into());
    Json(json!({
        "profiles": {
            "_default": {
                "id": "_default",
                "name": name,
                "model": "dollop paste printer",
                "current": true,
                "default": true,
            }
        }
    }))
}

/// Board 0's state; 409 when no board is connected, as OctoPrint answers when its
/// printer is not operational (Cura then shows the printer offline).
async fn printer(State(st): St) -> OpResult<Json<Value>> {
    let connected = st.boards.first().is_some_and(|b| b.view.borrow().connected);
    if !connected {
        return Err(Plain(ApiError::conflict(
            "Printer is not operational: no board is connected to dollop serve",
        )));
    }
    let (text, flags) = board_state(&st);
    Ok(Json(json!({
        "state": { "text": text, "flags": flags },
        "temperature": {},
        "sd": { "ready": false },
    })))
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

async fn file(State(st): St, Path(name): Path<String>) -> OpResult<Json<Value>> {
    st.files
        .list()
        .iter()
        .find(|e| e.name == name)
        .map(|e| Json(file_json(e)))
        .ok_or_else(|| Plain(ApiError::missing(format!("no file named {name:?}"))))
}

/// `true`/`false` as OctoPrint's form fields send them.
fn flag(field: &str, v: &str) -> Result<bool, ApiError> {
    match v.trim().to_ascii_lowercase().as_str() {
        "true" | "1" | "yes" => Ok(true),
        "false" | "0" | "no" | "" => Ok(false),
        other => Err(ApiError::bad(format!(
            "the form field {field}={other:?}: send true or false"
        ))),
    }
}

async fn upload(State(st): St, mut mp: Multipart) -> OpResult<Response> {
    let (mut file, mut print, mut folder) = (None, false, String::new());
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
            // The folder names the board to print on; files all go to the one folder.
            "path" => folder = field.text().await?,
            // `userdata` is read and dropped.
            _ => {}
        }
    }
    let Some((name, bytes)) = file else {
        return Err(Plain(ApiError::bad(
            "no file in the upload: send it as the multipart field \"file\"",
        )));
    };
    // Checked before the file is kept, so a print for no such board keeps nothing; a
    // file only kept may sit in any folder (they all go to the one).
    let board = if print {
        Some(board_for(&st, &folder)?)
    } else {
        None
    };
    // Imported for the machine it goes to: the board printing it, else the one the
    // folder names, else board 0; the first config offered when that board has none.
    let config = board
        .clone()
        .or_else(|| board_for(&st, &folder).ok())
        .or_else(|| board_for(&st, "").ok())
        .and_then(|b| b.config.get())
        .map(|k| k.text);
    let st2 = st.clone();
    let shown = name.clone();
    let taken = blocking(move || super::files::take_upload(&st2, &name, bytes, config)).await;
    let (kept, job) = match taken {
        Ok(t) => t,
        Err(e) => {
            st.console.error(
                "server",
                format!("upload from a slicer refused: {}", e.message()),
            );
            return Err(Plain(e));
        }
    };
    st.console.info(
        "server",
        format!(
            "upload from a slicer: {shown} kept as {kept}{}",
            if print { ", to print" } else { "" }
        ),
    );
    if let Some(board) = board {
        super::octoprint_control::send(&st, &board, job, &kept).await?;
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
