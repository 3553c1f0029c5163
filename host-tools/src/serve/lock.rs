//! The dashboard's one way of taking a lock: a thread that panicked while holding it
//! leaves the data as it was, and the others go on with it (no handler panics in turn).

use std::sync::{Mutex, MutexGuard};

/// Locks, going on with the data if another thread panicked while holding it.
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}
