//! "Inspect this print" on the Print page: one picture taken from the `--camera` address
//! (a snapshot, or the first frame of an MJPEG stream) and measured against a job the
//! dashboard holds, as `dollop inspect PHOTO --job --config --suggest --picture` measures a
//! photo: the report, the suggestions, the config fragment and the framed picture. Where it
//! stops: the measuring is `inspect`'s; the camera is fetched over plain http only (the page
//! shows an https camera, but this server has no TLS client).

use super::error::{ApiError, ApiResult};
use super::reply::blocking;
use super::state::AppState;
use axum::extract::State;
use axum::routing::post;
use axum::{Json, Router};
use base64::Engine;
use bytes::Bytes;
use http_body_util::{BodyExt, Empty};
use serde::Deserialize;
use serde_json::{json, Value};
use std::sync::Arc;
use std::time::Duration;

type St = State<Arc<AppState>>;

/// Largest picture taken from the camera, bytes: a 12-megapixel JPEG is about 5 MB.
pub const MAX_SNAPSHOT: usize = 32 << 20;

/// How long the camera may take to answer and send its picture.
const CAMERA_TIMEOUT: Duration = Duration::from_secs(10);

pub fn routes() -> Router<Arc<AppState>> {
    Router::new().route("/api/inspect", post(inspect_print))
}

#[derive(Deserialize)]
struct InspectReq {
    /// The job the print was made from (the page's current job).
    job: u64,
}

async fn inspect_print(State(st): St, Json(r): Json<InspectReq>) -> ApiResult<Json<Value>> {
    let url = st.camera.clone().ok_or_else(|| {
        ApiError::bad("no camera: start the dashboard with --camera URL (the camera's snapshot address) to inspect a print from it")
    })?;
    let job = st.job(r.job).ok_or_else(|| {
        ApiError::missing(format!(
            "job {} is no longer kept; open it again from the Files page",
            r.job
        ))
    })?;
    let picture = fetch(&url).await?;
    let out = blocking(move || measure(&job, &picture)).await?;
    Ok(Json(out))
}

/// One picture from `url`: the body of a snapshot address, or the first JPEG of an MJPEG
/// stream (`multipart/x-mixed-replace`), at most `MAX_SNAPSHOT` bytes.
pub async fn fetch(url: &str) -> ApiResult<Vec<u8>> {
    let uri: axum::http::Uri = url
        .parse()
        .map_err(|e| ApiError::bad(format!("the camera address {url:?} is not a URL: {e}")))?;
    if uri.scheme_str() != Some("http") {
        return Err(ApiError::bad(format!(
            "the camera at {url} is not plain http: this dashboard fetches pictures over http:// only; give --camera the camera's http snapshot address"
        )));
    }
    let client = hyper_util::client::legacy::Client::builder(hyper_util::rt::TokioExecutor::new())
        .build_http::<Empty<Bytes>>();
    let silent = || {
        ApiError::bad(format!(
            "the camera at {url} did not answer within {} s; is it on, and is this its address?",
            CAMERA_TIMEOUT.as_secs()
        ))
    };
    let deadline = tokio::time::Instant::now() + CAMERA_TIMEOUT;
    let resp = tokio::time::timeout_at(deadline, client.get(uri))
        .await
        .map_err(|_| silent())?
        .map_err(|e| ApiError::bad(format!("the camera at {url} cannot be reached: {e}")))?;
    if !resp.status().is_success() {
        return Err(ApiError::bad(format!(
            "the camera at {url} answered {}; give --camera its snapshot address",
            resp.status()
        )));
    }
    let stream = resp
        .headers()
        .get(axum::http::header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|t| t.to_ascii_lowercase().starts_with("multipart/"));
    let mut body = resp.into_body();
    let mut got: Vec<u8> = Vec::new();
    loop {
        let frame = tokio::time::timeout_at(deadline, body.frame())
            .await
            .map_err(|_| silent())?;
        let Some(frame) = frame else { break };
        let frame = frame.map_err(|e| {
            ApiError::bad(format!("the camera at {url} broke off its picture: {e}"))
        })?;
        if let Ok(data) = frame.into_data() {
            got.extend_from_slice(&data);
        }
        if stream {
            if let Some(jpeg) = first_jpeg(&got) {
                return Ok(jpeg.to_vec());
            }
        }
        if got.len() > MAX_SNAPSHOT {
            return Err(ApiError::bad(format!(
                "the camera at {url} sent more than {} MiB without a whole picture",
                MAX_SNAPSHOT >> 20
            )));
        }
    }
    if stream {
        return Err(ApiError::bad(format!(
            "the camera stream at {url} ended before a whole JPEG frame"
        )));
    }
    if got.is_empty() {
        return Err(ApiError::bad(format!(
            "the camera at {url} sent an empty picture"
        )));
    }
    Ok(got)
}

/// The first whole JPEG (start-of-image to end-of-image marker) in `b`, if one has arrived.
fn first_jpeg(b: &[u8]) -> Option<&[u8]> {
    let start = b.windows(2).position(|w| w == [0xFF, 0xD8])?;
    let end = b[start + 2..].windows(2).position(|w| w == [0xFF, 0xD9])?;
    Some(&b[start..start + 2 + end + 2])
}

/// Measures `picture` against `job` as `dollop inspect --suggest --picture` does. Blocking.
fn measure(job: &super::jobs::JobEntry, picture: &[u8]) -> ApiResult<Value> {
    use crate::inspect::{self, suggest};
    let dir = tempfile::tempdir()
        .map_err(|e| ApiError::internal(format!("cannot keep the camera's picture: {e}")))?;
    // The photo loader guesses the format from the bytes; the name is only for messages.
    let path = dir.path().join("camera-snapshot");
    std::fs::write(&path, picture)
        .map_err(|e| ApiError::internal(format!("cannot keep the camera's picture: {e}")))?;
    let s = &job.sliced;
    let ins = inspect::inspect(
        &path,
        &s.commands,
        s.header.start_um,
        &job.config,
        &inspect::Options::default(),
    )
    .map_err(|e| {
        ApiError::bad(format!(
            "the camera's picture cannot be measured against {}: {e}",
            s.name
        ))
    })?;
    let names = crate::slicer::material_names(&job.config);
    let sug = suggest::for_job(
        &ins,
        &job.config,
        s.header.start_um,
        s.header.initial_material,
        &s.commands,
    );
    let img = inspect::picture::figure(&ins)
        .map_err(|e| ApiError::internal(format!("cannot draw the picture: {e}")))?;
    let png = super::reply::png(&img)?;
    Ok(json!({
        "job": s.name,
        "report": ins.report(&names),
        "suggestions": sug.lines,
        "fragment": sug.fragment,
        "no_correction_needed": sug.none_needed(),
        "picture": format!("data:image/png;base64,{}", base64::engine::general_purpose::STANDARD.encode(&png)),
    }))
}

#[cfg(test)]
mod tests {
    use super::first_jpeg;

    #[test]
    fn the_first_whole_jpeg_of_a_stream_is_found() {
        let part = b"--frame\r\nContent-Type: image/jpeg\r\n\r\n\xFF\xD8abc\xFF\xD9\r\n--frame\r\n\xFF\xD8x";
        assert_eq!(first_jpeg(part), Some(&b"\xFF\xD8abc\xFF\xD9"[..]));
        assert_eq!(first_jpeg(b"--frame\r\n\xFF\xD8abc"), None);
        assert_eq!(first_jpeg(b"no picture"), None);
    }
}
