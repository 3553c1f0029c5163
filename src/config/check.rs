//! The single-value checks every section's `check` is written with: a value finite, above
//! zero or within a range, each refusal a `ConfigError` naming its section, index and key.
//! It stops at one value; what values mean together is each section's business.

use super::{ConfigError, Field, Problem};

/// Where the values checked sit: a section, and the inlet or axis for per-index keys.
pub(super) struct Check {
    pub(super) section: &'static str,
    pub(super) index: Option<u8>,
}

impl Check {
    /// A section's keys with no index.
    pub(super) const fn section(section: &'static str) -> Check {
        Check {
            section,
            index: None,
        }
    }
    pub(super) fn err(&self, key: &'static str, problem: Problem) -> ConfigError {
        ConfigError {
            field: Field {
                section: self.section,
                index: self.index,
                key,
            },
            problem,
        }
    }
    pub(super) fn finite(&self, key: &'static str, v: f32) -> Result<f32, ConfigError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.err(key, Problem::NotFinite))
        }
    }
    pub(super) fn positive(&self, key: &'static str, v: f32) -> Result<f32, ConfigError> {
        let v = self.finite(key, v)?;
        if v > 0.0 {
            Ok(v)
        } else {
            Err(self.err(key, Problem::NotPositive(v)))
        }
    }
    pub(super) fn range(
        &self,
        key: &'static str,
        v: f32,
        min: f32,
        max: f32,
    ) -> Result<f32, ConfigError> {
        let v = self.finite(key, v)?;
        if v >= min && v <= max {
            Ok(v)
        } else if v < 0.0 && min >= 0.0 {
            Err(self.err(key, Problem::Negative(v)))
        } else {
            Err(self.err(key, Problem::OutOfRange { got: v, min, max }))
        }
    }
    pub(super) fn positive_max(
        &self,
        key: &'static str,
        v: f32,
        max: f32,
    ) -> Result<f32, ConfigError> {
        let v = self.positive(key, v)?;
        if v <= max {
            Ok(v)
        } else {
            Err(self.err(
                key,
                Problem::OutOfRange {
                    got: v,
                    min: 0.0,
                    max,
                },
            ))
        }
    }
}

/// Keys of one axis (or inlet) of `section`.
pub(super) fn axis_check(section: &'static str, axis: usize) -> Check {
    Check {
        section,
        index: Some(axis as u8),
    }
}
