//! Path geometry and kinematics: corner fillets sized by the acceleration limit, points
//! along lines and arcs, and time-based trapezoid profiles for travel moves. Which element
//! the head is on, and how fast, is the executor's call.

use crate::real::Real;

/// A 2D vector.
pub type V2<R> = [R; 2];

/// A rounded corner: the arc tangent to both segments at distance `tangent` from the
/// vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fillet<R> {
    /// Distance from the vertex back along the incoming and forward along the outgoing
    /// segment to the tangent points, mm.
    pub tangent: R,
    /// Arc centre.
    pub centre: V2<R>,
    /// Radius, mm.
    pub radius: R,
    /// Angle of the start point seen from the centre, rad.
    pub start_angle: R,
    /// Signed sweep (positive: counter-clockwise), rad.
    pub sweep: R,
}

impl<R: Real> Fillet<R> {
    /// Arc length, mm.
    pub fn length(&self) -> R {
        self.radius * self.sweep.abs()
    }
    /// Point at arc length `s` from the start.
    pub fn point(&self, s: R) -> V2<R> {
        let phi = if self.sweep >= R::ZERO {
            self.start_angle + s / self.radius
        } else {
            self.start_angle - s / self.radius
        };
        let (sin, cos) = phi.sin_cos();
        [
            self.centre[0] + self.radius * cos,
            self.centre[1] + self.radius * sin,
        ]
    }
}

/// The fillet at a vertex where a segment along unit `u1` meets one along unit `u2`, with
/// `radius` wanted and at most `max_tangent` of either segment usable. `None` where the
/// path goes straight on. Where the segments are too short for `radius`, the radius shrinks
/// to fit (the corner is then tighter than the acceleration limit allows at top speed).
/// A full reversal has no fillet: the head turns on the spot.
pub fn fillet<R: Real>(
    vertex: V2<R>,
    u1: V2<R>,
    u2: V2<R>,
    radius: R,
    max_tangent: R,
) -> Option<Fillet<R>> {
    let cos = u1[0] * u2[0] + u1[1] * u2[1];
    let cross = u1[0] * u2[1] - u1[1] * u2[0];
    if cross.abs() < R::of(1e-6) {
        return None;
    }
    // tan(theta/2) = |cross| / (1 + cos): no trigonometry for the size.
    let tan_half = cross.abs() / (R::ONE + cos);
    let mut r = radius;
    let mut t = r * tan_half;
    if t > max_tangent {
        t = max_tangent;
        r = t / tan_half;
    }
    if r <= R::ZERO || !(r.is_finite() && t.is_finite()) {
        return None;
    }
    let left = cross > R::ZERO;
    // Normal towards the inside of the turn.
    let n = if left {
        [-u1[1], u1[0]]
    } else {
        [u1[1], -u1[0]]
    };
    let p1 = [vertex[0] - u1[0] * t, vertex[1] - u1[1] * t];
    let centre = [p1[0] + n[0] * r, p1[1] + n[1] * r];
    let start_angle = (p1[1] - centre[1]).atan2(p1[0] - centre[0]);
    let theta = cross.abs().atan2(cos);
    Some(Fillet {
        tangent: t,
        centre,
        radius: r,
        start_angle,
        sweep: if left { theta } else { -theta },
    })
}

/// A straight move of `length` at up to `v_max` with acceleration `a_max`, from rest to
/// rest: accelerate, cruise, decelerate (a triangle when too short to reach `v_max`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trapezoid<R> {
    /// Total length, mm.
    pub length: R,
    /// Peak speed reached, mm/s.
    pub v_peak: R,
    /// Acceleration, mm/s^2.
    pub accel: R,
    /// Time accelerating (= decelerating), s.
    pub t_ramp: R,
    /// Time cruising, s.
    pub t_cruise: R,
}

impl<R: Real> Trapezoid<R> {
    /// Plans the profile. `v_max` and `a_max` must be positive.
    pub fn new(length: R, v_max: R, a_max: R) -> Self {
        let length = length.max(R::ZERO);
        let ramp_len = v_max * v_max / (R::TWO * a_max);
        if R::TWO * ramp_len >= length {
            let v_peak = (a_max * length).sqrt();
            Trapezoid {
                length,
                v_peak,
                accel: a_max,
                t_ramp: v_peak / a_max,
                t_cruise: R::ZERO,
            }
        } else {
            Trapezoid {
                length,
                v_peak: v_max,
                accel: a_max,
                t_ramp: v_max / a_max,
                t_cruise: (length - R::TWO * ramp_len) / v_max,
            }
        }
    }
    /// Duration, s.
    pub fn duration(&self) -> R {
        R::TWO * self.t_ramp + self.t_cruise
    }
    /// Distance covered after `t` seconds.
    pub fn distance(&self, t: R) -> R {
        let a = self.accel;
        if t <= R::ZERO {
            R::ZERO
        } else if t < self.t_ramp {
            R::HALF * a * t * t
        } else if t < self.t_ramp + self.t_cruise {
            R::HALF * a * self.t_ramp * self.t_ramp + self.v_peak * (t - self.t_ramp)
        } else if t < self.duration() {
            let td = self.duration() - t;
            self.length - R::HALF * a * td * td
        } else {
            self.length
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn right_angle_fillet_is_tangent_and_centred() {
        let f = fillet([10.0f64, 0.0], [1.0, 0.0], [0.0, 1.0], 0.5, 5.0).unwrap();
        assert!((f.tangent - 0.5).abs() < 1e-12);
        assert!((f.centre[0] - 9.5).abs() < 1e-12 && (f.centre[1] - 0.5).abs() < 1e-12);
        let start = f.point(0.0);
        let end = f.point(f.length());
        assert!((start[0] - 9.5).abs() < 1e-12 && start[1].abs() < 1e-12);
        assert!((end[0] - 10.0).abs() < 1e-12 && (end[1] - 0.5).abs() < 1e-12);
        assert!((f.length() - 0.5 * core::f64::consts::FRAC_PI_2).abs() < 1e-12);
        // Clockwise turn mirrors it.
        let g = fillet([10.0f64, 0.0], [1.0, 0.0], [0.0, -1.0], 0.5, 5.0).unwrap();
        let end = g.point(g.length());
        assert!((end[0] - 10.0).abs() < 1e-12 && (end[1] + 0.5).abs() < 1e-12);
    }

    #[test]
    fn short_segments_shrink_the_radius() {
        let f = fillet([0.0f64, 0.0], [1.0, 0.0], [0.0, 1.0], 2.0, 0.1).unwrap();
        assert!((f.tangent - 0.1).abs() < 1e-12 && (f.radius - 0.1).abs() < 1e-12);
        assert!(fillet([0.0f64, 0.0], [1.0, 0.0], [1.0, 0.0], 2.0, 0.1).is_none());
        assert!(fillet([0.0f64, 0.0], [1.0, 0.0], [-1.0, 0.0], 2.0, 0.1).is_none());
    }

    #[test]
    fn trapezoid_and_triangle_reach_the_end_within_limits() {
        for (len, v, a) in [(100.0f64, 50.0, 1000.0), (1.0, 50.0, 1000.0)] {
            let t = Trapezoid::new(len, v, a);
            assert!(t.v_peak <= v + 1e-12);
            assert!((t.distance(t.duration()) - len).abs() < 1e-9);
            let mut last = 0.0;
            let mut last_v = 0.0;
            let n = 10_000;
            for i in 1..=n {
                let time = t.duration() * i as f64 / n as f64;
                let d = t.distance(time);
                let vel = (d - last) / (t.duration() / n as f64);
                assert!(vel <= v * 1.0001 && vel >= -1e-9);
                assert!((vel - last_v).abs() / (t.duration() / n as f64) <= a * 1.01 + 1e-6);
                last = d;
                last_v = vel;
            }
        }
    }
}
