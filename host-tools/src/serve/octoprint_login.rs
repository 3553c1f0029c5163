//! OctoPrint's `POST /api/login`, which Cura's OctoPrint plugin sends as it connects
//! (`{"passive": true}` with its `X-Api-Key`) to show whose key it holds: a 404 there
//! reads as "Anonymous user", a 401 or 403 as "Unknown user". Answered as OctoPrint's own
//! handler does (`octoprint/server/api/__init__.py`, `login`): `passive` answers the
//! user the request is signed in as; `user` and `pass` check the password (403 "User
//! unknown or password incorrect" when wrong); neither is a 400. The key itself is checked
//! before this, by `gate` (`--auth`; without it everything is open). dollop has one key
//! and no users, so the user is OctoPrint's global API key user, `_api`, an admin.
//! Stops there: no session is opened (every request carries the key anyway).

use super::error::ApiError;
use super::octoprint_common::{OpResult, Plain};
use super::state::AppState;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::{json, Value};
use std::sync::Arc;

/// The user OctoPrint's global API key signs in as.
pub const API_USER: &str = "_api";

/// What OctoPrint answers for a signed-in user (`User.as_dict()` and the flag its login
/// handler adds).
fn api_user() -> Value {
    json!({
        "name": API_USER,
        "active": true,
        "user": true,
        "admin": true,
        "apikey": null,
        "groups": ["admins", "users"],
        "roles": ["user", "admin"],
        "needs": { "group": ["admins", "users"], "role": ["admin", "user"] },
        "permissions": [],
        "settings": {},
        "_is_external_client": false,
        "_login_mechanism": "apikey",
    })
}

/// `POST /api/login`: the body as JSON (OctoPrint also takes form values: read as JSON
/// first, then as `a=b&c=d`).
pub async fn login(State(st): State<Arc<AppState>>, body: Bytes) -> OpResult<Response> {
    let fields = read_fields(&body);
    let has = |k: &str| fields.iter().any(|(f, _)| f == k);
    let get = |k: &str| fields.iter().find(|(f, _)| f == k).map(|(_, v)| v.as_str());
    if let (true, Some(pass)) = (has("user"), get("pass")) {
        if !st.auth.as_ref().is_none_or(|a| a.is_key(pass)) {
            return Ok((
                StatusCode::FORBIDDEN,
                [(header::CONTENT_TYPE, "text/plain")],
                "User unknown or password incorrect",
            )
                .into_response());
        }
        return Ok(Json(api_user()).into_response());
    }
    if has("passive") {
        return Ok(Json(api_user()).into_response());
    }
    Err(Plain(ApiError::bad(
        "Neither user and pass attributes nor passive flag present",
    )))
}

/// The body's fields and their values as text: a JSON object's, else a form's.
fn read_fields(body: &[u8]) -> Vec<(String, String)> {
    if let Ok(Value::Object(m)) = serde_json::from_slice::<Value>(body) {
        return m
            .into_iter()
            .map(|(k, v)| {
                let text = match v {
                    Value::String(s) => s,
                    other => other.to_string(),
                };
                (k, text)
            })
            .collect();
    }
    String::from_utf8_lossy(body)
        .split('&')
        .filter(|p| !p.is_empty())
        .map(|p| {
            let (k, v) = p.split_once('=').unwrap_or((p, ""));
            (k.to_string(), v.to_string())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_body_is_read_as_json_then_as_a_form() {
        let f = read_fields(br#"{"passive": true}"#);
        assert_eq!(f, vec![("passive".into(), "true".into())]);
        let f = read_fields(b"user=a&pass=b");
        assert_eq!(
            f,
            vec![("user".into(), "a".into()), ("pass".into(), "b".into())]
        );
        assert!(read_fields(b"").is_empty());
    }
}
