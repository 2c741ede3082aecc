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
    let (radius, theta) = if offset.x.abs() > offset.y.abs() {
        (
            offset.x,
            std::f32::consts::FRAC_PI_4 * (offset.y / offset.x),
        )
    } else {
        (
            offset.y,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (offset.x / offset.y),
        )
    };
    radius * Vec2::new(theta.cos(), theta.sin())
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
