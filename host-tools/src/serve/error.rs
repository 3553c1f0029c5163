//! The one error type the HTTP handlers return: what kind of refusal or failure (which
//! gives the HTTP status), a plain-words message for the page, and, where one field of the
//! page is at fault, that field. Each library's error comes in by a `From` that words it
//! in the page's terms (its field labels, not the command line's flags). Nothing from
//! outside reaches a panic: every failure becomes one of these.

use crate::calibrate::error::{CalError, CalOption, OptionError};
use crate::slicer::{Names, SliceError, SliceLimit, SliceOption};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};

/// A refusal or failure, as the page shows it.
#[derive(Debug, Clone, PartialEq)]
pub enum ApiError {
    /// The request was wrong (a bad file, a bad option): 400, with the page's field (a
    /// config path such as `channel.line_pitch_mm`, or a form field's id) when one is.
    Bad {
        /// What happened and what to do, one line.
        error: String,
        /// The field it is about.
        field: Option<String>,
    },
    /// Nothing by that name (a job, a simulation, a board): 404.
    Missing(String),
    /// Someone else holds it, or the board cannot act now: 409.
    Conflict(String),
    /// The upload is over the size limit: 413.
    TooLarge(String),
    /// No valid key or password (`--auth`): 401.
    Unauthorized(String),
    /// Our side failed (a worker thread gone, a temporary file not written): 500.
    Internal(String),
}

impl ApiError {
    /// The request was wrong (bad file, bad option).
    pub fn bad(msg: impl Into<String>) -> Self {
        ApiError::Bad {
            error: msg.into(),
            field: None,
        }
    }
    /// Nothing by that name.
    pub fn missing(msg: impl Into<String>) -> Self {
        ApiError::Missing(msg.into())
    }
    /// Someone else holds it, or it is busy.
    pub fn conflict(msg: impl Into<String>) -> Self {
        ApiError::Conflict(msg.into())
    }
    /// The upload is over the size limit.
    pub fn too_large() -> Self {
        ApiError::TooLarge(format!(
            "the upload is larger than the {} MiB this dashboard accepts; use the command line (dollop slice) for bigger files",
            super::MAX_UPLOAD >> 20
        ))
    }
    /// Our side failed.
    pub fn internal(msg: impl Into<String>) -> Self {
        ApiError::Internal(msg.into())
    }
    /// Attaches the page's field (a refusal that is not `Bad` has none, and stays as it is).
    pub fn at(self, f: impl Into<String>) -> Self {
        match self {
            ApiError::Bad { error, .. } => ApiError::Bad {
                error,
                field: Some(f.into()),
            },
            other => other,
        }
    }
    /// The HTTP status.
    pub fn status(&self) -> StatusCode {
        match self {
            ApiError::Bad { .. } => StatusCode::BAD_REQUEST,
            ApiError::Missing(_) => StatusCode::NOT_FOUND,
            ApiError::Conflict(_) => StatusCode::CONFLICT,
            ApiError::TooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::Unauthorized(_) => StatusCode::UNAUTHORIZED,
            ApiError::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }
    /// The message.
    pub fn message(&self) -> &str {
        match self {
            ApiError::Bad { error, .. } => error,
            ApiError::Missing(m)
            | ApiError::Conflict(m)
            | ApiError::TooLarge(m)
            | ApiError::Unauthorized(m)
            | ApiError::Internal(m) => m,
        }
    }
    /// The field it is about, if any.
    pub fn field(&self) -> Option<&str> {
        match self {
            ApiError::Bad { field, .. } => field.as_deref(),
            _ => None,
        }
    }
    /// The same refusal with its message rewritten (a temporary folder's name taken out).
    pub fn map_message(self, f: impl FnOnce(&str) -> String) -> Self {
        match self {
            ApiError::Bad { error, field } => ApiError::Bad {
                error: f(&error),
                field,
            },
            ApiError::Missing(m) => ApiError::Missing(f(&m)),
            ApiError::Conflict(m) => ApiError::Conflict(f(&m)),
            ApiError::TooLarge(m) => ApiError::TooLarge(f(&m)),
            ApiError::Unauthorized(m) => ApiError::Unauthorized(f(&m)),
            ApiError::Internal(m) => ApiError::Internal(f(&m)),
        }
    }
}

impl std::fmt::Display for ApiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.message())
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = match self.field() {
            Some(field) => serde_json::json!({ "error": self.message(), "field": field }),
            None => serde_json::json!({ "error": self.message() }),
        };
        (self.status(), axum::Json(body)).into_response()
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

/// The page's name for a request's option: its field's label (`index.html`, `opt-...`).
pub fn field_name(o: SliceOption) -> &'static str {
    match o {
        SliceOption::Palette => "Palette",
        SliceOption::Background => "Background",
        SliceOption::BackgroundTolerance => "Background tolerance",
        SliceOption::MinRun => "Shortest run, mm",
        SliceOption::Origin => "Origin X,Y mm",
        SliceOption::Layers => "Layers",
        SliceOption::Connect => "Join rows within, mm",
        SliceOption::Prime => "Priming bead, mm",
        // The page writes no G-code.
        SliceOption::GcodePorts => "G-code ports",
        SliceOption::Width => "Width, mm",
        SliceOption::Height => "Height, mm",
        SliceOption::Size => "Width, mm / Height, mm",
        SliceOption::Threshold => "Threshold (0-255)",
        SliceOption::Markers => "Markers",
    }
}

/// The slicer's options by the Design page's labels; its limits (the page sets none) in
/// the library's words.
struct Fields;

impl Names for Fields {
    fn option(&self, o: SliceOption) -> &'static str {
        field_name(o)
    }
    fn limit(&self, l: SliceLimit) -> &'static str {
        l.words()
    }
}

impl From<SliceError> for ApiError {
    fn from(e: SliceError) -> Self {
        let field = match &e {
            // `Label: value problem`: the label ends in a unit, so the colon comes first.
            SliceError::BadOption(o) => {
                let design = o
                    .design
                    .as_ref()
                    .map(|d| format!("{d}: "))
                    .unwrap_or_default();
                let label = field_name(o.option);
                return ApiError::bad(match &o.value {
                    Some(v) => format!("{design}{label}: {v} {}", o.problem),
                    None => format!("{design}{label}: {}", o.problem),
                });
            }
            SliceError::TooLarge { .. } => Some("opt-width_mm"),
            SliceError::OutsideTravel { .. } => Some("opt-origin"),
            _ => None,
        };
        let e = ApiError::bad(e.message(&Fields));
        match field {
            Some(f) => e.at(f),
            None => e,
        }
    }
}

impl From<CalError> for ApiError {
    fn from(e: CalError) -> Self {
        // The library names options in plain words; the page points at their fields.
        let field = match &e {
            CalError::RoiTooSmall { .. } => Some("cam-roi"),
            CalError::NeedsDensity { .. } => Some("cal-density"),
            CalError::KindUnclear { .. } => Some("cal-kind"),
            CalError::Option(OptionError::NotPositive { option, .. }) => match option {
                CalOption::Density => Some("cal-density"),
                CalOption::Fps => Some("cam-fps"),
                CalOption::MmPerPx => Some("cam-mm_per_px"),
                CalOption::TargetWidth => Some("cam-target_width"),
                CalOption::NozzleDiameter => Some("cam-nozzle"),
                _ => None,
            },
            _ => None,
        };
        let e = ApiError::bad(e.to_string());
        match field {
            Some(f) => e.at(f),
            None => e,
        }
    }
}

/// Results of handlers.
pub type ApiResult<T> = Result<T, ApiError>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_answers_its_status_and_the_field_only_where_one_is() {
        let e = ApiError::bad("x").at("motion.print_speed_mm_s");
        assert_eq!(e.status(), StatusCode::BAD_REQUEST);
        assert_eq!(e.field(), Some("motion.print_speed_mm_s"));
        let e = ApiError::conflict("busy").at("ignored");
        assert_eq!((e.status(), e.field()), (StatusCode::CONFLICT, None));
        assert_eq!(
            ApiError::too_large().status(),
            StatusCode::PAYLOAD_TOO_LARGE
        );
        assert_eq!(
            ApiError::Unauthorized("key".into()).status(),
            StatusCode::UNAUTHORIZED
        );
    }

    #[test]
    fn a_design_too_large_names_the_pages_fields_not_flags() {
        let e: ApiError = SliceError::TooLarge {
            what: "logo.png".into(),
            size: [300.0, 10.0, 1.0],
            travel: [200.0, 200.0, 50.0],
        }
        .into();
        assert!(!e.message().contains("--"), "{e}");
        assert!(e.message().contains("Width, mm"), "{e}");
        assert_eq!(e.field(), Some("opt-width_mm"));
        let e: ApiError = SliceError::OutsideTravel {
            what: "logo.png".into(),
            axis: "x",
            lo: -5.0,
            hi: 20.0,
            min: 0.0,
            max: 200.0,
        }
        .into();
        assert!(!e.message().contains("--"), "{e}");
        assert_eq!(e.field(), Some("opt-origin"));
    }
}
