//! How the handlers answer: blocking work run off the async threads, a job as the pages
//! read it, a file as a download, a picture as PNG. Shared by `routes`, `files`,
//! `octoprint` and `snapshot`; no handler lives here.

use super::design;
use super::error::{ApiError, ApiResult};
use super::state::JobEntry;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;

/// Runs blocking work (slicing, decoding, files) off the async threads.
pub async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> ApiResult<T> + Send + 'static,
) -> ApiResult<T> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ApiError::internal(format!("the work stopped unexpectedly: {e}")))?
}

/// The content type of a file by its name.
pub fn mime(name: &str) -> String {
    match name.rsplit('.').next().unwrap_or("") {
        "png" => "image/png",
        "csv" => "text/csv",
        "toml" | "gcode" | "txt" => "text/plain; charset=utf-8",
        "stl" => "model/stl",
        _ => "application/octet-stream",
    }
    .into()
}

#[derive(Serialize)]
struct JobView<'a> {
    id: u64,
    figures: &'a design::Figures,
    toolpath: &'a design::Toolpath,
    materials: Vec<String>,
}

/// A job as JSON.
pub fn job_json(e: &JobEntry) -> Response {
    Json(job_value(e)).into_response()
}

/// A job as the pages read it.
pub fn job_value(e: &JobEntry) -> serde_json::Value {
    serde_json::to_value(JobView {
        id: e.id,
        figures: &e.figures,
        toolpath: &e.toolpath,
        materials: crate::slicer::material_names(&e.config),
    })
    .unwrap_or_default()
}

/// A job's file-name stem (from its design's name).
pub fn stem(e: &JobEntry) -> String {
    let s: String = e
        .figures
        .name
        .split(['.', ' '])
        .next()
        .unwrap_or("job")
        .chars()
        .filter(|c| c.is_ascii_alphanumeric() || *c == '-' || *c == '_')
        .collect();
    if s.is_empty() {
        "job".into()
    } else {
        s
    }
}

/// Bytes as a download named `name`.
pub fn download(name: String, bytes: Vec<u8>) -> Response {
    (
        [
            (header::CONTENT_TYPE, mime(&name)),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{name}\""),
            ),
        ],
        bytes,
    )
        .into_response()
}

/// A picture as PNG bytes.
pub fn png(img: &image::RgbImage) -> ApiResult<Vec<u8>> {
    crate::figure::png(img).map_err(ApiError::internal)
}
