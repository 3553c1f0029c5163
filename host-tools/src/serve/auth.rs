//! `--auth`: one API key or password for the whole dashboard. With it every route (the
//! pages, the API, the status stream) answers 401 to a request without it; a browser signs
//! in once on a small form (`/login`) and gets a session cookie (a random token, not the
//! key), scripts send the key as `Authorization: Bearer KEY` or `X-Api-Key: KEY`. Without
//! `--auth` everything is open, which `start` allows on a loopback address only. This file
//! stops at checking: no users, no roles, no expiry (a restart signs everyone out).

use super::lock::lock;
use axum::http::{header, HeaderMap};
use rand::RngExt;
use std::collections::VecDeque;
use std::sync::Mutex;

/// Sessions kept (browsers signed in); the oldest is signed out past this.
pub const MAX_SESSIONS: usize = 64;

/// The session cookie's name.
pub const COOKIE: &str = "dollop_session";

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

    /// `key` is the key (a password given in a body, as OctoPrint's login takes it).
    pub fn is_key(&self, key: &str) -> bool {
        same(key.as_bytes(), self.key.as_bytes())
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
