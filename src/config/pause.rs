//! The `[pause]` section of a machine config: where a parked pause takes the head (a Z
//! lift, then an XY park position), checked against the travel limits. The executor's
//! park moves (`executor::park`) use what this validates; nothing here moves anything.

use super::{axis_check, Check, ConfigError};
use crate::real::Real;
use serde::{Deserialize, Serialize};

/// Longest accepted Z lift, mm: past it a typo (cm for mm) is likelier than a machine.
const LIFT_MAX_MM: f32 = 200.0;

/// What a parked pause does after the head stopped at the pause point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PauseConfig {
    /// Z lift above the pause point, mm (cut to the Z travel maximum where it would pass
    /// it); 0 parks without lifting.
    #[serde(default = "default_lift")]
    pub park_lift_mm: f32,
    /// Park position [x, y], mm; default the X and Y travel minima (the front-left corner
    /// on most machines).
    #[serde(default)]
    pub park_position_mm: Option<[f32; 2]>,
}

fn default_lift() -> f32 {
    5.0
}

impl Default for PauseConfig {
    fn default() -> Self {
        PauseConfig {
            park_lift_mm: default_lift(),
            park_position_mm: None,
        }
    }
}

/// A validated park: lift and position in the core's units (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Park<R> {
    /// Z lift above the pause point, mm (>= 0).
    pub lift_mm: R,
    /// Park position, mm, within the X and Y travel limits.
    pub xy_mm: [R; 2],
}

impl<R: Real> Park<R> {
    /// No park (an unconfigured machine).
    pub const NONE: Self = Park {
        lift_mm: R::ZERO,
        xy_mm: [R::ZERO; 2],
    };
}

impl PauseConfig {
    /// Checks the lift and the park position against the validated travel limits
    /// (`min_mm`, `max_mm`, X Y Z): a position outside them is refused here rather than
    /// faulting the machine when an operator parks.
    pub(super) fn validate<R: Real>(
        &self,
        min_mm: &[f32; 3],
        max_mm: &[f32; 3],
    ) -> Result<Park<R>, ConfigError> {
        let pc = Check {
            section: "pause",
            index: None,
        };
        let lift = pc.range("park_lift_mm", self.park_lift_mm, 0.0, LIFT_MAX_MM)?;
        let mut xy = [R::ZERO; 2];
        for a in 0..2 {
            let v = match self.park_position_mm {
                Some(p) => {
                    axis_check("pause", a).range("park_position_mm", p[a], min_mm[a], max_mm[a])?
                }
                None => min_mm[a],
            };
            xy[a] = R::of(v as f64);
        }
        Ok(Park {
            lift_mm: R::of(lift as f64),
            xy_mm: xy,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::Problem;
    use super::*;

    const MIN: [f32; 3] = [0.0, -10.0, 0.0];
    const MAX: [f32; 3] = [200.0, 190.0, 100.0];

    #[test]
    fn defaults_park_at_the_travel_minima_five_mm_up() {
        let p: Park<f64> = PauseConfig::default().validate(&MIN, &MAX).unwrap();
        assert_eq!(p.lift_mm, 5.0);
        assert_eq!(p.xy_mm, [0.0, -10.0]);
    }

    #[test]
    fn a_park_position_off_the_travel_is_refused_naming_the_axis() {
        let c = PauseConfig {
            park_lift_mm: 2.0,
            park_position_mm: Some([50.0, 195.0]),
        };
        let e = c.validate::<f64>(&MIN, &MAX).unwrap_err();
        assert_eq!(e.field.key, "park_position_mm");
        assert_eq!(e.field.index, Some(1));
        assert!(matches!(e.problem, Problem::OutOfRange { max, .. } if max == 190.0));
        let s = alloc_free_display(&e);
        assert!(s.starts_with("pause.park_position_mm[1]"), "{s}");
    }

    #[test]
    fn a_negative_or_huge_or_nan_lift_is_refused() {
        for (lift, neg) in [(-1.0, true), (500.0, false), (f32::NAN, false)] {
            let c = PauseConfig {
                park_lift_mm: lift,
                park_position_mm: None,
            };
            let e = c.validate::<f32>(&MIN, &MAX).unwrap_err();
            assert_eq!(e.field.key, "park_lift_mm");
            assert_eq!(matches!(e.problem, Problem::Negative(_)), neg, "{lift}");
        }
    }

    /// `Display` into a fixed buffer (the core has no `String`).
    fn alloc_free_display(e: &ConfigError) -> heapless::String<128> {
        use core::fmt::Write;
        let mut s = heapless::String::new();
        let _ = write!(s, "{e}");
        s
    }
}

#[cfg(test)]
mod hash_tests {
    use super::*;
    use crate::job::config_hash;

    /// A default `[pause]` hashes as the config did before the section existed (its
    /// encoding without the section's trailing bytes); any other park changes the hash.
    #[test]
    fn a_default_section_keeps_the_hash_and_another_changes_it() {
        let mut c = super::super::tests::seed();
        let mut buf = [0u8; 2048];
        let full = postcard::to_slice(&c, &mut buf).unwrap().len();
        let mut tail = [0u8; 32];
        let own = postcard::to_slice(&c.pause, &mut tail).unwrap().len();
        let legacy = crate::job::CRC.checksum(&buf[..full - own]);
        assert_eq!(config_hash(&c), legacy);
        c.pause.park_lift_mm = 2.0;
        assert_ne!(config_hash(&c), legacy);
        c.pause = PauseConfig {
            park_position_mm: Some([0.0, 0.0]),
            ..PauseConfig::default()
        };
        assert_ne!(config_hash(&c), legacy);
    }
}
