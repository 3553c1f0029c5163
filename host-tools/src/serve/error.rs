//! The one error type the HTTP handlers return: a status, a plain-words message for the
//! page, and, for config problems, the field it belongs to (the page shows it there).
//! Nothing from outside reaches a panic: every failure becomes one of these.

use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::Serialize;

/// A refusal or failure, as the page shows it.
#[derive(Debug, Clone, Serialize)]
pub struct ApiError {
    /// HTTP status.
    #[serde(skip)]
    pub status: StatusCode,
    /// What happened and what to do, one line.
    pub error: String,
    /// The config field it is about (`channel.line_pitch_mm`, `inlet[0].material`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
}

impl ApiError {
    /// The request was wrong (bad file, bad option): 400.
    pub fn bad(msg: impl Into<String>) -> Self {
        ApiError {
            status: StatusCode::BAD_REQUEST,
            error: msg.into(),
            field: None,
        }
    }
    /// Nothing by that name (a job, a simulation, a board): 404.
    pub fn missing(msg: impl Into<String>) -> Self {
        ApiError {
            status: StatusCode::NOT_FOUND,
            error: msg.into(),
            field: None,
        }
    }
    /// Someone else holds it, or it is busy: 409.
    pub fn conflict(msg: impl Into<String>) -> Self {
        ApiError {
            status: StatusCode::CONFLICT,
            error: msg.into(),
            field: None,
        }
    }
    /// The upload is over the size limit: 413.
    pub fn too_large() -> Self {
        ApiError {
            status: StatusCode::PAYLOAD_TOO_LARGE,
            error: format!(
                "the upload is larger than the {} MiB this dashboard accepts; use the command line (dollop slice) for bigger files",
                super::MAX_UPLOAD >> 20
            ),
            field: None,
        }
    }
    /// Our side failed (a worker thread gone, a temporary file not written): 500.
    pub fn internal(msg: impl Into<String>) -> Self {
        ApiError {
            status: StatusCode::INTERNAL_SERVER_ERROR,
            error: msg.into(),
            field: None,
        }
    }
    /// Attaches the config field.
    pub fn at(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into());
        self
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.status, axum::Json(self)).into_response()
    }
}

impl From<axum::extract::multipart::MultipartError> for ApiError {
    fn from(e: axum::extract::multipart::MultipartError) -> Self {
        if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::too_large()
        } else {
            ApiError::bad(format!(
                "the upload did not arrive whole: {}",
                e.body_text()
            ))
        }
    }
}

/// Results of handlers.
pub type ApiResult<T> = Result<T, ApiError>;
