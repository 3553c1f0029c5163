//! f32 `min` and `max` as the Cortex-M4F runs them in line, for the control cycle's hot
//! paths. ARMv7E-M has no `vminnm`, so `f32::min` / `f32::max` become calls to libm's
//! `fminf` / `fmaxf` (12 instructions and a call that spills the caller's float
//! registers); these are a compare and a select with the same answers, NaN included (the
//! other operand). Roots stay libm's (a Newton `sqrt` on the float unit, tried in the
//! follower, saved 1 instruction a tick on the soft machine's mean), but `hypot` and
//! `root_of_square_less` skip the root (about 45 instructions) where its answer is known
//! exactly: the root of a square is the number itself. Stops there: exponentials stay
//! libm's.

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

/// Least and greatest magnitude whose square is a normal f32 (neither under- nor
/// overflowing), where `sqrtf(x * x) == |x|` holds: in binary floating point with
/// round-to-nearest the correctly rounded root of a correctly rounded square is the number.
const SQUARE_LEAST: f32 = 1.0e-18;
const SQUARE_MOST: f32 = 1.0e18;

/// `libm::sqrtf(x * x + y * y)`, bit for bit, with no root when one of them is zero (a
/// bead along an axis, the usual case of an image's rows).
#[inline(always)]
pub fn hypot(x: f32, y: f32) -> f32 {
    let (ax, ay) = (libm::fabsf(x), libm::fabsf(y));
    if y == 0.0 && (SQUARE_LEAST..=SQUARE_MOST).contains(&ax) {
        ax
    } else if x == 0.0 && (SQUARE_LEAST..=SQUARE_MOST).contains(&ay) {
        ay
    } else {
        libm::sqrtf(x * x + y * y)
    }
}

/// `libm::sqrtf(max(top * top - d, 0))` for `top >= 0`, bit for bit, with no root when `d`
/// is too small to change the square (a straight, where the turn takes nothing).
#[inline(always)]
pub fn root_of_square_less(top: f32, d: f32) -> f32 {
    let top2 = top * top;
    let left = top2 - d;
    if left == top2 && (SQUARE_LEAST..=SQUARE_MOST).contains(&top) {
        top
    } else {
        libm::sqrtf(max(left, 0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shortcuts answer as the roots they skip, bit for bit, over axis-aligned and
    /// general moves, tiny and huge magnitudes and turns too small to count.
    #[test]
    fn shortcuts_answer_as_the_roots() {
        let mut seed = 0x2545_f491_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        let mut values = vec![
            0.0f32, -0.0, 1.0e-30, 1.0e-18, 1.0e-17, 1.0e18, 1.0e19, 3.0e38,
        ];
        for _ in 0..20_000 {
            // Any finite f32 of either sign, and ones near the follower's (units a frame).
            let bits = next();
            let v = f32::from_bits(bits);
            if v.is_finite() {
                values.push(v);
            }
            values.push((next() % 100_000) as f32 * 1.0e-3 - 50.0);
        }
        for &x in &values {
            for y in [0.0f32, -0.0, x * 0.5] {
                let want = libm::sqrtf(x * x + y * y);
                assert_eq!(hypot(x, y).to_bits(), want.to_bits(), "hypot({x}, {y})");
                assert_eq!(hypot(y, x).to_bits(), want.to_bits(), "hypot({y}, {x})");
            }
            let top = libm::fabsf(x);
            for d in [0.0f32, top * top * 1.0e-9, top * top * 0.3, top * top * 2.0] {
                let want = libm::sqrtf(max(top * top - d, 0.0));
                assert_eq!(
                    root_of_square_less(top, d).to_bits(),
                    want.to_bits(),
                    "root_of_square_less({top}, {d})"
                );
            }
        }
    }

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
