//! Frame step `render`: warping uniform values into directions and points, and the pdfs
//! that go with them (pbrt-v4 chapter A.5 and Shirley & Chiu 1997).

use glam::{Vec2, Vec3A};

/// A point on the unit disk, area-preserving (Shirley & Chiu 1997, "A Low Distortion Map
/// Between Disk and Square").
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let offset = u * 2.0 - Vec2::ONE;
    if offset == Vec2::ZERO {
        return Vec2::ZERO;
    }
    // The angle is pi/4 (b / a), a the larger offset, about a's axis: within a quarter turn.
    if offset.x.abs() > offset.y.abs() {
        let (cos, sin) = cos_sin_quarter(std::f32::consts::FRAC_PI_4 * (offset.y / offset.x));
        offset.x * Vec2::new(cos, sin)
    } else {
        // theta = pi/2 - angle: cos theta = sin angle, sin theta = cos angle.
        let (cos, sin) = cos_sin_quarter(std::f32::consts::FRAC_PI_4 * (offset.x / offset.y));
        offset.y * Vec2::new(sin, cos)
    }
}

/// (cos a, sin a) for |a| <= pi/4, by their Taylor series to the a^10 and a^9 terms (the
/// first terms left out are below 2e-9 there, under an f32's rounding). Inlined, where
/// `f32::sin_cos` calls libm's `sincosf` with its full range reduction: 1.2% of a
/// first-light frame's cycles, at one Lambertian bounce a vertex.
#[inline(always)]
fn cos_sin_quarter(a: f32) -> (f32, f32) {
    let a2 = a * a;
    // Nested (Horner) form; the constants' reciprocals fold at compile time.
    let term = |n: f32, rest: f32| 1.0 - a2 * (1.0 / n) * rest;
    let sin = a * term(6.0, term(20.0, term(42.0, term(72.0, 1.0))));
    let cos = term(2.0, term(12.0, term(30.0, term(56.0, term(90.0, 1.0)))));
    (cos, sin)
}

/// A cosine-weighted direction about +Z (Malley's method); pdf = cos(theta) / pi.
pub fn cosine_hemisphere(u: Vec2) -> Vec3A {
    let d = concentric_disk(u);
    Vec3A::new(d.x, d.y, (1.0 - d.length_squared()).max(0.0).sqrt())
}

/// Uniform barycentrics (b1, b2) on a triangle (pbrt-v4's `SampleUniformTriangle`).
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    let (b0, b1) = if u.x < u.y {
        let b0 = u.x / 2.0;
        (b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        (u.x - b1, b1)
    };
    // Returned as (b1, b2) for the (1 - b1 - b2) v0 + b1 v1 + b2 v2 convention.
    Vec2::new(b1, 1.0 - b0 - b1)
}

/// The power heuristic with beta = 2 (Veach 1997, section 9.2) for a sample from a
/// strategy with pdf `f` against another with pdf `g` (one sample each).
pub fn power_heuristic(f: f32, g: f32) -> f32 {
    let (f2, g2) = (f * f, g * g);
    if f2.is_infinite() {
        return 1.0;
    }
    if f2 + g2 == 0.0 { 0.0 } else { f2 / (f2 + g2) }
}

/// An orthonormal basis (t, b, n) around unit `n` (Duff et al. 2017, "Building an
/// Orthonormal Basis, Revisited").
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub tangent: Vec3A,
    pub bitangent: Vec3A,
    pub normal: Vec3A,
}

impl Frame {
    pub fn from_normal(normal: Vec3A) -> Frame {
        let sign = 1f32.copysign(normal.z);
        let a = -1.0 / (sign + normal.z);
        let b = normal.x * normal.y * a;
        Frame {
            tangent: Vec3A::new(
                1.0 + sign * normal.x * normal.x * a,
                sign * b,
                -sign * normal.x,
            ),
            bitangent: Vec3A::new(b, sign + normal.y * normal.y * a, -normal.y),
            normal,
        }
    }

    pub fn to_local(&self, v: Vec3A) -> Vec3A {
        Vec3A::new(
            v.dot(self.tangent),
            v.dot(self.bitangent),
            v.dot(self.normal),
        )
    }

    pub fn to_world(&self, v: Vec3A) -> Vec3A {
        self.tangent * v.x + self.bitangent * v.y + self.normal * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_turn_cos_and_sin_agree_with_libm() {
        let steps = 100_000;
        for i in 0..=steps {
            let a = std::f32::consts::FRAC_PI_4 * (2.0 * i as f32 / steps as f32 - 1.0);
            let (cos, sin) = cos_sin_quarter(a);
            assert!(
                (cos - a.cos()).abs() <= 2e-7,
                "cos {a}: {cos} against {}",
                a.cos()
            );
            assert!(
                (sin - a.sin()).abs() <= 2e-7,
                "sin {a}: {sin} against {}",
                a.sin()
            );
        }
    }

    /// Shirley & Chiu's map as they give it, angle and all, through libm.
    #[test]
    fn the_concentric_map_is_shirley_and_chius() {
        use std::f32::consts::{FRAC_PI_2, FRAC_PI_4};
        let n = 300;
        for i in 0..n * n {
            let u = Vec2::new(
                ((i % n) as f32 + 0.5) / n as f32,
                ((i / n) as f32 + 0.5) / n as f32,
            );
            let offset = u * 2.0 - Vec2::ONE;
            let (radius, theta) = if offset.x.abs() > offset.y.abs() {
                (offset.x, FRAC_PI_4 * (offset.y / offset.x))
            } else {
                (offset.y, FRAC_PI_2 - FRAC_PI_4 * (offset.x / offset.y))
            };
            let expected = radius * Vec2::new(theta.cos(), theta.sin());
            let p = concentric_disk(u);
            assert!(
                (p - expected).abs().max_element() <= 3e-7,
                "{u}: {p} against {expected}"
            );
        }
    }

    #[test]
    fn mis_weights_of_two_strategies_sum_to_one() {
        for (a, b) in [(1.0f32, 1.0f32), (0.3, 7.0), (1e-6, 5.0), (12.0, 0.0)] {
            assert!((power_heuristic(a, b) + power_heuristic(b, a) - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn uniform_triangle_stays_inside_and_averages_to_the_centroid() {
        let mut mean = Vec2::ZERO;
        let n = 64;
        for i in 0..n {
            for j in 0..n {
                let b = uniform_triangle(Vec2::new(
                    (i as f32 + 0.5) / n as f32,
                    (j as f32 + 0.5) / n as f32,
                ));
                assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
                mean += b;
            }
        }
        mean /= (n * n) as f32;
        assert!((mean - Vec2::splat(1.0 / 3.0)).length() < 1e-3, "{mean}");
    }

    #[test]
    fn frames_are_orthonormal() {
        for n in [
            Vec3A::Z,
            Vec3A::NEG_Z,
            Vec3A::new(0.3, -0.5, 0.8).normalize(),
            Vec3A::X,
        ] {
            let f = Frame::from_normal(n);
            assert!(f.tangent.dot(f.bitangent).abs() < 1e-6 && f.tangent.dot(n).abs() < 1e-6);
            assert!((f.tangent.cross(f.bitangent) - n).length() < 1e-5);
            let v = Vec3A::new(0.2, 0.4, -0.1);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        }
    }
}
