//! The Files page's work and API: kept files (`store`) turned into jobs (a `.dlp` decoded
//! and matched to the config it was sliced for, G-code imported, a design sliced), configs
//! saved and loaded by name, the console's lines and a board's trend. Routes under
//! `/api/store`, `/api/saved-configs`, `/api/console` and `/api/boards/{id}/trend`; the
//! OctoPrint-shaped upload is `octoprint`'s and uses `take_upload` from here.

use super::design::{self, SliceForm, Upload};
use super::error::{ApiError, ApiResult};
use super::reply::{blocking, download, job_json};
use super::state::{AppState, JobEntry};
use crate::slicer::job_file;
use crate::slicer::toolpath::PathStats;
use crate::slicer::Sliced;
use axum::extract::{Multipart, Path, State};
use axum::response::Response;
use axum::routing::{get, post};
use axum::{Json, Router};
use dollop::Command;
use serde::Deserialize;
use serde_json::json;
use std::sync::Arc;

type St = State<Arc<AppState>>;

/// The routes of this module.
pub fn routes() -> Router<Arc<AppState>> {
    Router::new()
        .route("/api/store", get(list).post(upload))
        .route("/api/store/{name}", get(fetch).delete(remove))
        .route("/api/store/{name}/open", post(open))
        .route("/api/saved-configs", get(configs_list))
        .route(
            "/api/saved-configs/{name}",
            get(config_get).put(config_put).delete(config_delete),
        )
        .route("/api/console", get(console))
        .route("/api/boards/{id}/trend", get(trend))
}

/// Distance and counts of a decoded job's commands (a `.dlp` carries no statistics), over
/// the job's moves as `command::walk` gives them.
fn stats_of(commands: &[Command], start_um: [i32; 3]) -> PathStats {
    use dollop::command::{walk, MoveKind};
    let mm = |a: [i32; 3], b: [i32; 3]| -> f64 {
        let d = [0, 1, 2].map(|k| (b[k] as f64 - a[k] as f64) / 1000.0);
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    };
    let mut s = PathStats::default();
    let mut material = None;
    let mut printing = false;
    let mut layers = std::collections::BTreeSet::new();
    for m in walk(commands, start_um) {
        match m.kind {
            MoveKind::Print { material: now } => {
                s.print_mm += mm(m.from, m.to);
                s.print_segments += 1;
                if material.is_some_and(|p| p != now) {
                    s.switches += 1;
                }
                material = Some(now);
                if !printing {
                    s.beads += 1;
                }
                printing = true;
                layers.insert(m.to[2]);
            }
            MoveKind::Travel | MoveKind::Layer => {
                s.travel_mm += mm(m.from, m.to);
                s.travels += 1;
                printing = false;
            }
        }
    }
    s.layers = layers.len();
    s
}

/// The configs a job may have been sliced for: those offered, then those saved by name.
fn config_texts(st: &AppState) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = st
        .configs
        .iter()
        .map(|c| (c.name.clone(), c.text.clone()))
        .collect();
    for e in st.saved_configs.list() {
        if let Ok(b) = st.saved_configs.read(&e.name) {
            out.push((e.name, String::from_utf8_lossy(&b).into_owned()));
        }
    }
    out
}

/// A `.dlp` decoded (every check the board makes) and matched by its config hash to a
/// config this dashboard has; refused, naming the file, when it does not decode or no
/// config matches.
pub fn job_from_dlp(st: &AppState, name: &str, bytes: &[u8]) -> ApiResult<Arc<JobEntry>> {
    let (header, commands) = job_file::decode_job(bytes)
        .map_err(|e| ApiError::bad(format!("{name}: not a job dollop can print: {e}")))?;
    let want = header.config_hash;
    let found = config_texts(st).into_iter().find_map(|(_, text)| {
        let c = design::check(&text).ok()?;
        (dollop::job::config_hash(&c.config) == want).then_some(c)
    });
    let Some(checked) = found else {
        return Err(ApiError::bad(format!(
            "{name}: sliced for a machine config this dashboard does not have (config hash {want:08x}); load that config on the Design page and save it by name, or slice the design again"
        )));
    };
    let (lo, hi) = (header.bounds_min_um, header.bounds_max_um);
    let size_mm = [
        (hi[0] as f64 - lo[0] as f64) / 1000.0,
        (hi[1] as f64 - lo[1] as f64) / 1000.0,
    ];
    let stats = stats_of(&commands, header.start_um);
    // The body as the board receives it (a decoded job encodes back to the same bytes).
    let (_, body) = job_file::encode(
        &commands,
        header.start_um,
        header.initial_material,
        &checked.config,
    );
    let sliced = Sliced {
        header,
        commands,
        body,
        name: name.to_string(),
        size_mm,
        stats,
    };
    Ok(st.add_job(checked.config, checked.text, sliced))
}

/// The config to slice with: the text given, else the first offered (`--config`, else the
/// first bundled one).
fn config_or_default(st: &AppState, text: Option<String>) -> ApiResult<design::Checked> {
    let text = match text.filter(|t| !t.trim().is_empty()) {
        Some(t) => t,
        None => st
            .configs
            .first()
            .map(|c| c.text.clone())
            .ok_or_else(|| ApiError::bad("choose a machine config"))?,
    };
    design::check(&text)
}

/// A kept file as a job: a `.dlp` decoded, G-code imported, a design sliced with `config`
/// (or the default) and `form`. Blocking.
pub fn job_from_file(
    st: &AppState,
    name: &str,
    bytes: Vec<u8>,
    config: Option<String>,
    form: &SliceForm,
) -> ApiResult<Arc<JobEntry>> {
    if super::store::kind_of(name) == Some("job") {
        return job_from_dlp(st, name, &bytes);
    }
    let checked = config_or_default(st, config)?;
    let uploads = [Upload {
        name: name.to_string(),
        bytes,
    }];
    let sliced = design::slice(&uploads, &checked.config, form)?;
    Ok(st.add_job(checked.config, checked.text, sliced))
}

/// Keeps an uploaded file after checking it can become a job (a `.dlp` decoded and
/// matched, G-code imported, with `config` or the default); a bad file is refused naming
/// it and is not kept. Returns the kept name and the job. Blocking.
pub fn take_upload(
    st: &AppState,
    name: &str,
    bytes: Vec<u8>,
    config: Option<String>,
) -> ApiResult<(String, Arc<JobEntry>)> {
    let clean = super::store::clean_name(name, &["job", "gcode", "design"])?;
    let job = job_from_file(st, &clean, bytes.clone(), config, &SliceForm::default())?;
    let kept = st.files.write(&clean, &bytes)?;
    st.console.info(
        "server",
        format!(
            "kept {kept} ({} bytes): job {} of {} commands",
            bytes.len(),
            job.id,
            job.sliced.commands.len()
        ),
    );
    Ok((kept, job))
}

/// A sliced job and its design kept after the Design page sliced it (best effort: a full
/// folder or a failed write goes to the console, never fails the slicing); the job's kept
/// name.
pub fn keep_sliced(st: &AppState, uploads: &[Upload], job: &JobEntry) -> Option<String> {
    for u in uploads {
        if let Err(e) = st.files.write(&u.name, &u.bytes) {
            st.console
                .error("server", format!("not kept: {}", e.message()));
        }
    }
    let name = format!("{}.dlp", super::reply::stem(job));
    match st.files.write(&name, &job.sliced.to_bytes()) {
        Ok(n) => {
            st.console
                .info("server", format!("sliced job {} kept as {n}", job.id));
            Some(n)
        }
        Err(e) => {
            st.console
                .error("server", format!("not kept: {}", e.message()));
            None
        }
    }
}

async fn list(State(st): St) -> Json<serde_json::Value> {
    Json(json!({
        "files": st.files.list(),
        "max_files": super::store::MAX_FILES,
        "max_file_mb": super::store::MAX_FILE >> 20,
    }))
}

async fn upload(State(st): St, mut mp: Multipart) -> ApiResult<Json<serde_json::Value>> {
    let (mut file, mut config) = (None, None);
    while let Some(field) = mp.next_field().await? {
        match field.name().unwrap_or("") {
            "file" => {
                let name = field.file_name().unwrap_or("upload").to_string();
                file = Some((name, field.bytes().await?.to_vec()));
            }
            "config" => config = Some(field.text().await?),
            _ => {}
        }
    }
    let (name, bytes) = file.ok_or_else(|| ApiError::bad("choose a file to upload"))?;
    let st2 = st.clone();
    let r = blocking(move || take_upload(&st2, &name, bytes, config)).await;
    match r {
        Ok((name, job)) => Ok(Json(json!({ "name": name, "job": job.id }))),
        Err(e) => {
            st.console
                .error("server", format!("upload refused: {}", e.message()));
            Err(e)
        }
    }
}

async fn fetch(State(st): St, Path(name): Path<String>) -> ApiResult<Response> {
    let bytes = st.files.read(&name)?;
    Ok(download(name, bytes))
}

async fn remove(State(st): St, Path(name): Path<String>) -> ApiResult<Json<serde_json::Value>> {
    st.files.delete(&name)?;
    st.console.info("server", format!("deleted {name}"));
    Ok(Json(json!({ "message": format!("deleted {name}") })))
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct OpenReq {
    /// The Design page's config (TOML); none: the default.
    config: Option<String>,
    /// The Design page's options (a design is sliced again with them).
    options: Option<SliceForm>,
}

/// A kept file as a job the pages show and send (re-sliced with the page's config and
/// options where it is a design or G-code).
async fn open(
    State(st): St,
    Path(name): Path<String>,
    Json(r): Json<OpenReq>,
) -> ApiResult<Response> {
    let bytes = st.files.read(&name)?;
    let st2 = st.clone();
    let job = blocking(move || {
        job_from_file(&st2, &name, bytes, r.config, &r.options.unwrap_or_default())
    })
    .await?;
    Ok(job_json(&job))
}

async fn configs_list(State(st): St) -> Json<serde_json::Value> {
    Json(json!({ "configs": st.saved_configs.list() }))
}

fn toml_name(name: &str) -> String {
    if name.to_ascii_lowercase().ends_with(".toml") {
        name.to_string()
    } else {
        format!("{name}.toml")
    }
}

async fn config_get(State(st): St, Path(name): Path<String>) -> ApiResult<Json<serde_json::Value>> {
    let bytes = st.saved_configs.read(&toml_name(&name))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| ApiError::bad(format!("{name}: the saved config is not text")))?;
    let checked = design::check(&text)?;
    Ok(Json(json!({
        "name": name,
        "text": checked.text,
        "fields": checked.fields,
        "derived": checked.derived.figures,
    })))
}

#[derive(Deserialize)]
struct PutReq {
    text: String,
}

async fn config_put(
    State(st): St,
    Path(name): Path<String>,
    Json(r): Json<PutReq>,
) -> ApiResult<Json<serde_json::Value>> {
    // Only a config that checks is kept (the board would refuse it anyway).
    design::check(&r.text)?;
    let kept = st
        .saved_configs
        .write(&toml_name(&name), r.text.as_bytes())?;
    st.console.info("server", format!("config saved as {kept}"));
    Ok(Json(
        json!({ "name": kept, "message": format!("saved as {kept}") }),
    ))
}

async fn config_delete(
    State(st): St,
    Path(name): Path<String>,
) -> ApiResult<Json<serde_json::Value>> {
    let n = toml_name(&name);
    st.saved_configs.delete(&n)?;
    Ok(Json(json!({ "message": format!("deleted {n}") })))
}

async fn console(State(st): St) -> Json<serde_json::Value> {
    Json(json!({ "seq": st.console.seq(), "lines": st.console.lines() }))
}

async fn trend(State(st): St, Path(id): Path<usize>) -> ApiResult<Json<serde_json::Value>> {
    if id >= st.boards.len() {
        return Err(ApiError::missing(format!("there is no board {id}")));
    }
    Ok(Json(json!({ "samples": st.console.trend(id) })))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_decoded_jobs_statistics_count_what_it_prints() {
        let cmds = [
            Command::Travel { x: 0, y: 0, z: 600 },
            Command::Print {
                dx: 3000,
                dy: 4000,
                material: 0,
            },
            Command::Print {
                dx: 1000,
                dy: 0,
                material: 1,
            },
            Command::Layer { z: 1200 },
            Command::Print {
                dx: 0,
                dy: 2000,
                material: 1,
            },
            Command::End,
        ];
        let s = stats_of(&cmds, [0, 0, 0]);
        assert_eq!(s.print_segments, 3);
        assert!((s.print_mm - 8.0).abs() < 1e-9, "{}", s.print_mm);
        assert!((s.travel_mm - 1.2).abs() < 1e-9, "{}", s.travel_mm);
        assert_eq!((s.switches, s.beads, s.layers, s.travels), (1, 2, 2, 2));
    }
}
