//! `--auth`: one API key or password for the whole dashboard. With it every route (the
//! pages, the API, the status stream) answers 401 to a request without it; a browser signs
//! in once on a small form (`/login`) and gets a session cookie (a random token, not the
//! key), scripts send the key as `Authorization: Bearer KEY` or `X-Api-Key: KEY`. Without
//! `--auth` everything is open, which `start` allows on a loopback address only. This file
//! stops at checking: no users, no roles, no expiry (a restart signs everyone out).

use super::error::ApiError;
use super::lock::lock;
use super::state::AppState;
use axum::extract::{Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::middleware::Next;
use axum::response::{Html, IntoResponse, Redirect, Response};
use rand::RngExt;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

/// Sessions kept (browsers signed in); the oldest is signed out past this.
pub const MAX_SESSIONS: usize = 64;

/// The session cookie's name.
const COOKIE: &str = "dollop_session";

/// The key and the sessions signed in with it.
pub struct Auth {
    key: String,
    sessions: Mutex<VecDeque<String>>,
}

/// Equal, in a time that does not depend on where they differ.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

impl Auth {
    /// The key given to `--auth` (refused when empty or shorter than 8 characters).
    pub fn new(key: &str) -> anyhow::Result<Self> {
        if key.chars().count() < 8 {
            anyhow::bail!(
                "--auth needs a key or password of at least 8 characters (anyone who reaches the address can try keys)"
            );
        }
        Ok(Auth {
            key: key.to_string(),
            sessions: Mutex::new(VecDeque::new()),
        })
    }

    /// The request carries the key, or a session cookie signed in with it.
    pub fn admits(&self, h: &HeaderMap) -> bool {
        let get = |name: header::HeaderName| h.get(name).and_then(|v| v.to_str().ok());
        if let Some(k) = get(header::AUTHORIZATION).and_then(|v| v.strip_prefix("Bearer ")) {
            return same(k.trim().as_bytes(), self.key.as_bytes());
        }
        if let Some(k) = h.get("x-api-key").and_then(|v| v.to_str().ok()) {
            return same(k.trim().as_bytes(), self.key.as_bytes());
        }
        let Some(cookies) = get(header::COOKIE) else {
            return false;
        };
        let sessions = lock(&self.sessions);
        cookies
            .split(';')
            .filter_map(|c| c.trim().strip_prefix(COOKIE)?.strip_prefix('='))
            .any(|t| sessions.iter().any(|s| same(s.as_bytes(), t.as_bytes())))
    }

    /// Checks a key typed on the form; a new session's token when it is right.
    pub fn sign_in(&self, key: &str) -> Option<String> {
        if !same(key.as_bytes(), self.key.as_bytes()) {
            return None;
        }
        let token = format!("{:032x}", rand::rng().random::<u128>());
        let mut s = lock(&self.sessions);
        s.push_back(token.clone());
        while s.len() > MAX_SESSIONS {
            s.pop_front();
        }
        Some(token)
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(&str, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.insert(
                header::HeaderName::from_bytes(k.as_bytes()).expect("name"),
                v.parse().expect("value"),
            );
        }
        h
    }

    #[test]
    fn the_key_a_session_or_nothing() {
        assert!(Auth::new("short").is_err());
        let a = Auth::new("open sesame").expect("a key");
        assert!(!a.admits(&headers(&[])));
        assert!(a.admits(&headers(&[("authorization", "Bearer open sesame")])));
        assert!(!a.admits(&headers(&[("authorization", "Bearer open sesamE")])));
        assert!(a.admits(&headers(&[("x-api-key", "open sesame")])));
        assert!(!a.admits(&headers(&[("cookie", "dollop_session=guess")])));
        assert_eq!(a.sign_in("wrong key!"), None);
        let t = a.sign_in("open sesame").expect("signed in");
        assert!(a.admits(&headers(&[("cookie", &format!("a=b; dollop_session={t}"))])));
        // Past the limit the oldest session is signed out.
        for _ in 0..MAX_SESSIONS {
            a.sign_in("open sesame").expect("signed in");
        }
        assert!(!a.admits(&headers(&[("cookie", &format!("dollop_session={t}"))])));
    }
}
