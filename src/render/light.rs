//! Frame step `render`: the lights next event estimation samples.
//!
//! Every emissive triangle and every KHR punctual light is one entry of a `LightSet`. A
//! light is picked per shading point in two steps. First the punctual lights as one group,
//! or the emissive triangles, with probability proportional to their estimated power.
//! Within the group, a punctual light is picked in proportion to the irradiance it would
//! give the shading point unshadowed (I cos-falloff / d^2, or E): the importance that
//! light trees estimate per cluster (Conty Estevez and Kulla 2018, "Importance Sampling of
//! Many Lights with Adaptive Tree Splitting"), exact here for lights that are points. Inside
//! a lamp's cone that lamp is then picked for almost every pixel, so at one sample a pixel
//! its pool is lit whole rather than in scattered pixels. A region's `LightReach` names
//! the lamps whose cones may reach it, so the real-time render's dark tiles skip the
//! weighing (it gives every other lamp exactly 0 there). A triangle is picked through an
//! alias table over power (Walker 1977; Vose 1991), then a point on it uniformly by area,
//! and the area pdf is converted to solid angle: pdf = p_pick * d^2 / (|cos theta_light| A).
//! The sky is not sampled here: bounce rays that leave the scene pick it up.
//!
//! The punctual lights are weighed eight at a time in SIMD lanes (`PunctualGroup`): on
//! the-gallery, 17% fewer instructions per path vertex, the same bits. Skipping
//! the weighing where no lamp's cone can reach (each tile asks `LightSet::reach` once for
//! the box around its first hits, and the other lamps weigh exactly 0 there, so the picks
//! are the same) made first-light's shade phase 9% faster.

use std::collections::HashMap;

use glam::{Vec2, Vec3, Vec3A};

use super::sampling::uniform_triangle;

/// One light.
#[derive(Clone, Debug)]
pub enum Light {
    /// A triangle of an emissive surface, in world space.
    Triangle {
        vertices: [Vec3A; 3],
        /// UVs at the vertices, for emissive textures.
        uvs: [Vec2; 3],
        /// Unit normal of the emitting (front) side.
        normal: Vec3A,
        area: f32,
        /// Index into `RenderScene::materials` (emission is read there at the sampled UV).
        material: u32,
        double_sided: bool,
    },
    /// Radiant intensity `intensity` (W/sr per channel) in every direction.
    Point { position: Vec3A, intensity: Vec3 },
    /// As a point light inside a cone around `direction`, with glTF's smooth falloff.
    Spot {
        position: Vec3A,
        direction: Vec3A,
        intensity: Vec3,
        cos_inner: f32,
        cos_outer: f32,
    },
    /// Irradiance `irradiance` (W/m^2) arriving from the direction opposite `direction`.
    Directional { direction: Vec3A, irradiance: Vec3 },
}

/// The most punctual lights picked by their irradiance at the shading point, which costs
/// one evaluation per light per sample; a set with more picks them by power instead (the
/// alias table), as a light tree would be needed to keep such a pick cheap.
const SPATIAL_PICK_MAX: usize = 32;

/// Beside a dominant light (`LightSet::sample_beside_dominant`), the other punctual lights
/// are always sampled once their irradiance adds up to this fraction of the dominant one's,
/// and below it with probability in proportion.
const OTHERS_ROULETTE: f32 = 0.25;

impl Light {
    /// Light `index` (of its set, picked with probability `pick`) as seen from `point`:
    /// a direction towards it, the point it comes from and what arrives, with the pdf of
    /// having sampled it (`pick` times the solid-angle pdf of point `u` on an area light;
    /// `pick` for a delta light). None when nothing arrives. `LightSet::sample` draws
    /// lights this way, and the game's exposure measures them with the same definitions
    /// (`pick` 1, fixed `u`).
    pub fn sample(
        &self,
        index: u32,
        pick: f32,
        point: Vec3A,
        u: Vec2,
        emission: impl Fn(u32, Vec2) -> Vec3,
    ) -> Option<LightSample> {
        match self {
            Light::Triangle {
                vertices,
                uvs,
                normal,
                area,
                material,
                double_sided,
            } => {
                let b = uniform_triangle(u);
                let on_light =
                    vertices[0] * (1.0 - b.x - b.y) + vertices[1] * b.x + vertices[2] * b.y;
                let offset = on_light - point;
                let distance2 = offset.length_squared();
                if distance2 <= 0.0 {
                    return None;
                }
                let wi = offset / distance2.sqrt();
                let cos_light = -normal.dot(wi);
                if cos_light <= 0.0 && !double_sided {
                    return None; // the back of a one-sided emitter
                }
                let uv = uvs[0] * (1.0 - b.x - b.y) + uvs[1] * b.x + uvs[2] * b.y;
                let pdf = pick * distance2 / (cos_light.abs() * area);
                (pdf.is_finite() && pdf > 0.0).then(|| LightSample {
                    wi,
                    point: on_light,
                    radiance: emission(*material, uv),
                    pdf,
                    is_delta: false,
                    light: index,
                })
            }
            Light::Point {
                position,
                intensity,
            } => {
                let offset = *position - point;
                let distance2 = offset.length_squared().max(f32::MIN_POSITIVE);
                Some(LightSample {
                    wi: offset / distance2.sqrt(),
                    point: *position,
                    radiance: *intensity / distance2,
                    pdf: pick,
                    is_delta: true,
                    light: index,
                })
            }
            Light::Spot {
                position,
                direction,
                intensity,
                cos_inner,
                cos_outer,
            } => {
                let offset = *position - point;
                let distance2 = offset.length_squared().max(f32::MIN_POSITIVE);
                let wi = offset / distance2.sqrt();
                let attenuation = spot_falloff(direction.dot(-wi), *cos_inner, *cos_outer);
                (attenuation > 0.0).then(|| LightSample {
                    wi,
                    point: *position,
                    radiance: *intensity * (attenuation / distance2),
                    pdf: pick,
                    is_delta: true,
                    light: index,
                })
            }
            Light::Directional {
                direction,
                irradiance,
            } => Some(LightSample {
                wi: -*direction,
                point: point - *direction * 1e7,
                radiance: *irradiance,
                pdf: pick,
                is_delta: true,
                light: index,
            }),
        }
    }
}

/// A sampled light direction as seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3A,
    /// The point on the light (for the shadow ray); at infinity for directional lights.
    pub point: Vec3A,
    /// Incident radiance for area lights; for delta lights, the irradiance-like quantity
    /// (I / d^2, or E) that takes radiance's place in the estimator.
    pub radiance: Vec3,
    /// Solid-angle pdf for area lights; the pick probability for delta lights.
    pub pdf: f32,
    pub is_delta: bool,
    /// Which light: its emissive triangle is recognised again if a bounce hits it.
    pub light: u32,
}

/// Walker's alias method: O(1) sampling of a discrete distribution.
#[derive(Clone, Debug, Default)]
pub struct AliasTable {
    probability: Vec<f32>,
    alias: Vec<u32>,
    pmf: Vec<f32>,
}

impl AliasTable {
    /// Builds the table for non-negative `weights` (all zero: empty).
    pub fn new(weights: &[f32]) -> AliasTable {
        let total: f64 = weights.iter().map(|&w| w.max(0.0) as f64).sum();
        let n = weights.len();
        if n == 0 || total <= 0.0 {
            return AliasTable::default();
        }
        let pmf: Vec<f32> = weights
            .iter()
            .map(|&w| (w.max(0.0) as f64 / total) as f32)
            .collect();
        let mut scaled: Vec<f64> = weights
            .iter()
            .map(|&w| w.max(0.0) as f64 / total * n as f64)
            .collect();
        let mut probability = vec![1.0f32; n];
        let mut alias: Vec<u32> = (0..n as u32).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| scaled[i] < 1.0);
        while let (Some(s), Some(&l)) = (small.pop(), large.last()) {
            probability[s] = scaled[s] as f32;
            alias[s] = l as u32;
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        AliasTable {
            probability,
            alias,
            pmf,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }

    /// An index, and its probability, from one uniform value.
    pub fn sample(&self, u: f32) -> (u32, f32) {
        let n = self.probability.len();
        let scaled = u * n as f32;
        let index = (scaled as usize).min(n - 1);
        let remainder = scaled - index as f32;
        let chosen = if remainder < self.probability[index] {
            index
        } else {
            self.alias[index] as usize
        };
        (chosen as u32, self.pmf[chosen])
    }

    pub fn pmf(&self, index: u32) -> f32 {
        self.pmf.get(index as usize).copied().unwrap_or(0.0)
    }
}

/// KHR_lights_punctual's recommended spot falloff at `cos` from the axis: a squared
/// linear ramp from 0 at `cos_outer` to 1 at `cos_inner`.
#[inline]
fn spot_falloff(cos: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    spot_ramp(cos, cos_outer, cone_scale(cos_inner, cos_outer))
}

/// `spot_falloff`'s ramp steepness, 1 / (cos_inner - cos_outer) (a cone with no width
/// ramps over 1e-3).
#[inline(always)]
fn cone_scale(cos_inner: f32, cos_outer: f32) -> f32 {
    1.0 / (cos_inner - cos_outer).max(1e-3)
}

/// `spot_falloff` with its `cone_scale` worked out.
#[inline(always)]
fn spot_ramp(cos: f32, cos_outer: f32, scale: f32) -> f32 {
    let ramp = ((cos - cos_outer) * scale).clamp(0.0, 1.0);
    ramp * ramp
}

/// The groups of punctual lights (`PunctualGroup`, a bit each) that may give some point of
/// a region light: a group left out gives every point there a weight of exactly 0, so
/// weighing only the others picks the same lights with the same probabilities. The
/// real-time render asks once per tile, for the box around its first hits: in the dark
/// (outside every cone, most of a stealth level) the pick skips its weighing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LightReach(u32);

impl LightReach {
    /// Every group: nothing known of the point.
    pub const ALL: LightReach = LightReach(u32::MAX);

    fn has(self, group: usize) -> bool {
        self.0 >> group & 1 != 0
    }
}

/// Slack for the reach test's rounding, against the cosine a lamp's weighing computes in
/// f32 (a few ulps off the exact one): a lamp is left out only when no point of the region
/// comes within this of its cone.
const REACH_COS_SLACK: f64 = 1e-4;

/// A punctual light as the pick by irradiance reads it, unpacked from its `Light` once
/// per light set (the pick weighs every punctual light at every shading point: read
/// through the `Light` enum this was 7% of a real-time frame's instructions).
#[derive(Clone, Copy, Debug)]
struct PunctualImportance {
    /// The light's index in `LightSet::lights`.
    index: u32,
    /// Where it is (points and spots).
    position: Vec3A,
    /// A spot's axis; zero otherwise.
    direction: Vec3A,
    /// The luminance of its intensity (W/sr; points and spots) or irradiance (W/m^2;
    /// directional lights).
    luminance: f32,
    /// A spot's cone (`spot_falloff`); a cone no direction falls outside otherwise.
    cos_inner: f32,
    cos_outer: f32,
    directional: bool,
}

impl PunctualImportance {
    /// False only when the light's weight (`PunctualGroup::irradiance_at`) is exactly 0 at
    /// every point of the sphere at `centre` of `radius`: a spot whose cone misses it by
    /// more than the slack, the sphere's widest angle seen from the apex against the
    /// cone's, in f64.
    fn may_light(&self, centre: [f64; 3], radius: f64) -> bool {
        let scale = cone_scale(self.cos_inner, self.cos_outer);
        // A cone a half-space or wider (a point light has none) is kept whole, and so is a
        // lamp whose weighing is not plainly finite.
        if self.directional
            || f64::from(self.cos_outer) - REACH_COS_SLACK <= 0.0
            || !self.luminance.is_finite()
            || !(scale > 0.0 && scale.is_finite())
        {
            return true;
        }
        let axis = [0, 1, 2].map(|i| f64::from(self.direction[i]));
        let to_centre = [0, 1, 2].map(|i| centre[i] - f64::from(self.position[i]));
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let (axis_length, distance) = (dot(axis, axis).sqrt(), dot(to_centre, to_centre).sqrt());
        // The apex inside the sphere; or no axis, where the weighing's cosine is 0, outside
        // a cone narrower than a half-space.
        if distance <= radius || axis_length == 0.0 {
            return distance <= radius;
        }
        // The widest cosine between the axis and a direction into the sphere.
        let cos_off_axis = (dot(axis, to_centre) / (axis_length * distance)).clamp(-1.0, 1.0);
        let sin_half_width = radius / distance;
        let cos_half_width = (1.0 - sin_half_width * sin_half_width).sqrt();
        let widest = if cos_off_axis >= cos_half_width {
            1.0
        } else {
            let sin_off_axis = (1.0 - cos_off_axis * cos_off_axis).sqrt();
            cos_off_axis * cos_half_width + sin_off_axis * sin_half_width
        };
        // The weighing's cosine carries the axis's length (1 up to rounding).
        axis_length * widest >= f64::from(self.cos_outer) - REACH_COS_SLACK
    }

    fn of(index: u32, light: &Light) -> Option<PunctualImportance> {
        let unlit = PunctualImportance {
            index,
            position: Vec3A::ZERO,
            direction: Vec3A::ZERO,
            luminance: 0.0,
            // A cone that lets everything through: any cos is past its inner edge.
            cos_inner: -2.0,
            cos_outer: -3.0,
            directional: false,
        };
        Some(match *light {
            Light::Triangle { .. } => return None,
            Light::Point {
                position,
                intensity,
            } => PunctualImportance {
                position,
                luminance: luminance(intensity),
                ..unlit
            },
            Light::Spot {
                position,
                direction,
                intensity,
                cos_inner,
                cos_outer,
            } => PunctualImportance {
                position,
                direction,
                luminance: luminance(intensity),
                cos_inner,
                cos_outer,
                ..unlit
            },
            Light::Directional { irradiance, .. } => PunctualImportance {
                luminance: luminance(irradiance),
                directional: true,
                ..unlit
            },
        })
    }
}

/// Lights a `PunctualGroup` weighs at once.
const GROUP_LANES: usize = 8;
// The pick's buffer holds whole groups.
const _: () = assert!(SPATIAL_PICK_MAX.is_multiple_of(GROUP_LANES));

/// `GROUP_LANES` punctual lights' `PunctualImportance`s, a plane per quantity, so that
/// weighing them at a point runs in SIMD lanes: the pick weighs every punctual light at
/// every shading point (the-gallery's 27 lamps, one at a time, were most of the 6.6% of its
/// frame's CPU time that light sampling took). Unused lanes have no luminance (weight 0).
#[derive(Clone, Copy, Debug, Default)]
struct PunctualGroup {
    position: [[f32; GROUP_LANES]; 3],
    direction: [[f32; GROUP_LANES]; 3],
    luminance: [f32; GROUP_LANES],
    /// Each spot's `cone_scale`, worked out once.
    cone_scale: [f32; GROUP_LANES],
    cos_outer: [f32; GROUP_LANES],
    directional: [bool; GROUP_LANES],
}

impl PunctualGroup {
    /// `lights` (at most GROUP_LANES) in lanes.
    fn of(lights: &[PunctualImportance]) -> PunctualGroup {
        let mut group = PunctualGroup::default();
        for (lane, light) in lights.iter().enumerate() {
            for axis in 0..3 {
                group.position[axis][lane] = light.position[axis];
                group.direction[axis][lane] = light.direction[axis];
            }
            group.luminance[lane] = light.luminance;
            group.cone_scale[lane] = cone_scale(light.cos_inner, light.cos_outer);
            group.cos_outer[lane] = light.cos_outer;
            group.directional[lane] = light.directional;
        }
        group
    }

    /// Per lane, the luminance of the irradiance its light gives `point`, unshadowed and
    /// before the receiver's cosine: I falloff(cos) / d^2 (zero outside a spot's cone, 1
    /// for a point light), or E for a directional light.
    #[inline(always)]
    fn irradiance_at(&self, point: Vec3A) -> [f32; GROUP_LANES] {
        let mut irradiance = [0.0; GROUP_LANES];
        for lane in 0..GROUP_LANES {
            let offset = [
                self.position[0][lane] - point.x,
                self.position[1][lane] - point.y,
                self.position[2][lane] - point.z,
            ];
            let distance2 =
                (offset[0] * offset[0] + offset[1] * offset[1] + offset[2] * offset[2]).max(1e-8);
            let cos = (self.direction[0][lane] * -offset[0]
                + self.direction[1][lane] * -offset[1]
                + self.direction[2][lane] * -offset[2])
                / distance2.sqrt();
            let falloff = spot_ramp(cos, self.cos_outer[lane], self.cone_scale[lane]);
            let spot = self.luminance[lane] * falloff / distance2;
            irradiance[lane] = if self.directional[lane] {
                self.luminance[lane]
            } else {
                spot
            };
        }
        irradiance
    }
}

/// The largest of `weights` and 0 (NaN never is), kept in eight lanes and folded:
/// maxima are exact in any order.
#[inline]
fn largest(weights: &[f32]) -> f32 {
    let larger = |most: f32, weight: f32| if weight > most { weight } else { most };
    let mut lanes = [0.0f32; GROUP_LANES];
    for chunk in weights.chunks(GROUP_LANES) {
        for (lane, &weight) in lanes.iter_mut().zip(chunk) {
            *lane = larger(*lane, weight);
        }
    }
    lanes.into_iter().fold(0.0, larger)
}

/// All lights, how they are picked (module docs), and a map from (instance, triangle) to
/// light so a bounce that hits an emitter can weigh itself against light sampling (MIS).
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    pub lights: Vec<Light>,
    /// The emissive triangles by power (punctual lights weigh nothing here), or, in a set
    /// with more than `SPATIAL_PICK_MAX` punctual lights, every light.
    table: AliasTable,
    /// The punctual lights picked by their irradiance at the shading point (empty when
    /// the table picks them).
    punctual: Vec<PunctualImportance>,
    /// `punctual` in groups of GROUP_LANES, the last one padded.
    punctual_groups: Vec<PunctualGroup>,
    /// The probability of picking from `punctual` rather than the table: the punctual
    /// lights' share of the estimated power.
    punctual_share: f32,
    by_triangle: HashMap<(u32, u32), u32>,
}

impl LightSet {
    /// `lights` with their selection weights (estimated power), and for each triangle light
    /// the (instance, triangle) it came from.
    pub fn new(
        lights: Vec<Light>,
        weights: &[f32],
        triangle_keys: Vec<((u32, u32), u32)>,
    ) -> LightSet {
        let is_punctual = |index: usize| !matches!(lights[index], Light::Triangle { .. });
        let punctual: Vec<PunctualImportance> = (0..lights.len())
            .filter(|&index| weights.get(index).is_some_and(|&w| w > 0.0))
            .filter_map(|index| PunctualImportance::of(index as u32, &lights[index]))
            .collect();
        let total: f64 = weights.iter().map(|&w| f64::from(w.max(0.0))).sum();
        let (table, punctual, punctual_share) = if punctual.len() > SPATIAL_PICK_MAX || total <= 0.0
        {
            (AliasTable::new(weights), Vec::new(), 0.0)
        } else {
            let grouped: f64 = punctual
                .iter()
                .map(|light| f64::from(weights[light.index as usize]))
                .sum();
            let triangles: Vec<f32> = weights
                .iter()
                .enumerate()
                .map(|(index, &w)| if is_punctual(index) { 0.0 } else { w })
                .collect();
            (
                AliasTable::new(&triangles),
                punctual,
                (grouped / total) as f32,
            )
        };
        LightSet {
            table,
            lights,
            punctual_groups: punctual
                .chunks(GROUP_LANES)
                .map(PunctualGroup::of)
                .collect(),
            punctual,
            punctual_share,
            by_triangle: triangle_keys.into_iter().collect(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.table.is_empty() && self.punctual.is_empty()
    }

    /// Every triangle light as ((instance, triangle), light index), in no particular order;
    /// collected so the caller may then change `lights`.
    pub fn triangle_lights(&self) -> Vec<((u32, u32), u32)> {
        self.by_triangle
            .iter()
            .map(|(&key, &light)| (key, light))
            .collect()
    }

    /// Renames the instances the emissive triangles are keyed by, after the instances were
    /// numbered anew: `new_index[old]` (None: the instance is gone, and with it the key).
    pub fn renumber_instances(&mut self, new_index: &[Option<u32>]) {
        self.by_triangle = self
            .by_triangle
            .drain()
            .filter_map(|((instance, triangle), light)| {
                let renamed = new_index.get(instance as usize).copied().flatten()?;
                Some(((renamed, triangle), light))
            })
            .collect();
    }

    /// The light of an emissive triangle, if it is one.
    pub fn triangle_light(&self, instance: u32, triangle: u32) -> Option<u32> {
        self.by_triangle.get(&(instance, triangle)).copied()
    }

    /// The punctual groups that may light some point of the box from `low` to `high`.
    pub fn reach(&self, low: Vec3A, high: Vec3A) -> LightReach {
        let (low, high) = (
            low.to_array().map(f64::from),
            high.to_array().map(f64::from),
        );
        let centre = [0, 1, 2].map(|i| 0.5 * (low[i] + high[i]));
        let half = [0, 1, 2].map(|i| 0.5 * (high[i] - low[i]));
        let radius = (half[0] * half[0] + half[1] * half[1] + half[2] * half[2]).sqrt();
        // Widened past the rounding of the centre and the half-extent.
        let radius = radius * (1.0 + 1e-6) + 1e-6;
        if !radius.is_finite() {
            return LightReach::ALL;
        }
        let mut reach = 0;
        for (group, lights) in self.punctual.chunks(GROUP_LANES).enumerate() {
            if lights.iter().any(|light| light.may_light(centre, radius)) {
                reach |= 1 << group;
            }
        }
        LightReach(reach)
    }

    /// Samples a light as seen from `point`; `emission(material, uv)` gives an area light's
    /// radiance at a UV. None when there are no lights or the sample carries nothing.
    pub fn sample(
        &self,
        point: Vec3A,
        u_pick: f32,
        u: Vec2,
        emission: impl Fn(u32, Vec2) -> Vec3,
    ) -> Option<LightSample> {
        if u_pick < self.punctual_share {
            let weights = self.punctual_weights(point, LightReach::ALL);
            let weights = &weights[..self.punctual.len()];
            return self.sample_punctual(
                weights,
                weights.iter().sum(),
                point,
                u_pick / self.punctual_share,
                self.punctual_share,
                u,
            );
        }
        self.sample_table(point, u_pick, u, emission)
    }

    /// The dominant light, and `sample` without it: the punctual light that gives `point`
    /// the most irradiance (unshadowed: the pick's own importance), as a sample with
    /// probability 1, and a light sample among all the others (the punctual group keeps
    /// its share, its other lights their weights, renormalised). The two add up to an
    /// estimate of every light's contribution, the dominant one's without the one-in-N
    /// pick's noise. No dominant light when no punctual light reaches the point (or the
    /// set is too large to weigh them per point).
    /// `reach`: the groups that may light `point` (`LightSet::reach`).
    pub fn sample_beside_dominant(
        &self,
        point: Vec3A,
        reach: LightReach,
        u_pick: f32,
        u: Vec2,
        emission: impl Fn(u32, Vec2) -> Vec3,
    ) -> (Option<LightSample>, Option<LightSample>) {
        let mut weights = [0.0; SPATIAL_PICK_MAX];
        if reach.0 != 0 {
            weights = self.punctual_weights(point, reach);
        }
        let weights = &mut weights[..self.punctual.len()];
        // Where no punctual light reaches (outside every cone: most of a dark level), there
        // is no dominant lamp and the punctual pick finds nothing: only the table's share
        // can sample a light. The same answer as the walk below gives, without it.
        if !weights.iter().any(|&weight| weight > 0.0) {
            let sampled = if u_pick >= self.punctual_share {
                self.sample_table(point, u_pick, u, emission)
            } else {
                None
            };
            return (None, sampled);
        }
        // The strongest: the first slot holding the largest weight. The largest is found
        // in lanes (exact in any order), then its slot; walked slot by slot, keeping the
        // strongest so far, it cost a compare and a branch a lamp (27 on the-gallery).
        let most = largest(weights);
        let strongest = (weights.iter())
            .position(|&weight| weight == most)
            .map(|slot| (slot, most));
        let dominant = strongest.and_then(|(slot, _)| {
            weights[slot] = 0.0;
            let index = self.punctual[slot].index;
            self.lights[index as usize].sample(index, 1.0, point, Vec2::ZERO, |_, _| Vec3::ZERO)
        });
        if u_pick >= self.punctual_share {
            return (dominant, self.sample_table(point, u_pick, u, emission));
        }
        // Russian roulette on the other punctual lights where they weigh little beside the
        // dominant one (in its pool): the group is taken with probability min(1, their
        // irradiance / (the dominant's x OTHERS_ROULETTE)), its picks' probabilities scaled
        // by that, so most of their shadow rays are saved there. `bench the-keep` at 0.5:
        // the shadow phase 4.0 -> 3.3 ms.
        let others_total: f32 = weights.iter().sum();
        let survival = match strongest {
            Some((_, most)) => (others_total / (most * OTHERS_ROULETTE)).min(1.0),
            None => 1.0,
        };
        let u_group = u_pick / self.punctual_share;
        let others = if u_group < survival {
            let group = self.punctual_share * survival;
            self.sample_punctual(weights, others_total, point, u_group / survival, group, u)
        } else {
            None
        };
        (dominant, others)
    }

    /// Each punctual light's importance at `point`, once, into a buffer on the stack (the
    /// group holds at most SPATIAL_PICK_MAX lights): evaluated twice, for the total and
    /// then for the walk, they were 6% of a first-light frame's CPU time. Compiled for 8
    /// lanes where the CPU has AVX2: the same operations (no fused multiply-adds), so the
    /// same bits, a group in one register instead of two (built for SSE2, perf put 5% of
    /// the-keep's one-thread frame in `sample_beside_dominant`, most of it here).
    /// The groups outside `reach` are left at 0, which is what they weigh there.
    #[inline]
    fn punctual_weights(&self, point: Vec3A, reach: LightReach) -> [f32; SPATIAL_PICK_MAX] {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx2() {
            #[target_feature(enable = "avx2")]
            fn punctual_weights_avx2(
                set: &LightSet,
                point: Vec3A,
                reach: LightReach,
            ) -> [f32; SPATIAL_PICK_MAX] {
                set.punctual_weights_lanes(point, reach)
            }
            // SAFETY: the CPU has AVX2, the only feature `punctual_weights_avx2` enables.
            return unsafe { punctual_weights_avx2(self, point, reach) };
        }
        self.punctual_weights_lanes(point, reach)
    }

    /// `punctual_weights` as plain lane arithmetic, for the compiler to vectorise.
    #[inline(always)]
    fn punctual_weights_lanes(&self, point: Vec3A, reach: LightReach) -> [f32; SPATIAL_PICK_MAX] {
        let mut weights = [0.0f32; SPATIAL_PICK_MAX];
        for (index, (weights, group)) in (weights.chunks_exact_mut(GROUP_LANES))
            .zip(&self.punctual_groups)
            .enumerate()
        {
            if reach.has(index) {
                weights.copy_from_slice(&group.irradiance_at(point));
            }
        }
        weights
    }

    /// A punctual light picked in proportion to `weights` (summing to `total`, in slot
    /// order: the caller has summed them already) by `u_group` in [0, 1), the group itself
    /// having been chosen with probability `group`, sampled; None when none of them
    /// reaches the point.
    fn sample_punctual(
        &self,
        weights: &[f32],
        total: f32,
        point: Vec3A,
        u_group: f32,
        group: f32,
        u: Vec2,
    ) -> Option<LightSample> {
        debug_assert_eq!(total.to_bits(), weights.iter().sum::<f32>().to_bits());
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let target = u_group * total;
        let mut below = 0.0;
        let mut chosen = None;
        for (light, &weight) in self.punctual.iter().zip(weights) {
            if weight > 0.0 {
                chosen = Some((light.index, weight));
                if target < below + weight {
                    break;
                }
                below += weight;
            }
        }
        let (index, weight) = chosen?;
        let pick = group * (weight / total);
        self.lights[index as usize].sample(index, pick, point, u, |_, _| Vec3::ZERO)
    }

    /// A triangle picked from the table (u_pick at or above the punctual share), sampled.
    fn sample_table(
        &self,
        point: Vec3A,
        u_pick: f32,
        u: Vec2,
        emission: impl Fn(u32, Vec2) -> Vec3,
    ) -> Option<LightSample> {
        if self.table.is_empty() {
            return None;
        }
        // u_pick's part above the punctual share, stretched back over [0, 1).
        let u_table = ((u_pick - self.punctual_share) / (1.0 - self.punctual_share))
            .clamp(0.0, 1.0 - f32::EPSILON);
        let (index, pmf) = self.table.sample(u_table);
        let pick = (1.0 - self.punctual_share) * pmf;
        self.lights[index as usize].sample(index, pick, point, u, emission)
    }

    /// The solid-angle pdf with which `sample` would have produced the direction from
    /// `point` to `on_light` on triangle light `index` (for MIS after a BSDF sample).
    pub fn pdf(&self, index: u32, point: Vec3A, on_light: Vec3A) -> f32 {
        let Some(Light::Triangle { normal, area, .. }) = self.lights.get(index as usize) else {
            return 0.0;
        };
        let offset = on_light - point;
        let distance2 = offset.length_squared();
        let cos_light = normal.dot(offset).abs() / distance2.sqrt();
        if cos_light <= 0.0 {
            return 0.0;
        }
        (1.0 - self.punctual_share) * self.table.pmf(index) * distance2 / (cos_light * area)
    }
}

pub use crate::scene::model::luminance;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_weight_is_the_running_maximums() {
        let mut state = 0x1234_5678u32;
        for n in 0..=SPATIAL_PICK_MAX {
            for _ in 0..200 {
                let weights: Vec<f32> = (0..n)
                    .map(|_| {
                        state = state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
                        match state >> 28 {
                            0 => 0.0,
                            1 => f32::NAN,
                            2 => 0.5, // ties
                            _ => (state >> 8) as f32 / (1 << 24) as f32,
                        }
                    })
                    .collect();
                let running = weights
                    .iter()
                    .fold(0.0f32, |most, &w| if w > most { w } else { most });
                assert_eq!(
                    largest(&weights).to_bits(),
                    running.to_bits(),
                    "{weights:?}"
                );
            }
        }
    }

    #[test]
    fn alias_table_reproduces_its_weights() {
        let weights = [1.0f32, 0.0, 3.0, 6.0];
        let table = AliasTable::new(&weights);
        let n = 100_000;
        let mut counts = [0usize; 4];
        for i in 0..n {
            let (index, pmf) = table.sample((i as f32 + 0.5) / n as f32);
            assert!((pmf - weights[index as usize] / 10.0).abs() < 1e-6);
            counts[index as usize] += 1;
        }
        for (count, weight) in counts.iter().zip(weights) {
            assert!(
                (*count as f32 / n as f32 - weight / 10.0).abs() < 2e-3,
                "{counts:?}"
            );
        }
    }

    /// A warden's lamp (a spot) over the floor and, far off, a point light with ten times
    /// its power, and an emissive triangle.
    fn lamp_and_far_light() -> LightSet {
        let lamp = Light::Spot {
            position: Vec3A::new(0.0, 2.0, 0.0),
            direction: Vec3A::NEG_Y,
            intensity: Vec3::splat(10.0),
            cos_inner: 0.9,
            cos_outer: 0.8,
        };
        let far = Light::Point {
            position: Vec3A::new(20.0, 2.0, 0.0),
            intensity: Vec3::splat(100.0),
        };
        let triangle = Light::Triangle {
            vertices: [
                Vec3A::new(-5.0, 3.0, -5.0),
                Vec3A::new(-4.0, 3.0, -5.0),
                Vec3A::new(-5.0, 3.0, -4.0),
            ],
            uvs: [Vec2::ZERO; 3],
            normal: Vec3A::NEG_Y,
            area: 0.5,
            material: 0,
            double_sided: false,
        };
        LightSet::new(
            vec![lamp, far, triangle],
            &[10.0, 100.0, 20.0],
            vec![((0, 0), 2)],
        )
    }

    /// Weighed in lanes, over more lights than one group holds: a point light gives
    /// I / d^2, a spot the same inside its cone and nothing outside, a directional light
    /// its irradiance, and the padding lanes nothing.
    #[test]
    fn punctual_weights_are_each_lights_unshadowed_irradiance() {
        let mut lights: Vec<Light> = (0..10)
            .map(|i| Light::Point {
                position: Vec3A::new(i as f32, 2.0, 0.0),
                intensity: Vec3::splat(4.0),
            })
            .collect();
        lights.push(Light::Spot {
            position: Vec3A::new(0.0, 3.0, 0.0),
            direction: Vec3A::NEG_Y,
            intensity: Vec3::splat(9.0),
            cos_inner: 0.9,
            cos_outer: 0.8,
        });
        lights.push(Light::Directional {
            direction: Vec3A::NEG_Y,
            irradiance: Vec3::splat(0.5),
        });
        let count = lights.len();
        let set = LightSet::new(lights, &vec![1.0; count], Vec::new());
        let at = |point: Vec3A| set.punctual_weights(point, LightReach::ALL);
        let under_spot = at(Vec3A::ZERO);
        for i in 0..10 {
            let expected = 4.0 / (i as f32 * i as f32 + 4.0);
            assert!(
                (under_spot[i] - expected).abs() < 1e-6,
                "light {i}: {}",
                under_spot[i]
            );
        }
        assert!(
            (under_spot[10] - 1.0).abs() < 1e-6,
            "inside the cone: 9 / 3^2"
        );
        assert_eq!(at(Vec3A::new(5.0, 0.0, 0.0))[10], 0.0, "outside the cone");
        assert_eq!(under_spot[11], 0.5);
        assert!(under_spot[count..].iter().all(|&w| w == 0.0));
        // The AVX2 build weighs to the portable one's bits.
        for point in [
            Vec3A::ZERO,
            Vec3A::new(2.5, -1.0, 0.3),
            Vec3A::new(9.0, 2.0, 0.0),
        ] {
            let bits = |weights: [f32; SPATIAL_PICK_MAX]| weights.map(f32::to_bits);
            let lanes = set.punctual_weights_lanes(point, LightReach::ALL);
            assert_eq!(bits(at(point)), bits(lanes));
        }
    }

    #[test]
    fn inside_a_lamps_cone_the_lamp_is_picked_whatever_the_power_elsewhere() {
        let set = lamp_and_far_light();
        let under_the_lamp = Vec3A::new(0.1, 0.0, 0.0);
        let n = 1000;
        let lamp_picks = (0..n)
            .filter_map(|i| {
                let u = (i as f32 + 0.5) / n as f32;
                set.sample(under_the_lamp, u, Vec2::splat(0.5), |_, _| Vec3::ONE)
            })
            .filter(|sample| sample.light == 0)
            .count();
        // The punctual group has 110/130 of the power; within it the lamp gives the point
        // 10/4 = 2.5 against the far light's 100/400 = 0.25.
        let expected = n as f32 * (110.0 / 130.0) * (2.5 / 2.75);
        assert!((lamp_picks as f32 - expected).abs() < 3.0, "{lamp_picks}");
    }

    /// A group `reach` leaves out weighs exactly 0 at every point of the box, and where
    /// the box is wholly outside a group's cones, the group is left out.
    #[test]
    fn a_group_out_of_reach_weighs_nothing_anywhere_in_the_box() {
        let mut state = 0x9e37_79b9u32;
        let mut random = || {
            state = state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
            (state >> 8) as f32 / (1 << 24) as f32
        };
        let mut left_out = 0;
        for _ in 0..400 {
            // Spots of every width pointing every way, a point light now and then, in
            // groups of 8: a group is left out only when all its lights are.
            let mut lights = Vec::new();
            for _ in 0..1 + (random() * 12.0) as usize {
                let position = Vec3A::new(random(), random(), random()) * 8.0 - 4.0;
                if random() < 0.05 {
                    lights.push(Light::Point {
                        position,
                        intensity: Vec3::ONE,
                    });
                    continue;
                }
                let direction = (Vec3A::new(random(), random(), random()) - 0.5).normalize();
                let cos_outer = random() * 1.2 - 0.2;
                lights.push(Light::Spot {
                    position,
                    direction,
                    intensity: Vec3::ONE,
                    cos_inner: (cos_outer + random() * 0.1).min(1.0),
                    cos_outer,
                });
            }
            let count = lights.len();
            let set = LightSet::new(lights, &vec![1.0; count], Vec::new());
            let low = Vec3A::new(random(), random(), random()) * 6.0 - 3.0;
            let high = low + Vec3A::new(random(), random(), random()) * 1.5;
            let reach = set.reach(low, high);
            for group in 0..count.div_ceil(GROUP_LANES) {
                if reach.has(group) {
                    continue;
                }
                left_out += 1;
                for _ in 0..200 {
                    let t = Vec3A::new(random(), random(), random());
                    let point = low + (high - low) * t;
                    let weights = set.punctual_weights(point, LightReach::ALL);
                    let group_weights = &weights[group * GROUP_LANES..][..GROUP_LANES];
                    assert!(
                        group_weights.iter().all(|&weight| weight == 0.0),
                        "group {group} weighs {group_weights:?} at {point}"
                    );
                }
            }
        }
        assert!(left_out > 50, "only {left_out} groups were left out");
        // A box behind a narrow spot is out of its reach; one in front of it is not.
        let set = LightSet::new(
            vec![Light::Spot {
                position: Vec3A::ZERO,
                direction: Vec3A::NEG_Y,
                intensity: Vec3::ONE,
                cos_inner: 0.95,
                cos_outer: 0.9,
            }],
            &[1.0],
            Vec::new(),
        );
        let unit = Vec3A::splat(0.5);
        assert_eq!(set.reach(Vec3A::Y * 3.0 - unit, Vec3A::Y * 3.0 + unit).0, 0);
        assert_eq!(
            set.reach(Vec3A::NEG_Y * 3.0 - unit, Vec3A::NEG_Y * 3.0 + unit)
                .0,
            1
        );
    }

    #[test]
    fn the_dominant_light_in_full_and_the_others_sampled_estimate_every_light() {
        let set = lamp_and_far_light();
        let mut far_light_samples = [0; 2];
        // Under the lamp it dominates; far from it, the far light does.
        for (point, dominant) in [
            (Vec3A::new(0.1, 0.0, 0.0), 0),
            (Vec3A::new(5.0, 0.0, 1.0), 1),
        ] {
            let n = 20_000;
            let estimate =
                |sample: Option<LightSample>| sample.map_or(Vec3::ZERO, |s| s.radiance / s.pdf);
            let (mut plain, mut split) = (Vec3::ZERO, Vec3::ZERO);
            for i in 0..n {
                let u_pick = (i as f32 + 0.5) / n as f32;
                let u = Vec2::new((i % 97) as f32 / 97.0, (i % 89) as f32 / 89.0);
                let sampled = set.sample(point, u_pick, u, |_, _| Vec3::ONE);
                plain += estimate(sampled);
                let (full, others) =
                    set.sample_beside_dominant(point, LightReach::ALL, u_pick, u, |_, _| Vec3::ONE);
                if dominant == 0 {
                    far_light_samples[0] += sampled.is_some_and(|s| s.light == 1) as usize;
                    far_light_samples[1] += others.is_some_and(|s| s.light == 1) as usize;
                }
                let full = full.expect("a punctual light reaches the point");
                assert_eq!(full.light, dominant);
                assert_eq!(full.pdf, 1.0);
                assert!(others.is_none_or(|other| other.light != dominant));
                split += estimate(Some(full)) + estimate(others);
            }
            let (plain, split) = (plain / n as f32, split / n as f32);
            assert!(
                ((split - plain).abs() / plain).max_element() < 1e-3,
                "at {point}: {split} against {plain}"
            );
        }
        // Under the lamp the far light gives a tenth of its irradiance: beside it, the far
        // light is sampled (a shadow ray traced) 4 x 0.1 = 0.4 times as often as the group.
        let [alone, beside] = far_light_samples.map(|count| count as f32);
        let group = 20_000.0 * 110.0 / 130.0;
        assert!(
            (beside / group - 0.4).abs() < 0.01,
            "{beside} of {group}, alone {alone}"
        );
    }

    #[test]
    fn picking_by_irradiance_stays_unbiased() {
        // Over every u, the delta lights' estimates average to the irradiance they give.
        let set = lamp_and_far_light();
        for point in [Vec3A::new(0.1, 0.0, 0.0), Vec3A::new(5.0, 0.0, 1.0)] {
            let n = 20_000;
            let mut sum = Vec3::ZERO;
            for i in 0..n {
                let u = (i as f32 + 0.5) / n as f32;
                if let Some(sample) = set.sample(point, u, Vec2::splat(0.5), |_, _| Vec3::ONE)
                    && sample.is_delta
                {
                    sum += sample.radiance / sample.pdf;
                }
            }
            let mean = sum / n as f32;
            let exact: Vec3 = set.lights[..2]
                .iter()
                .map(|light| {
                    let sample = light.sample(0, 1.0, point, Vec2::ZERO, |_, _| Vec3::ONE);
                    sample.map_or(Vec3::ZERO, |s| s.radiance)
                })
                .sum();
            assert!(
                (mean - exact).abs().max_element() < 1e-3 * exact.x,
                "{mean} vs {exact}"
            );
        }
    }

    #[test]
    fn a_triangles_pdf_in_a_mixed_set_matches_what_sampling_reports() {
        let set = lamp_and_far_light();
        let point = Vec3A::new(-4.6, 0.0, -4.6);
        // u_pick above the punctual share (110/130) picks from the triangles.
        let sample = set
            .sample(point, 0.95, Vec2::new(0.3, 0.4), |_, _| Vec3::ONE)
            .unwrap();
        assert_eq!(sample.light, 2);
        let pdf = set.pdf(2, point, sample.point);
        assert!(
            (pdf - sample.pdf).abs() < 1e-4 * sample.pdf,
            "{pdf} vs {}",
            sample.pdf
        );
    }

    #[test]
    fn triangle_light_pdf_matches_what_sampling_reports() {
        let light = Light::Triangle {
            vertices: [
                Vec3A::new(0.0, 2.0, 0.0),
                Vec3A::new(1.0, 2.0, 0.0),
                Vec3A::new(0.0, 2.0, 1.0),
            ],
            uvs: [Vec2::ZERO; 3],
            normal: Vec3A::NEG_Y,
            area: 0.5,
            material: 0,
            double_sided: false,
        };
        let set = LightSet::new(vec![light], &[1.0], vec![((0, 0), 0)]);
        let point = Vec3A::new(0.2, 0.0, 0.3);
        let sample = set
            .sample(point, 0.3, Vec2::new(0.4, 0.6), |_, _| Vec3::ONE)
            .unwrap();
        assert!(
            (set.pdf(sample.light, point, sample.point) - sample.pdf).abs() < 1e-4 * sample.pdf
        );
        // From above, the one-sided light shows its back: nothing.
        assert!(
            set.sample(
                Vec3A::new(0.2, 4.0, 0.3),
                0.3,
                Vec2::new(0.4, 0.6),
                |_, _| Vec3::ONE
            )
            .is_none()
        );
    }
}
