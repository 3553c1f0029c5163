//! `Real`: the float type the core computes in (f32 on the chip, f64 for reference runs),
//! with the maths it needs routed through `libm` so both behave the same on host and target.

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// A float the planning core can run on. Implemented for `f32` (what the chip runs) and
/// `f64` (the reference the f32 path is tested against).
pub trait Real:
    Copy
    + Debug
    + Default
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
{
    /// 0
    const ZERO: Self;
    /// Not a number (the marker for "none yet").
    const NAN: Self;
    /// 1
    const ONE: Self;
    /// 2
    const TWO: Self;
    /// 1/2
    const HALF: Self;
    /// pi
    const PI: Self;
    /// Machine epsilon of the type.
    const EPSILON: Self;
    /// Converts a constant or reference value (rounds for f32).
    fn of(x: f64) -> Self;
    /// Widens to f64.
    fn to_f64(self) -> f64;
    /// Converts to f32 (rounds for f64).
    fn to_f32(self) -> f32;
    /// Square root (libm; exact rounding for f32's `sqrtf`).
    fn sqrt(self) -> Self;
    /// e^x
    fn exp(self) -> Self;
    /// Natural logarithm.
    fn ln(self) -> Self;
    /// self^y
    fn powf(self, y: Self) -> Self;
    /// Sine (radians).
    fn sin(self) -> Self;
    /// Cosine (radians).
    fn cos(self) -> Self;
    /// Four-quadrant arctangent of self/x.
    fn atan2(self, x: Self) -> Self;
    /// (sin, cos) of an angle in [-2 pi, 2 pi], for the per-cycle path (corner arcs).
    /// f32 uses `poly::sin_cos` (pure f32, under 1e-6 absolute error); f64 uses libm.
    fn sin_cos(self) -> (Self, Self);
    /// `self^y` for `self >= 0`, for the per-cycle flow solve. f32 uses `poly::powf`
    /// (pure f32, under 2e-6 relative error for exponents up to 1); f64 uses libm.
    fn pow_fast(self, y: Self) -> Self;
    /// log2 of `self > 0`, for the flow solve, which raises one flow to several flow
    /// indices: `exp2_fast(n * q.log2_fast())` is `q^n` at the accuracy of `pow_fast`.
    fn log2_fast(self) -> Self;
    /// 2^self (see `log2_fast`).
    fn exp2_fast(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Largest integer not above.
    fn floor(self) -> Self;
    /// True unless NaN or infinite.
    fn is_finite(self) -> bool;
    /// Nearest i64 (ties away from zero); saturates, NaN gives 0.
    fn round_i64(self) -> i64;
    /// From an integer (rounds when it does not fit the mantissa).
    fn from_i64(x: i64) -> Self;
    /// From a small unsigned integer (one instruction on an FPU).
    fn from_u32(x: u32) -> Self;
    /// Nearest i32 (ties away from zero), saturating; NaN gives 0. For values known to
    /// fit (step positions), without `round_i64`'s wide path.
    fn round_i32(self) -> i32;
    /// The smaller of two: `self` if `o` is NaN, NaN if `self` is (unlike `f32::min` and
    /// `crate::fast::min`, which give the other for either: a NaN here shows).
    #[inline]
    fn min(self, o: Self) -> Self {
        if o < self {
            o
        } else {
            self
        }
    }
    /// The larger of two: `self` if `o` is NaN, NaN if `self` is (as `min`).
    #[inline]
    fn max(self, o: Self) -> Self {
        if o > self {
            o
        } else {
            self
        }
    }
}

impl Real for f32 {
    const ZERO: Self = 0.0;
    const NAN: Self = f32::NAN;
    const ONE: Self = 1.0;
    const TWO: Self = 2.0;
    const HALF: Self = 0.5;
    const PI: Self = core::f32::consts::PI;
    const EPSILON: Self = f32::EPSILON;
    #[inline]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline]
    fn to_f32(self) -> f32 {
        self
    }
    #[inline]
    fn sqrt(self) -> Self {
        libm::sqrtf(self)
    }
    #[inline]
    fn exp(self) -> Self {
        libm::expf(self)
    }
    #[inline]
    fn ln(self) -> Self {
        libm::logf(self)
    }
    #[inline]
    fn powf(self, y: Self) -> Self {
        libm::powf(self, y)
    }
    #[inline]
    fn sin(self) -> Self {
        libm::sinf(self)
    }
    #[inline]
    fn cos(self) -> Self {
        libm::cosf(self)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        libm::atan2f(self, x)
    }
    #[inline]
    fn sin_cos(self) -> (Self, Self) {
        crate::poly::sin_cos(self)
    }
    #[inline]
    fn pow_fast(self, y: Self) -> Self {
        crate::poly::powf(self, y)
    }
    #[inline]
    fn log2_fast(self) -> Self {
        crate::poly::log2_any(self)
    }
    #[inline]
    fn exp2_fast(self) -> Self {
        crate::poly::exp2(self)
    }
    #[inline]
    fn abs(self) -> Self {
        libm::fabsf(self)
    }
    #[inline]
    fn floor(self) -> Self {
        libm::floorf(self)
    }
    #[inline]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[inline]
    fn round_i64(self) -> i64 {
        // The M4F converts f32 <-> i32 in one instruction but i64 only in software: take
        // the i32 path whenever the value fits (every per-cycle volume and step does).
        if self.abs() < 2.0e9 {
            let t = self as i32;
            let r = self - t as f32;
            let t = if r >= 0.5 {
                t + 1
            } else if r <= -0.5 {
                t - 1
            } else {
                t
            };
            t as i64
        } else {
            libm::roundf(self) as i64
        }
    }
    #[inline]
    fn from_i64(x: i64) -> Self {
        if x >= i32::MIN as i64 && x <= i32::MAX as i64 {
            x as i32 as f32
        } else {
            // High and low words apart: two one-instruction conversions, at most one ulp
            // off the correctly rounded value.
            ((x >> 32) as i32 as f32) * 4_294_967_296.0 + (x as u32) as f32
        }
    }
    #[inline]
    fn from_u32(x: u32) -> Self {
        x as f32
    }
    #[inline]
    fn round_i32(self) -> i32 {
        let t = self as i32;
        let r = self - t as f32;
        // Beyond 2^24 f32 holds whole numbers only, so r is 0 there (and at saturation).
        if r >= 0.5 {
            t.saturating_add(1)
        } else if r <= -0.5 {
            t.saturating_sub(1)
        } else {
            t
        }
    }
}

impl Real for f64 {
    const ZERO: Self = 0.0;
    const NAN: Self = f64::NAN;
    const ONE: Self = 1.0;
    const TWO: Self = 2.0;
    const HALF: Self = 0.5;
    const PI: Self = core::f64::consts::PI;
    const EPSILON: Self = f64::EPSILON;
    #[inline]
    fn of(x: f64) -> Self {
        x
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn to_f32(self) -> f32 {
        self as f32
    }
    #[inline]
    fn sqrt(self) -> Self {
        libm::sqrt(self)
    }
    #[inline]
    fn exp(self) -> Self {
        libm::exp(self)
    }
    #[inline]
    fn ln(self) -> Self {
        libm::log(self)
    }
    #[inline]
    fn powf(self, y: Self) -> Self {
        libm::pow(self, y)
    }
    #[inline]
    fn sin(self) -> Self {
        libm::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        libm::cos(self)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        libm::atan2(self, x)
    }
    #[inline]
    fn sin_cos(self) -> (Self, Self) {
        (libm::sin(self), libm::cos(self))
    }
    #[inline]
    fn pow_fast(self, y: Self) -> Self {
        libm::pow(self, y)
    }
    #[inline]
    fn log2_fast(self) -> Self {
        libm::log2(self)
    }
    #[inline]
    fn exp2_fast(self) -> Self {
        libm::exp2(self)
    }
    #[inline]
    fn abs(self) -> Self {
        libm::fabs(self)
    }
    #[inline]
    fn floor(self) -> Self {
        libm::floor(self)
    }
    #[inline]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    #[inline]
    fn round_i64(self) -> i64 {
        libm::round(self) as i64
    }
    #[inline]
    fn from_i64(x: i64) -> Self {
        x as f64
    }
    #[inline]
    fn from_u32(x: u32) -> Self {
        x as f64
    }
    #[inline]
    fn round_i32(self) -> i32 {
        libm::round(self) as i32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `min` and `max` keep `self` against a NaN and show a NaN `self` (their docs).
    #[test]
    fn min_and_max_show_a_nan_self() {
        for (a, b) in [(1.0f32, 2.0f32), (2.0, 1.0), (-0.5, -0.5)] {
            assert_eq!(Real::min(a, b), a.min(b));
            assert_eq!(Real::max(a, b), a.max(b));
        }
        assert_eq!(Real::min(1.0f32, f32::NAN), 1.0);
        assert_eq!(Real::max(1.0f64, f64::NAN), 1.0);
        assert!(Real::min(f32::NAN, 1.0).is_nan());
        assert!(Real::max(f64::NAN, 1.0).is_nan());
    }

    #[test]
    fn fast_f32_conversions_match_the_exact_ones() {
        for &x in &[
            0.0f32,
            0.49999997,
            0.5,
            -0.5,
            1.5,
            -2.5,
            1e7 + 0.5,
            3.0e9,
            -3.0e9,
            1.7e18,
            -1.7e18,
            2.1e9,
            -2.0e9,
            9.2e18,
            -9.3e18,
            1e30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ] {
            let want = if x.is_nan() {
                0
            } else {
                libm::roundf(x) as i64
            };
            assert_eq!(x.round_i64(), want, "{x}");
            let want32 = if x.is_nan() {
                0
            } else {
                libm::roundf(x) as i32
            };
            assert_eq!(x.round_i32(), want32, "{x}");
        }
        let mut v = 1i64;
        for _ in 0..62 {
            for &x in &[v, -v, v + 12345, v * 3 - 1] {
                let fast = f32::from_i64(x) as f64;
                let exact = x as f64;
                let ulp = (exact.abs() as f32).max(1.0) as f64 * f32::EPSILON as f64;
                assert!((fast - exact).abs() <= ulp, "{x}: {fast} vs {exact}");
            }
            v *= 2;
        }
    }
}
