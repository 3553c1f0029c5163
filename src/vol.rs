//! `Vol`: volumes as fixed-point integers (0.1 pL steps), so that the cumulative volume
//! that clocks a print never drifts however long it runs; floats only see differences.

use crate::real::Real;
use serde::{Deserialize, Serialize};

/// A volume in units of 1e-10 mm^3 (0.1 pL). An i64 spans +-9.2e8 mm^3 (922 litres),
/// far beyond a print, while one control cycle moves about 1e7 units, so rounding a
/// cycle's float volume to this grid costs under 1e-7 of it.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Vol(pub i64);

/// Units per mm^3.
pub const UNITS_PER_MM3: f64 = 1e10;

impl Vol {
    /// Zero volume.
    pub const ZERO: Vol = Vol(0);
    /// The nearest grid volume to `mm3` (saturates; NaN gives zero).
    #[inline]
    pub fn from_mm3<R: Real>(mm3: R) -> Vol {
        Vol((mm3 * R::of(UNITS_PER_MM3)).round_i64())
    }
    /// This volume in mm^3.
    #[inline]
    pub fn mm3<R: Real>(self) -> R {
        R::from_i64(self.0) * R::of(1.0 / UNITS_PER_MM3)
    }
    /// Sum. Plain two's-complement arithmetic (two instructions on the M4): volumes in a
    /// job stay below 1e8 mm^3 of print, ten thousand times inside the range, so the
    /// saturating forms' extra checks would only cost time on every cycle.
    #[inline]
    pub fn plus(self, o: Vol) -> Vol {
        Vol(self.0.wrapping_add(o.0))
    }
    /// Difference (see `plus`).
    #[inline]
    pub fn minus(self, o: Vol) -> Vol {
        Vol(self.0.wrapping_sub(o.0))
    }
}

impl core::ops::Add for Vol {
    type Output = Vol;
    #[inline]
    fn add(self, o: Vol) -> Vol {
        self.plus(o)
    }
}
impl core::ops::Sub for Vol {
    type Output = Vol;
    #[inline]
    fn sub(self, o: Vol) -> Vol {
        self.minus(o)
    }
}
impl core::ops::AddAssign for Vol {
    #[inline]
    fn add_assign(&mut self, o: Vol) {
        *self = self.plus(o)
    }
}
impl core::ops::SubAssign for Vol {
    #[inline]
    fn sub_assign(&mut self, o: Vol) {
        *self = self.minus(o)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_a_cycle_volume_to_1e_7() {
        for &x in &[1e-3f32, 3.7e-4, 0.25, 1.2] {
            let back: f32 = Vol::from_mm3(x).mm3();
            assert!(((back - x) / x).abs() < 1e-7, "{x} -> {back}");
        }
    }

    #[test]
    fn a_million_cycles_do_not_drift() {
        // 1e6 cycles of 1e-3 mm^3 summed on the grid equal the product to the grid step.
        let mut acc = Vol::ZERO;
        let step = Vol::from_mm3(1e-3f32);
        for _ in 0..1_000_000 {
            acc += step;
        }
        assert_eq!(acc.0, step.0 * 1_000_000);
        let total: f64 = acc.mm3();
        assert!((total - 1000.0).abs() < 1e-3, "{total}");
    }

    #[test]
    fn nan_and_huge_do_not_panic() {
        assert_eq!(Vol::from_mm3(f32::NAN), Vol(0));
        assert_eq!(Vol::from_mm3(f32::INFINITY).0, i64::MAX);
    }
}
