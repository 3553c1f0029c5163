//! What the OctoPrint API's two halves share (`octoprint`: the status and upload answers;
//! `octoprint_control`: the commands): the plain-text refusal both slicers show, the board
//! an upload's folder names, and a board's job flags. Stops there: no route is here.

use super::boards::Board;
use super::error::ApiError;
use super::state::AppState;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use std::sync::Arc;

/// A refusal as the OctoPrint API's clients show it: the status and the message as
/// `text/plain` (exactly that type: Cura's plugin shows the body only then, and
/// PrusaSlicer shows whatever body comes, so JSON would reach the user with its braces).
#[derive(Debug)]
pub struct Plain(pub ApiError);

impl<T: Into<ApiError>> From<T> for Plain {
    fn from(e: T) -> Self {
        Plain(e.into())
    }
}

impl IntoResponse for Plain {
    fn into_response(self) -> Response {
        (
            self.0.status(),
            [(header::CONTENT_TYPE, "text/plain")],
            self.0.message().to_string(),
        )
            .into_response()
    }
}

/// What the OctoPrint handlers return.
pub type OpResult<T> = Result<T, Plain>;

/// The board an upload's folder names (`path`: a board's name or number, any case, with
/// or without slashes), or board 0 for no folder.
pub fn board_for(st: &AppState, folder: &str) -> OpResult<Arc<Board>> {
    let want = folder.trim().trim_matches('/').trim();
    let found = if want.is_empty() {
        st.boards.first()
    } else {
        st.boards.iter().find(|b| {
            let name = b.view.borrow().name.clone();
            name.eq_ignore_ascii_case(want)
                || super::store::plain_name(&name).eq_ignore_ascii_case(want)
                || b.id.to_string() == want
        })
    };
    found.cloned().ok_or_else(|| {
        let names: Vec<String> = st
            .boards
            .iter()
            .map(|b| format!("{:?} ({})", b.view.borrow().name, b.id))
            .collect();
        Plain(if names.is_empty() {
            ApiError::conflict("there is no board to print on")
        } else {
            ApiError::bad(format!(
                "no board named {want:?}: upload into the folder of one of {}, or into no folder for the first",
                names.join(", ")
            ))
        })
    })
}

/// Whether a board runs a job, and whether that job is paused.
pub fn job_flags(v: &super::view::View) -> (bool, bool) {
    let printing = v.mode == Some(dollop::wire::Mode::Job);
    (printing, printing && v.activity.starts_with("paused"))
}
