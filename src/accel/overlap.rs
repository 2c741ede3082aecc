//! Frame step `accel`, for the simulation: which surfaces come within reach of a sphere.
//!
//! A character controller resolves its capsule against the level as a stack of spheres:
//! each sphere asks `AccelScene::sphere_contacts` for every triangle within its radius, with
//! the closest point on it, and pushes itself out along the direction from that point
//! (the collide-and-slide scheme of Fauerby 2003, "Improved Collision detection and
//! Response", with overlap tests in place of swept ones: moved in steps shorter than the
//! radius, a sphere cannot pass through a surface between two tests).
//!
//! The query walks the TLAS and each BLAS's BVH2 with the sphere's box (obvhs's
//! `aabb_traverse`; the box carried into object space for instances, so non-uniform scale
//! and rotation stay exact), then tests each candidate triangle exactly in world space
//! (closest point on a triangle: Ericson 2005, "Real-Time Collision Detection", 5.1.5).
//! Meshes that deform test every triangle (their BVH2 lags the pose; the game's deforming
//! meshes are wardens and banners of a few thousand triangles). Static batches report
//! their members' own (instance, triangle), as every other query does.

use glam::{Affine3A, Vec3A};
use obvhs::aabb::Aabb;

use super::InstanceMask;
use super::blas::{Blas, BlasKind};
use super::tlas::AccelScene;

/// A surface point within reach of a query sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// The closest point of the triangle to the sphere's centre, in world space.
    pub point: Vec3A,
    /// Unit direction from `point` to the centre (the way out); the triangle's own normal,
    /// facing the centre, when the centre lies on it.
    pub normal: Vec3A,
    /// Distance from the centre to `point` (less than the radius).
    pub distance: f32,
    /// Index into `AccelScene::instances`.
    pub instance: u32,
    /// Triangle index in the instance's mesh.
    pub triangle: u32,
}

/// The point of triangle (a, b, c) closest to `p` (Ericson 2005, 5.1.5: the Voronoi
/// regions of the vertices, then the edges, then the face).
pub fn closest_point_on_triangle(p: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> Vec3A {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denominator = 1.0 / (va + vb + vc);
    a + ab * (vb * denominator) + ac * (vc * denominator)
}

/// The contact of world-space triangle `vertices` with the sphere, if it reaches it.
fn contact(vertices: [Vec3A; 3], center: Vec3A, radius: f32) -> Option<(Vec3A, Vec3A, f32)> {
    let [a, b, c] = vertices;
    let point = closest_point_on_triangle(center, a, b, c);
    let offset = center - point;
    let distance = offset.length();
    // NaN distances (degenerate input) fail this test too.
    if distance.partial_cmp(&radius) != Some(std::cmp::Ordering::Less) {
        return None;
    }
    let normal = if distance > 1e-6 {
        offset / distance
    } else {
        let face = (b - a).cross(c - a).normalize_or_zero();
        if face.dot(offset) < 0.0 { -face } else { face }
    };
    (normal != Vec3A::ZERO).then_some((point, normal, distance))
}

/// The box around `aabb` after `transform` (its eight corners carried over).
fn transformed_box(aabb: &Aabb, transform: &Affine3A) -> Aabb {
    let mut out = Aabb::empty();
    for corner in 0..8 {
        let point = Vec3A::new(
            if corner & 1 == 0 {
                aabb.min.x
            } else {
                aabb.max.x
            },
            if corner & 2 == 0 {
                aabb.min.y
            } else {
                aabb.max.y
            },
            if corner & 4 == 0 {
                aabb.min.z
            } else {
                aabb.max.z
            },
        );
        out.extend(transform.transform_point3a(point));
    }
    out
}

impl Blas {
    /// Calls `visit(triangle)` for every triangle whose box may overlap `aabb` (object
    /// space): through the BVH2 for meshes that keep their shape, all of them for meshes
    /// that deform.
    fn triangles_near(&self, aabb: &Aabb, mut visit: impl FnMut(u32)) {
        if self.kind == BlasKind::Deforming {
            (0..self.triangle_count() as u32).for_each(visit);
            return;
        }
        self.bvh.aabb_traverse(*aabb, |bvh, node| {
            let node = &bvh.nodes[node as usize];
            let first = node.first_index as usize;
            for &triangle in &self.ordered_ids[first..first + node.prim_count as usize] {
                visit(triangle);
            }
            true
        });
    }
}

impl AccelScene {
    /// Every triangle of the instances sharing a bit with `mask` that comes closer than
    /// `radius` to `center`, appended to `out` (see the module doc).
    pub fn sphere_contacts(
        &self,
        center: Vec3A,
        radius: f32,
        mask: InstanceMask,
        out: &mut Vec<Contact>,
    ) {
        let reach = Vec3A::splat(radius);
        let query = Aabb::new(center - reach, center + reach);
        self.visit_boxes(&query, |entry| match entry {
            Entry::Instance(index) => {
                let instance = &self.instances()[index as usize];
                if !instance.mask.intersects(mask) {
                    return;
                }
                let blas = &self.blases[instance.blas as usize];
                let to_world = instance.world_from_object();
                let local = transformed_box(&query, &instance.object_from_world());
                blas.triangles_near(&local, |triangle| {
                    let vertices = blas
                        .geometry
                        .triangle_vertices(triangle as usize)
                        .map(|v| to_world.transform_point3a(v));
                    if let Some((point, normal, distance)) = contact(vertices, center, radius) {
                        out.push(Contact {
                            point,
                            normal,
                            distance,
                            instance: index,
                            triangle,
                        });
                    }
                });
            }
            Entry::Batch(blas, members) => {
                if !members.mask().intersects(mask) {
                    return;
                }
                blas.triangles_near(&query, |triangle| {
                    let vertices = blas.geometry.triangle_vertices(triangle as usize);
                    if let Some((point, normal, distance)) = contact(vertices, center, radius) {
                        let (instance, triangle) = members.member_of(triangle);
                        out.push(Contact {
                            point,
                            normal,
                            distance,
                            instance,
                            triangle,
                        });
                    }
                });
            }
        });
    }
}

/// What a TLAS leaf the query box reaches stands for.
pub(super) enum Entry<'a> {
    Instance(u32),
    /// A static batch's world-space BLAS and the batch (to name members and read its mask).
    Batch(&'a Blas, &'a super::batch::StaticBatch),
}
