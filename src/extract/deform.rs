//! Frame step `extract`, timed as "animation": meshes that change shape, read from the ECS
//! (`Skin`, `MorphWeights`, `Deformer` on `MeshNode`s) and written into their own BLAS's
//! geometry, which the `accel` step then refits.
//!
//! Per displayed frame, after `extract_scene`:
//! 1. change detection, per deforming mesh entity: skinned meshes re-pose when a
//!    `Transform` of any joint, or of a node between the joints and the entity's root,
//!    changed since the last frame; morphing meshes when their `MorphWeights` changed;
//!    deformed meshes when their `Deformer` clock moved. Everything else is skipped;
//! 2. deformation, in parallel over meshes and over each mesh's vertices, written straight
//!    into the mesh's BLAS geometry: morph targets (glTF: weighted position and normal
//!    deltas), then the procedural deformer, then linear blend skinning;
//! 3. each deformed BLAS is listed for the `accel` step (`RenderState::refit`), which
//!    refits it in parallel with the others (`Blas::refit_geometry`, which rebuilds
//!    instead when refitting has let the tree decay); the instances' emissive triangles
//!    are marked to follow, and the TLAS stale.
//!
//! Skinning is linear blend skinning as glTF specifies it: v' = sum_i w_i J_i IBM_i v over
//! every JOINTS_n/WEIGHTS_n set, where J_i is joint i's world matrix and IBM_i its inverse
//! bind matrix. Gloam evaluates it in the space of the level entity's root (the instance's
//! object space) so that moving a warden moves only its instance, not its vertices. Normals
//! are transformed by the cofactor matrix of the blended 3x3 (the inverse transpose up to a
//! positive scale) and renormalised, which stays right under non-uniform joint scale.

use std::collections::HashMap;
use std::sync::Arc;

use bevy_ecs::prelude::*;
use glam::{Mat3A, Mat4, Vec3, Vec3A};
use rayon::prelude::*;

use super::RenderState;
use crate::accel::Blas;
use crate::game::{Deformer, GlobalTransform, MeshNode, MorphWeights, Skin, Transform};
use crate::profile::{Stage, StageTimes, since};
use crate::scene::AssetKey;
use crate::scene::gltf_import::MAX_COORDINATE;
use crate::scene::level::DeformerDef;
use crate::scene::model::Asset;

/// A mesh's rest geometry and deformation data, in the vertex order of
/// `extract::mesh_geometry` (which gives the rest positions, normals and triangles, so the
/// order is the BLAS's by construction): shared by every instance of the mesh.
#[derive(Clone, Debug, Default)]
pub struct DeformSource {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    /// Triangles (for recomputing normals after a procedural deformer).
    pub triangles: Vec<[u32; 3]>,
    /// Per vertex, up to `influences_per_vertex` (joint, weight) pairs, flattened; empty
    /// for unskinned meshes. Zero weights are dropped; unused slots hold weight 0.
    pub joints: Vec<u16>,
    pub weights: Vec<f32>,
    pub influences_per_vertex: usize,
    /// Per morph target, per vertex position and normal deltas (normals may be empty).
    pub morph_positions: Vec<Vec<Vec3>>,
    pub morph_normals: Vec<Vec<Vec3>>,
    /// Half the diagonal of the rest bounds (the wobble deformer's size).
    pub radius: f32,
}

impl DeformSource {
    /// Gathers mesh `mesh` of `asset`. Import has checked that every joint index is inside
    /// the node's skin and that all primitives have the same number of morph targets.
    pub fn from_mesh(asset: &Asset, mesh: usize) -> DeformSource {
        let primitives = &asset.meshes[mesh].primitives;
        let targets = primitives.first().map_or(0, |p| p.morph_targets.len());
        let sets = primitives
            .iter()
            .map(|p| p.skin_influences.len())
            .max()
            .unwrap_or(0);
        let rest = super::mesh_geometry(asset, mesh, 0);
        let mut source = DeformSource {
            positions: rest.positions,
            normals: rest.normals,
            triangles: rest.triangles,
            influences_per_vertex: 4 * sets,
            morph_positions: vec![Vec::new(); targets],
            morph_normals: vec![Vec::new(); targets],
            ..DeformSource::default()
        };
        for primitive in primitives {
            let count = primitive.positions.len();
            for vertex in 0..count {
                for slot in 0..sets {
                    let set = primitive.skin_influences.get(slot);
                    for k in 0..4 {
                        let (joint, weight) = set.map_or((0, 0.0), |set| {
                            (set.joints[vertex][k], set.weights[vertex][k])
                        });
                        source.joints.push(joint);
                        source.weights.push(weight);
                    }
                }
            }
            for (target, morph) in primitive.morph_targets.iter().enumerate() {
                let deltas = |values: &Vec<Vec3>| {
                    if values.is_empty() {
                        vec![Vec3::ZERO; count]
                    } else {
                        values.clone()
                    }
                };
                source.morph_positions[target].extend(deltas(&morph.positions));
                source.morph_normals[target].extend(deltas(&morph.normals));
            }
        }
        if sets > 0 {
            source.normalise_weights();
        }
        let (min, max) = source
            .positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        source.radius = ((max - min).length() * 0.5).max(1e-6);
        source
    }

    /// glTF asks exporters to normalise weights but files drift (quantised weights sum to
    /// 0.996...); dividing by the sum keeps vertices from shrinking toward the root. A vertex
    /// with no weight at all follows joint 0.
    fn normalise_weights(&mut self) {
        let per_vertex = self.influences_per_vertex;
        for weights in self.weights.chunks_exact_mut(per_vertex) {
            let sum: f32 = weights.iter().sum();
            if sum > 0.0 && sum.is_finite() {
                weights.iter_mut().for_each(|w| *w /= sum);
            } else {
                weights.fill(0.0);
                weights[0] = 1.0;
            }
        }
        // Joints with zero weight point at joint 0 so they cost nothing and index safely.
        for (joint, &weight) in self.joints.iter_mut().zip(&self.weights) {
            if weight == 0.0 {
                *joint = 0;
            }
        }
    }

    pub fn is_skinned(&self) -> bool {
        self.influences_per_vertex > 0
    }
}

/// The pose a mesh is deformed into this frame.
#[derive(Clone, Copy, Debug)]
pub struct Pose<'a> {
    /// Object-space skinning matrix per joint (root-from-joint x inverse bind), or empty.
    pub joint_matrices: &'a [Mat4],
    /// Morph target weights (empty: rest shape).
    pub morph_weights: &'a [f32],
    /// A procedural deformer and its clock.
    pub deformer: Option<(&'a DeformerDef, f64)>,
}

/// Vertices per parallel task: big enough that rayon's per-task cost (~1 us) stays small
/// next to 2,048 vertices x ~60 ns of skinning.
const VERTICES_PER_TASK: usize = 2048;

/// Writes `source` deformed by `pose` into `positions` and `normals` (each as long as the
/// source's vertices; import gives every primitive normals).
pub fn deform(source: &DeformSource, pose: &Pose, positions: &mut [Vec3], normals: &mut [Vec3]) {
    assert!(
        positions.len() == source.positions.len() && normals.len() == source.normals.len(),
        "deform: output buffers must match the source's {} vertices",
        source.positions.len()
    );
    let morphs: Vec<(usize, f32)> = pose
        .morph_weights
        .iter()
        .copied()
        .enumerate()
        .filter(|&(target, w)| w != 0.0 && target < source.morph_positions.len())
        .collect();
    let skin = source.is_skinned() && !pose.joint_matrices.is_empty();
    let per_vertex = source.influences_per_vertex;
    // Joints as affine column sets: blending 12 floats per influence instead of a Mat4's 16.
    let joints: Vec<[Vec3A; 4]> = pose
        .joint_matrices
        .iter()
        .map(|m| {
            [m.x_axis, m.y_axis, m.z_axis, m.w_axis].map(|column| Vec3A::from(column.truncate()))
        })
        .collect();

    // 1. Rest shape plus morph targets, then the deformer's offset along the normal.
    for_each_vertex(positions, normals, |v, position, normal| {
        let mut p = source.positions[v];
        let mut n = source.normals[v];
        for &(target, w) in &morphs {
            p += w * source.morph_positions[target][v];
            n += w * source.morph_normals[target][v];
        }
        if let Some((deformer, time)) = pose.deformer {
            p += n.normalize_or_zero() * deformer_offset(deformer, time, p, source.radius);
        }
        *position = p;
        *normal = n;
    });
    if pose.deformer.is_some() {
        recompute_normals(positions, &source.triangles, normals);
    }

    // 2. Linear blend skinning in place (or just renormalise morphed normals).
    for_each_vertex(positions, normals, |v, position, normal| {
        skin_vertex(
            source,
            &joints,
            skin.then_some(per_vertex),
            v,
            position,
            normal,
        );
        // Rule: what leaves here feeds the BVH refit, whose build asserts every box is a
        // number: a pose that throws a vertex out of range (joints scaled 1e6 at every level
        // of a chain overflow f32) leaves that vertex at rest instead.
        if !(position.is_finite() && position.abs().max_element() <= MAX_COORDINATE) {
            *position = source.positions[v];
            *normal = source.normals[v];
        }
    });
}

/// Linear blend skinning of vertex `v` in place with `influences` joints a vertex (or,
/// unskinned, just the renormalised normal).
fn skin_vertex(
    source: &DeformSource,
    joints: &[[Vec3A; 4]],
    influences: Option<usize>,
    v: usize,
    position: &mut Vec3,
    normal: &mut Vec3,
) {
    let Some(per_vertex) = influences else {
        *normal = normal.normalize_or(Vec3::Y);
        return;
    };
    let range = v * per_vertex..(v + 1) * per_vertex;
    let mut blended = [Vec3A::ZERO; 4];
    for (&joint, &weight) in source.joints[range.clone()]
        .iter()
        .zip(&source.weights[range])
    {
        if weight != 0.0 {
            let columns = &joints[joint as usize];
            for (sum, column) in blended.iter_mut().zip(columns) {
                *sum += *column * weight;
            }
        }
    }
    let [x, y, z, translation] = blended;
    let p = Vec3A::from(*position);
    *position = Vec3::from(x * p.x + y * p.y + z * p.z + translation);
    *normal = Vec3::from(
        normal_matrix(x, y, z)
            .mul_vec3a(Vec3A::from(*normal))
            .normalize_or(Vec3A::Y),
    );
}

/// Calls `visit(vertex index, position, normal)` for every vertex, in parallel chunks.
fn for_each_vertex(
    positions: &mut [Vec3],
    normals: &mut [Vec3],
    visit: impl Fn(usize, &mut Vec3, &mut Vec3) + Sync,
) {
    positions
        .par_chunks_mut(VERTICES_PER_TASK)
        .zip(normals.par_chunks_mut(VERTICES_PER_TASK))
        .enumerate()
        .for_each(|(chunk, (positions, normals))| {
            let first = chunk * VERTICES_PER_TASK;
            for (offset, (position, normal)) in positions.iter_mut().zip(normals).enumerate() {
                visit(first + offset, position, normal);
            }
        });
}

/// The cofactor matrix of the 3x3 with columns `c0`, `c1`, `c2`, sign-corrected: the
/// inverse transpose times |det|, so it turns normals the right way under any invertible
/// (even mirroring) matrix without a division.
#[inline]
fn normal_matrix(c0: Vec3A, c1: Vec3A, c2: Vec3A) -> Mat3A {
    let cofactor = Mat3A::from_cols(c1.cross(c2), c2.cross(c0), c0.cross(c1));
    if c0.dot(c1.cross(c2)) < 0.0 {
        -cofactor
    } else {
        cofactor
    }
}

/// A procedural deformer's displacement (metres along the rest normal) at rest point `p`.
pub fn deformer_offset(deformer: &DeformerDef, time: f64, p: Vec3, radius: f32) -> f32 {
    use std::f64::consts::TAU;
    match *deformer {
        DeformerDef::Wave {
            amplitude,
            wavelength,
            period,
            direction,
        } => {
            let along = direction.normalize_or(Vec3::X).dot(p) as f64;
            let phase = TAU * (along / wavelength as f64 - time / period as f64);
            amplitude * phase.sin() as f32
        }
        DeformerDef::Wobble { amplitude, period } => {
            let ripple = 3.0 * (p.x + p.y + p.z) as f64 / radius as f64;
            let phase = TAU * time / period as f64 + ripple;
            amplitude * phase.sin() as f32
        }
    }
}

/// Area-weighted vertex normals of the triangles (each vertex's normal is the normalised
/// sum of its triangles' cross products), for shapes a deformer moved.
pub fn recompute_normals(positions: &[Vec3], triangles: &[[u32; 3]], normals: &mut [Vec3]) {
    normals.fill(Vec3::ZERO);
    for triangle in triangles {
        let [a, b, c] = triangle.map(|i| positions[i as usize]);
        let cross = (b - a).cross(c - a);
        for &i in triangle {
            normals[i as usize] += cross;
        }
    }
    for n in normals.iter_mut() {
        *n = n.normalize_or(Vec3::Y);
    }
}

/// What extract keeps for the deforming mesh nodes: each mesh's source data (shared by
/// its instances), and per node its BLAS and whether it has been posed.
#[derive(Default)]
pub struct DeformCache {
    sources: HashMap<(AssetKey, usize), Arc<DeformSource>>,
    nodes: HashMap<Entity, DeformedMesh>,
}

impl DeformCache {
    /// Follows deforming node `entity` (mesh `mesh` of `asset`) into `blas`; a node
    /// already followed keeps its state.
    pub fn track(&mut self, entity: Entity, asset: &Arc<Asset>, mesh: usize, blas: u32) {
        if self.nodes.contains_key(&entity) {
            return;
        }
        let source = self
            .sources
            .entry((AssetKey(Arc::clone(asset)), mesh))
            .or_insert_with(|| Arc::new(DeformSource::from_mesh(asset, mesh)))
            .clone();
        self.nodes.insert(
            entity,
            DeformedMesh {
                blas,
                source,
                posed: false,
                joint_matrices: Vec::new(),
            },
        );
    }

    /// Stops following a despawned node.
    pub fn forget(&mut self, entity: Entity) {
        self.nodes.remove(&entity);
    }
}

/// A deforming mesh node as extract follows it.
struct DeformedMesh {
    /// Its own (deforming) BLAS in the accel scene.
    blas: u32,
    source: Arc<DeformSource>,
    /// False until the first deformation (the import's rest shape is not yet posed).
    posed: bool,
    /// This frame's skinning matrices (reused allocation).
    joint_matrices: Vec<Mat4>,
}

/// What deformation did in the last frame.
#[derive(Resource, Default, Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeformStats {
    /// Deforming meshes whose shape changed this frame.
    pub deformed: u32,
    /// ... of which refit in place,
    pub refits: u32,
    /// ... and rebuilt because refitting had let their tree decay.
    pub rebuilds: u32,
    /// Deforming meshes left alone: nothing that shapes them changed.
    pub skipped: u32,
    /// Vertices written.
    pub vertices: u64,
}

/// A mesh node and what may shape it, with change ticks.
type DeformingNode<'a> = (
    Entity,
    &'a MeshNode,
    Option<&'a Skin>,
    Option<Ref<'a, MorphWeights>>,
    Option<Ref<'a, Deformer>>,
);

/// A node whose shape changed this frame: its skin, morph weights and deformer clock.
type ChangedNode<'a> = (
    Entity,
    Option<&'a Skin>,
    Option<&'a [f32]>,
    Option<(&'a DeformerDef, f64)>,
);

/// Extract: deform what changed, straight into its BLAS's geometry, and leave the BLAS
/// for accel to refit (`RenderState::refit`), the TLAS flagged stale.
pub fn deform_meshes(
    meshes: Query<DeformingNode>,
    transforms: Query<(Ref<Transform>, &GlobalTransform)>,
    mut state: ResMut<RenderState>,
    mut stats: ResMut<DeformStats>,
    mut times: ResMut<StageTimes>,
) {
    let start = std::time::Instant::now();
    profiling::scope!("animation.deform");
    *stats = DeformStats::default();
    let state = &mut *state;

    // 1. Change detection and this frame's inputs.
    struct Job<'a> {
        entity: Entity,
        blas: u32,
        source: Arc<DeformSource>,
        joint_matrices: &'a [Mat4],
        weights: Option<&'a [f32]>,
        deformer: Option<(&'a DeformerDef, f64)>,
    }
    let mut changed_nodes: Vec<ChangedNode> = Vec::new();
    for (entity, node, skin, weights, deformer) in &meshes {
        if !node.deforms {
            continue;
        }
        let Some(followed) = state.deform.nodes.get(&entity) else {
            continue;
        };
        let skin_changed = skin.is_some_and(|skin| {
            skin.watched
                .iter()
                .any(|&e| transforms.get(e).is_ok_and(|(t, _)| t.is_changed()))
        });
        let changed = !followed.posed
            || skin_changed
            || weights.as_ref().is_some_and(|w| w.is_changed())
            || deformer.as_ref().is_some_and(|d| d.is_changed());
        if !changed {
            stats.skipped += 1;
            continue;
        }
        changed_nodes.push((
            entity,
            skin,
            weights.map(|w| w.into_inner().0.as_slice()),
            deformer.map(|d| {
                let d = d.into_inner();
                (&d.kind, d.time)
            }),
        ));
    }
    // Skinning matrices, in the space of the instance (the skin's root entity).
    for (entity, skin, _, _) in &changed_nodes {
        let Some(followed) = state.deform.nodes.get_mut(entity) else {
            continue;
        };
        followed.posed = true;
        followed.joint_matrices.clear();
        if let Some(skin) = skin {
            let object_from_world = transforms
                .get(skin.root)
                .map_or(Mat4::IDENTITY, |(_, g)| Mat4::from(g.0.inverse()));
            for (&joint, inverse_bind) in skin.joints.iter().zip(&skin.inverse_bind_matrices) {
                let world_from_joint = transforms
                    .get(joint)
                    .map_or(Mat4::IDENTITY, |(_, g)| Mat4::from(g.0));
                followed
                    .joint_matrices
                    .push(object_from_world * world_from_joint * *inverse_bind);
            }
        }
    }
    let jobs: Vec<Job> = changed_nodes
        .iter()
        .filter_map(|&(entity, _, weights, deformer)| {
            let followed = state.deform.nodes.get(&entity)?;
            Some(Job {
                entity,
                blas: followed.blas,
                source: Arc::clone(&followed.source),
                joint_matrices: &followed.joint_matrices,
                weights,
                deformer,
            })
        })
        .collect();
    if jobs.is_empty() {
        times.add(Stage::Animation, since(start));
        return;
    }

    // Pair each job with its own BLAS (each deforming mesh has a distinct one).
    let mut blases: Vec<Option<&mut Blas>> =
        state.scene.accel.blases.iter_mut().map(Some).collect();
    let mut work: Vec<(&Job, &mut Blas)> = Vec::with_capacity(jobs.len());
    for job in &jobs {
        if let Some(blas) = blases.get_mut(job.blas as usize).and_then(Option::take) {
            work.push((job, blas));
        }
    }

    // 2. Deform, straight into the BLAS geometry (parallel over meshes and vertices).
    work.par_iter_mut().for_each(|(job, blas)| {
        let pose = Pose {
            joint_matrices: job.joint_matrices,
            morph_weights: job.weights.unwrap_or(&[]),
            deformer: job.deformer,
        };
        let geometry = &mut blas.geometry;
        deform(
            &job.source,
            &pose,
            &mut geometry.positions,
            &mut geometry.normals,
        );
    });
    stats.deformed = work.len() as u32;
    stats.vertices = work
        .iter()
        .map(|(job, _)| job.source.positions.len() as u64)
        .sum();
    times.add(Stage::Animation, since(start));

    // 3. Their BLASes are refit by accel; their emitters move with them, and the TLAS
    // must see their new bounds.
    let deformed: Vec<(Entity, u32)> = work.iter().map(|(job, _)| (job.entity, job.blas)).collect();
    drop(work);
    drop(blases);
    for (entity, blas) in deformed {
        state.refit.push(blas);
        if let Some(&instance) = state.instance_of.get(&entity)
            && let Some(flag) = state.moved.get_mut(instance as usize)
        {
            *flag = true;
        }
    }
    state.tlas_stale = true;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Found by fuzzing: a joint chain whose keyframes scale past f32's range gave NaN
    /// positions, and the deformed mesh's BVH rebuild panicked on them. Such a vertex now
    /// stays at rest; the others follow their joints.
    #[test]
    fn a_vertex_posed_out_of_range_stays_at_rest() {
        let source = DeformSource {
            positions: vec![Vec3::X, Vec3::Y],
            normals: vec![Vec3::Z, Vec3::Z],
            joints: vec![0, 1],
            weights: vec![1.0, 1.0],
            influences_per_vertex: 1,
            ..DeformSource::default()
        };
        let joint_matrices = [
            Mat4::from_translation(Vec3::new(0.0, 0.0, 2.0)),
            Mat4::from_scale(Vec3::splat(f32::INFINITY)),
        ];
        let pose = Pose {
            joint_matrices: &joint_matrices,
            morph_weights: &[],
            deformer: None,
        };
        let (mut positions, mut normals) = (vec![Vec3::ZERO; 2], vec![Vec3::ZERO; 2]);
        deform(&source, &pose, &mut positions, &mut normals);
        assert_eq!(positions, [Vec3::new(1.0, 0.0, 2.0), Vec3::Y]);
        assert_eq!(normals, [Vec3::Z, Vec3::Z]);
    }
}
