//! Frame step `render`: the lights next event estimation samples.
//!
//! Every emissive triangle and every KHR punctual light is one entry of a `LightSet`; one is
//! picked per shading point with probability proportional to its estimated power, through
//! an alias table (Walker 1977; Vose 1991), then a point on it is chosen uniformly by area
//! and the area pdf is converted to solid angle: pdf = p_pick * d^2 / (|cos theta_light| A).
//! The sky is not sampled here: bounce rays that leave the scene pick it up.

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
                // KHR_lights_punctual's recommended falloff: a squared linear ramp in cos.
                let scale = 1.0 / (cos_inner - cos_outer).max(1e-3);
                let ramp = ((direction.dot(-wi) - cos_outer) * scale).clamp(0.0, 1.0);
                let attenuation = ramp * ramp;
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

/// All lights, the table that picks them, and a map from (instance, triangle) to light so a
/// bounce that hits an emitter can weigh itself against light sampling (MIS).
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    pub lights: Vec<Light>,
    table: AliasTable,
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
        LightSet {
            table: AliasTable::new(weights),
            lights,
            by_triangle: triangle_keys.into_iter().collect(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.table.is_empty()
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

    /// Samples a light as seen from `point`; `emission(material, uv)` gives an area light's
    /// radiance at a UV. None when there are no lights or the sample carries nothing.
    pub fn sample(
        &self,
        point: Vec3A,
        u_pick: f32,
        u: Vec2,
        emission: impl Fn(u32, Vec2) -> Vec3,
    ) -> Option<LightSample> {
        if self.table.is_empty() {
            return None;
        }
        let (index, pick) = self.table.sample(u_pick);
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
        self.table.pmf(index) * distance2 / (cos_light * area)
    }
}

pub use crate::scene::model::luminance;

#[cfg(test)]
mod tests {
    use super::*;

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
