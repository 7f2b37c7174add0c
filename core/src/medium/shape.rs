//! Region shapes and their ray intersections. Intervals are returned as ray parameters
//! `(t_enter, t_exit)` along `o + t·d` (unit `d`), possibly with `t_enter < 0` when `o` is inside.

use glam::DVec3;

/// A closed solid: the extent of a region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Circular cylinder of any orientation; `half_length = ∞` for an unbounded tube (clipped by
    /// its layer).
    Cylinder {
        center: DVec3,
        axis: DVec3,
        radius: f64,
        half_length: f64,
    },
    /// Axis-aligned box.
    Box {
        min: DVec3,
        max: DVec3,
    },
    Sphere {
        center: DVec3,
        radius: f64,
    },
}

impl Shape {
    /// Whether `p` lies inside (boundary included).
    #[inline]
    pub fn contains(&self, p: DVec3) -> bool {
        match *self {
            Shape::Cylinder { center, axis, radius, half_length } => {
                let d = p - center;
                let s = d.dot(axis);
                s.abs() <= half_length && (d - s * axis).length_squared() <= radius * radius
            }
            Shape::Box { min, max } => p.cmpge(min).all() && p.cmple(max).all(),
            Shape::Sphere { center, radius } => (p - center).length_squared() <= radius * radius,
        }
    }

    /// The parameter interval where the line `o + t·d` is inside the shape, if any.
    #[inline]
    pub fn intersect(&self, o: DVec3, d: DVec3) -> Option<(f64, f64)> {
        match *self {
            Shape::Sphere { center, radius } => {
                let oc = o - center;
                quadratic_interval(1.0, oc.dot(d), oc.length_squared() - radius * radius)
            }
            Shape::Cylinder { center, axis, radius, half_length } => {
                let oc = o - center;
                let (oa, da) = (oc.dot(axis), d.dot(axis));
                let (op, dp) = (oc - oa * axis, d - da * axis);
                let a = dp.length_squared();
                let c = op.length_squared() - radius * radius;
                let (mut t0, mut t1) = if a < 1e-24 {
                    // Parallel to the axis: inside for all t or never.
                    if c > 0.0 {
                        return None;
                    }
                    (f64::NEG_INFINITY, f64::INFINITY)
                } else {
                    quadratic_interval(a, op.dot(dp), c)?
                };
                if half_length.is_finite() {
                    let (s0, s1) = slab(oa, da, -half_length, half_length)?;
                    t0 = t0.max(s0);
                    t1 = t1.min(s1);
                }
                (t0 <= t1).then_some((t0, t1))
            }
            Shape::Box { min, max } => {
                let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
                for i in 0..3 {
                    let (s0, s1) = slab(o[i], d[i], min[i], max[i])?;
                    t0 = t0.max(s0);
                    t1 = t1.min(s1);
                }
                (t0 <= t1).then_some((t0, t1))
            }
        }
    }

    /// The outward unit normal of the boundary at `p` (a point on it, up to rounding), seen from
    /// the direction `toward` (a ray arriving along `−toward`): a box's face nearest `p` among
    /// those facing `toward` (at an edge, the face the ray came through), a cylinder's side or
    /// cap, whichever is nearer.
    pub fn outward_normal(&self, p: DVec3, toward: DVec3) -> DVec3 {
        match *self {
            Shape::Sphere { center, .. } => (p - center).normalize(),
            Shape::Cylinder { center, axis, radius, half_length } => {
                let d = p - center;
                let s = d.dot(axis);
                let radial = d - s * axis;
                let r = radial.length();
                if (half_length - s.abs()) < (radius - r).abs() || r == 0.0 { axis * s.signum() } else { radial / r }
            }
            Shape::Box { min, max } => {
                let mut best = (f64::INFINITY, DVec3::ZERO);
                for i in 0..3 {
                    let mut e = DVec3::ZERO;
                    for (dist, sign) in [(p[i] - min[i], -1.0), (max[i] - p[i], 1.0)] {
                        if dist.abs() < best.0 && sign * toward[i] >= 0.0 {
                            e[i] = sign;
                            best = (dist.abs(), e);
                        }
                    }
                }
                best.1
            }
        }
    }

    /// The length of the shape's longest extent (its bounding box's diagonal).
    pub fn size(&self) -> f64 {
        match *self {
            Shape::Sphere { radius, .. } => 2.0 * radius,
            Shape::Box { min, max } => (max - min).length(),
            Shape::Cylinder { radius, half_length, .. } => (2.0 * radius).hypot(2.0 * half_length),
        }
    }

    /// Half-extent of the shape along `z` about its centre (for placing it in its layer).
    /// The shape grown by `d` on every side (a box's faces moved out, a sphere's or cylinder's
    /// radius and a cylinder's half-length lengthened): a neighbourhood that holds it.
    pub fn grown(&self, d: f64) -> Shape {
        match *self {
            Shape::Cylinder { center, axis, radius, half_length } => {
                Shape::Cylinder { center, axis, radius: radius + d, half_length: half_length + d }
            }
            Shape::Box { min, max } => Shape::Box { min: min - DVec3::splat(d), max: max + DVec3::splat(d) },
            Shape::Sphere { center, radius } => Shape::Sphere { center, radius: radius + d },
        }
    }

    pub fn z_range(&self) -> (f64, f64) {
        match *self {
            Shape::Sphere { center, radius } => (center.z - radius, center.z + radius),
            Shape::Box { min, max } => (min.z, max.z),
            Shape::Cylinder { center, axis, radius, half_length } => {
                // Extent of a cylinder along z: |a_z|·h + R·√(1 − a_z²).
                let e = axis.z.abs() * half_length + radius * (1.0 - axis.z * axis.z).max(0.0).sqrt();
                (center.z - e, center.z + e)
            }
        }
    }
}

/// Roots of `a t² + 2 b t + c = 0` as an interval, computed without cancellation.
#[inline(always)]
fn quadratic_interval(a: f64, b: f64, c: f64) -> Option<(f64, f64)> {
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let q = -(b + disc.sqrt().copysign(b));
    if q == 0.0 {
        // b = 0 and c = 0: tangent at t = 0.
        return Some((0.0, 0.0));
    }
    let (r0, r1) = (q / a, c / q);
    Some((r0.min(r1), r0.max(r1)))
}

/// Where `o + t·d` lies in `[lo, hi]` for one coordinate.
#[inline(always)]
fn slab(o: f64, d: f64, lo: f64, hi: f64) -> Option<(f64, f64)> {
    if d == 0.0 {
        return (lo <= o && o <= hi).then_some((f64::NEG_INFINITY, f64::INFINITY));
    }
    let inv = 1.0 / d;
    let (a, b) = ((lo - o) * inv, (hi - o) * inv);
    Some((a.min(b), a.max(b)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_consistent(s: &Shape, o: DVec3, d: DVec3) {
        // Points just inside the returned interval are inside; points outside are not.
        match s.intersect(o, d) {
            Some((t0, t1)) => {
                let mid = 0.5 * (t0.max(-1e3) + t1.min(1e3));
                assert!(s.contains(o + mid * d), "{s:?} mid");
                if t0.is_finite() {
                    assert!(!s.contains(o + (t0 - 1e-6) * d));
                }
                if t1.is_finite() {
                    assert!(!s.contains(o + (t1 + 1e-6) * d));
                }
            }
            None => {
                for i in -100..100 {
                    assert!(!s.contains(o + (i as f64 * 0.05) * d));
                }
            }
        }
    }

    #[test]
    fn intersections_agree_with_containment() {
        let shapes = [
            Shape::Sphere { center: DVec3::new(0.1, 0.0, 0.5), radius: 0.3 },
            Shape::Box { min: DVec3::new(-0.2, -0.1, 0.2), max: DVec3::new(0.3, 0.4, 0.6) },
            Shape::Cylinder {
                center: DVec3::new(0.0, 0.0, 0.5),
                axis: DVec3::new(1.0, 0.0, 0.2).normalize(),
                radius: 0.2,
                half_length: f64::INFINITY,
            },
            Shape::Cylinder { center: DVec3::new(0.0, 0.1, 0.5), axis: DVec3::Y, radius: 0.25, half_length: 0.3 },
        ];
        let mut r = crate::sampling::PathRng::new(1, crate::sampling::Purpose::Test, 0, 0);
        for s in &shapes {
            for _ in 0..2000 {
                let o = DVec3::new(r.uniform() - 0.5, r.uniform() - 0.5, r.uniform()) * 1.5;
                let d = crate::sampling::warp::uniform_sphere(r.uniform(), r.uniform());
                check_consistent(s, o, d);
            }
            // Axis-parallel rays exercise the degenerate branches.
            check_consistent(s, DVec3::new(0.0, 0.0, -1.0), DVec3::Z);
            check_consistent(s, DVec3::new(-1.0, 0.0, 0.5), DVec3::X);
        }
    }

    #[test]
    fn sphere_chord() {
        let s = Shape::Sphere { center: DVec3::ZERO, radius: 1.0 };
        let (t0, t1) = s.intersect(DVec3::new(0.0, 0.0, -3.0), DVec3::Z).unwrap();
        assert!((t0 - 2.0).abs() < 1e-15 && (t1 - 4.0).abs() < 1e-15);
    }
}
