//! Single-precision sine/cosine and power for the per-cycle path. libm's `sinf`, `cosf`
//! and `powf` compute in f64, which the Cortex-M4F does in software (thousands of
//! instructions); these stay in f32 hardware arithmetic at a stated accuracy, tested
//! against f64 below. Constants and set-up code keep using libm.

/// (sin x, cos x) for |x| <= 2 pi, absolute error under 1e-6 (on a 0.25 mm corner arc:
/// 0.25 nm of position). Uses the half angle so the
/// Taylor series runs on |x/2| <= pi, reduced further to |x/4| <= pi/2.
pub fn sin_cos(x: f32) -> (f32, f32) {
    // Quarter angle within [-pi/2, pi/2]: series to x^11 err < (pi/2)^13/13! = 5e-8.
    let q = x * 0.25;
    let q2 = q * q;
    let s = q
        * (1.0
            + q2 * (-1.0 / 6.0
                + q2 * (1.0 / 120.0
                    + q2 * (-1.0 / 5040.0 + q2 * (1.0 / 362_880.0 + q2 * (-1.0 / 39_916_800.0))))));
    let c = 1.0
        + q2 * (-0.5
            + q2 * (1.0 / 24.0
                + q2 * (-1.0 / 720.0
                    + q2 * (1.0 / 40_320.0
                        + q2 * (-1.0 / 3_628_800.0 + q2 * (1.0 / 479_001_600.0))))));
    // Double twice: sin 2a = 2 sin a cos a, cos 2a = 1 - 2 sin^2 a (stable near a = 0).
    let (s2, c2) = (2.0 * s * c, 1.0 - 2.0 * s * s);
    (2.0 * s2 * c2, 1.0 - 2.0 * s2 * s2)
}

/// log2 of a positive normal f32, absolute error under 3e-7.
#[inline(always)]
fn log2(x: f32) -> f32 {
    let bits = x.to_bits();
    let exp = ((bits >> 23) & 0xFF) as i32 - 127;
    // Mantissa in [sqrt(1/2), sqrt(2)) so the series variable stays small.
    let mut m = f32::from_bits((bits & 0x007F_FFFF) | 0x3F80_0000);
    let mut e = exp as f32;
    if m > core::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1.0;
    }
    // ln m = 2 atanh(t), t = (m - 1)/(m + 1), |t| <= 0.1716: series to t^9 (the next
    // term, 2 t^11 / 11, is under 1e-9).
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let ln_m =
        2.0 * t * (1.0 + t2 * (1.0 / 3.0 + t2 * (1.0 / 5.0 + t2 * (1.0 / 7.0 + t2 * (1.0 / 9.0)))));
    e + ln_m * core::f32::consts::LOG2_E
}

/// log2 of any x > 0: the series for normal x, libm for the rest (subnormal, 0, inf).
/// The test on the bits: positive and normal is one range of them (`is_normal`
/// classified the float through a chain of tests).
pub fn log2_any(x: f32) -> f32 {
    if (0x0080_0000..0x7F80_0000).contains(&x.to_bits()) {
        log2(x)
    } else {
        libm::log2f(x)
    }
}

/// 2^y for y in f32's normal range, relative error under 5e-7. Inlined: the flow
/// solve's loop over the pastes calls it once a paste.
#[inline(always)]
pub fn exp2(y: f32) -> f32 {
    if y < -126.0 {
        return 0.0;
    }
    if y > 127.0 {
        return f32::INFINITY;
    }
    // Nearest integer (ties either way) leaves |f| <= 1/2.
    let n = if y >= 0.0 {
        (y + 0.5) as i32
    } else {
        (y - 0.5) as i32
    };
    let f = y - n as f32;
    let z = f * core::f32::consts::LN_2;
    // e^z for |z| <= 0.347: series to z^6, err < 0.347^7/7! = 1.2e-7 relative (f32's
    // own rounding is 6e-8).
    let p = 1.0
        + z * (1.0
            + z * (0.5
                + z * (1.0 / 6.0 + z * (1.0 / 24.0 + z * (1.0 / 120.0 + z * (1.0 / 720.0))))));
    p * f32::from_bits(((n + 127) as u32) << 23)
}

/// x^y for x >= 0 (0 for x <= 0), relative error under 1e-5 where |y log2 x| <= 150
/// (the flow solve's Q^n, Q from 1e-6 to 1e4 mm^3/s: under 2e-6 for n <= 1).
pub fn powf(x: f32, y: f32) -> f32 {
    // Positive and normal, nearly always: one range of the bits (as `log2_any`).
    if (0x0080_0000..0x7F80_0000).contains(&x.to_bits()) {
        return exp2(y * log2(x));
    }
    if x <= 0.0 || x.is_nan() {
        return 0.0;
    }
    libm::powf(x, y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_within_1e_6_over_two_turns() {
        let mut worst = 0.0f64;
        for i in -20_000..=20_000 {
            let x = i as f32 * (2.0 * core::f32::consts::PI / 20_000.0);
            let (s, c) = sin_cos(x);
            let xd = x as f64;
            worst = worst
                .max((s as f64 - xd.sin()).abs())
                .max((c as f64 - xd.cos()).abs());
        }
        assert!(worst < 1e-6, "{worst:e}");
    }

    /// The range of bits `log2_any` and `powf` test is exactly the positive normal
    /// floats, over the edges either side of it.
    #[test]
    fn the_bits_range_is_the_positive_normal_floats() {
        let xs = [
            0.0f32,
            -0.0,
            f32::from_bits(1),
            f32::from_bits(0x007F_FFFF),
            f32::MIN_POSITIVE,
            1.0,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
            -f32::NAN,
            -f32::MIN_POSITIVE,
            -1.0,
            -f32::INFINITY,
        ];
        for x in xs {
            let range = (0x0080_0000..0x7F80_0000).contains(&x.to_bits());
            assert_eq!(range, x.is_normal() && x > 0.0, "{x:e}");
            let want = if x.is_normal() && x > 0.0 {
                log2(x)
            } else {
                libm::log2f(x)
            };
            let got = log2_any(x);
            assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()));
        }
        assert_eq!(
            powf(f32::from_bits(1), 0.5),
            libm::powf(f32::from_bits(1), 0.5)
        );
        assert_eq!(powf(f32::INFINITY, 0.5), f32::INFINITY);
        assert_eq!(powf(f32::NAN, 0.5), 0.0);
        assert_eq!(powf(-0.0, 0.5), 0.0);
    }

    #[test]
    fn powf_within_1e_5_relative_where_the_flow_solve_uses_it() {
        // Flows from 1e-6 to 1e4 mm^3/s, flow indices 0.1 ..= 1, and their inverses.
        let mut worst = 0.0f64;
        let mut worst_flow = 0.0f64;
        for i in 0..=400 {
            let x = 10f32.powf(-6.0 + 10.0 * i as f32 / 400.0);
            for &y in &[0.1f32, 0.25, 0.45, 0.6, 0.99, 1.0, 1.0 / 0.45, 2.5, 10.0] {
                let want = (x as f64).powf(y as f64);
                if want.is_finite() && want > 1e-37 && want < 1e37 {
                    let got = powf(x, y) as f64;
                    let rel = ((got - want) / want).abs();
                    worst = worst.max(rel);
                    if y <= 1.0 {
                        worst_flow = worst_flow.max(rel);
                    }
                }
            }
        }
        assert!(worst < 1e-5, "{worst:e}");
        assert!(worst_flow < 2e-6, "{worst_flow:e}");
        assert_eq!(powf(0.0, 0.5), 0.0);
        // The split form the flow solve uses (one log2, several exp2) is the same.
        for &x in &[1e-5f32, 0.37, 1.0, 12.5, 3e3] {
            for &y in &[0.45f32, 0.6, 1.0] {
                assert_eq!(exp2(y * log2_any(x)), powf(x, y));
            }
        }
        assert_eq!(exp2(0.5 * log2_any(0.0)), 0.0);
        assert_eq!(powf(-1.0, 0.5), 0.0);
    }
}
