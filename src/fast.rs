//! f32 `min` and `max` as the Cortex-M4F runs them in line, for the control cycle's hot
//! paths. ARMv7E-M has no `vminnm`, so `f32::min` / `f32::max` become calls to libm's
//! `fminf` / `fmaxf` (12 instructions and a call that spills the caller's float
//! registers); these are a compare and a select with the same answers, NaN included (the
//! other operand). Stops at min and max: roots and exponentials stay libm's (a Newton
//! `sqrt` on the float unit, tried in the follower, saved 1 instruction a tick on the
//! soft machine's mean).

/// The smaller of `a` and `b`; the other if one is NaN (as `f32::min`).
#[inline(always)]
pub fn min(a: f32, b: f32) -> f32 {
    if b < a || a.is_nan() {
        b
    } else {
        a
    }
}

/// The larger of `a` and `b`; the other if one is NaN (as `f32::max`).
#[inline(always)]
pub fn max(a: f32, b: f32) -> f32 {
    if b > a || a.is_nan() {
        b
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same answers as `f32::min` / `f32::max` over ordinary values, infinities,
    /// NaN on either side and equal operands.
    #[test]
    fn min_and_max_answer_as_the_standard_ones() {
        let xs = [
            -f32::INFINITY,
            -3.5,
            -1.0e-30,
            0.0,
            1.0e-30,
            2.25,
            7.0,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
        ];
        for &a in &xs {
            for &b in &xs {
                let same =
                    |x: f32, y: f32| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan());
                assert!(same(min(a, b), a.min(b)), "min({a}, {b})");
                assert!(same(max(a, b), a.max(b)), "max({a}, {b})");
            }
        }
    }
}
