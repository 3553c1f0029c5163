//! The dashboard's door when `--auth` is on: the middleware that admits a request (or
//! sends a browser to sign in, or answers 401) and the sign-in form. What a key and a
//! session are, and how they are checked, is `auth`'s.

use super::auth::COOKIE;
use super::error::ApiError;
use super::state::AppState;
use axum::extract::{Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::Next;
use axum::response::{Html, IntoResponse, Redirect, Response};
use std::sync::Arc;

/// The middleware: lets the request through when `--auth` is off or it is admitted (and
/// always to the sign-in form); otherwise sends a browser's page load to the form and
/// answers anything else 401.
pub async fn guard(State(st): State<Arc<AppState>>, req: Request, next: Next) -> Response {
    let Some(auth) = st.auth.as_ref() else {
        return next.run(req).await;
    };
    let open = matches!(req.uri().path(), "/login" | "/favicon.svg" | "/favicon.ico");
    if open || auth.admits(req.headers()) {
        return next.run(req).await;
    }
    let wants_page = req
        .headers()
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|a| a.contains("text/html"));
    if wants_page && req.uri().path() == "/" {
        return Redirect::to("/login").into_response();
    }
    ApiError::Unauthorized(
        "this dashboard needs its key (dollop serve --auth): sign in at /login, or send Authorization: Bearer KEY".into(),
    )
    .into_response()
}

/// The sign-in form.
fn form(refused: bool) -> Html<String> {
    Html(format!(
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>dollop: sign in</title><link rel=\"icon\" href=\"/favicon.svg\" type=\"image/svg+xml\"></head>\
<body style=\"font:16px system-ui,sans-serif;max-width:24em;margin:3em auto;padding:0 1em\"><h1>dollop</h1>\
<form method=\"post\" action=\"/login\"><p><label>Key or password (as given to <code>dollop serve --auth</code>)<br><input id=\"key\" name=\"key\" type=\"password\" autofocus style=\"width:100%;font:inherit\"></label></p>\
<p><button id=\"sign-in\" style=\"font:inherit\">Sign in</button></p>{}</form></body></html>",
        if refused {
            "<p id=\"refused\" style=\"color:#8a1c12\">That is not this dashboard's key.</p>"
        } else {
            ""
        }
    ))
}

/// `GET /login`.
pub async fn login_page() -> Html<String> {
    form(false)
}

/// The form's field.
#[derive(serde::Deserialize)]
pub struct KeyForm {
    key: String,
}

/// `POST /login`: a session cookie and on to the dashboard, or the form again (401).
pub async fn login(State(st): State<Arc<AppState>>, f: axum::Form<KeyForm>) -> Response {
    let Some(auth) = st.auth.as_ref() else {
        return Redirect::to("/").into_response();
    };
    match auth.sign_in(&f.key) {
        Some(token) => (
            [(
                header::SET_COOKIE,
                format!("{COOKIE}={token}; HttpOnly; SameSite=Strict; Path=/"),
            )],
            Redirect::to("/"),
        )
            .into_response(),
        None => (StatusCode::UNAUTHORIZED, form(true)).into_response(),
    }
}
