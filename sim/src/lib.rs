//! Host-side simulation of dollop jobs.
