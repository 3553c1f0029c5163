//! Savitzky-Golay smoothing of a measured series: each point is replaced by the value at
//! that point of the least-squares polynomial through its window; near the ends the first
//! or last full window is used, so the series keeps its length and no end is padded.

use nalgebra::{DMatrix, DVector};

/// Weights that, dotted with a window of `2 half + 1` samples, give the polynomial of
/// `order` through them evaluated at sample `at` (0 ..= 2 half). `None` if singular.
fn weights(half: usize, order: usize, at: usize) -> Option<DVector<f64>> {
    let w = 2 * half + 1;
    let a = DMatrix::from_fn(w, order + 1, |i, c| (i as f64 - half as f64).powi(c as i32));
    let pinv = (a.transpose() * &a).try_inverse()? * a.transpose();
    let t = at as f64 - half as f64;
    let e = DVector::from_fn(order + 1, |c, _| t.powi(c as i32));
    Some(pinv.transpose() * e)
}

/// Smooths `y` with a window of `window` samples (made odd, and shrunk to fit a short
/// series) and a polynomial of `order` (lowered to below the window). Series too short to
/// smooth come back unchanged.
pub fn smooth(y: &[f64], window: usize, order: usize) -> Vec<f64> {
    let n = y.len();
    let mut w = window.min(n);
    if w.is_multiple_of(2) {
        w = w.saturating_sub(1);
    }
    if w < 3 {
        return y.to_vec();
    }
    let half = w / 2;
    let order = order.min(w - 2);
    let Some(center) = weights(half, order, half) else {
        return y.to_vec();
    };
    let dot = |c: &DVector<f64>, start: usize| -> f64 {
        c.iter().zip(&y[start..start + w]).map(|(a, b)| a * b).sum()
    };
    let mut out = vec![0.0; n];
    for (i, o) in out.iter_mut().enumerate() {
        *o = if i < half {
            weights(half, order, i).map_or(y[i], |c| dot(&c, 0))
        } else if i + half >= n {
            weights(half, order, i + w - n).map_or(y[i], |c| dot(&c, n - w))
        } else {
            dot(&center, i - half)
        };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_polynomials_of_its_order_exactly() {
        let y: Vec<f64> = (0..15)
            .map(|i| 2.0 + 0.5 * i as f64 - 0.03 * (i * i) as f64)
            .collect();
        let s = smooth(&y, 7, 2);
        for (a, b) in y.iter().zip(&s) {
            assert!((a - b).abs() < 1e-9, "{a} {b}");
        }
    }

    #[test]
    fn known_five_point_quadratic_weights() {
        // The classic table: (-3, 12, 17, 12, -3) / 35.
        let c = weights(2, 2, 2).unwrap();
        let want = [-3.0, 12.0, 17.0, 12.0, -3.0].map(|v| v / 35.0);
        for (a, b) in c.iter().zip(want) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn reduces_alternating_noise_and_survives_short_series() {
        let y: Vec<f64> = (0..21)
            .map(|i| 5.0 + if i % 2 == 0 { 0.2 } else { -0.2 })
            .collect();
        let s = smooth(&y, 9, 2);
        let spread = |v: &[f64]| v.iter().map(|x| (x - 5.0).abs()).fold(0.0, f64::max);
        assert!(spread(&s[4..17]) < 0.05, "{s:?}");
        assert_eq!(smooth(&[1.0, 2.0], 9, 2), vec![1.0, 2.0]);
        assert_eq!(smooth(&[], 9, 2), Vec::<f64>::new());
    }
}
