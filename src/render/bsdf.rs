//! Frame step `render`: how surfaces scatter light (BSDFs), in a local shading frame whose
//! +Z is the shading normal turned towards the outgoing direction `wo`.
//!
//! Conventions follow pbrt-v4: `f(wo, wi)` is the BSDF value (no cosine), `pdf` is per
//! solid angle of `wi`, and delta lobes (mirror, smooth glass) return f = weight / |cos wi|
//! with pdf equal to the lobe's selection probability, so `f |cos| / pdf` is always the
//! path throughput factor.

use glam::{Vec2, Vec3, Vec3A};

use super::sampling::{concentric_disk, cosine_hemisphere};

/// Roughness (GGX alpha) below which a conductor is a perfect mirror.
const MIRROR_ALPHA: f32 = 1e-3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// Ideal diffuse reflection: f = albedo / pi.
    Lambertian { albedo: Vec3 },
    /// A metal: GGX microfacets (Trowbridge & Reitz 1975; Walter et al. 2007) with Schlick's
    /// Fresnel on the base colour; a perfect mirror when alpha < 1e-3.
    Conductor { f0: Vec3, alpha: f32 },
    /// A smooth dielectric boundary; `eta` is the relative index of refraction from the
    /// side `wo` is on to the other side (ior when entering, 1/ior when leaving).
    Dielectric { eta: f32 },
}

/// A sampled incident direction and its throughput terms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Local direction towards the light's side.
    pub wi: Vec3A,
    pub f: Vec3,
    pub pdf: f32,
    /// From a delta lobe: light sampling could not have produced it (no MIS).
    pub specular: bool,
    /// Crossed the surface (glass).
    pub transmitted: bool,
}

impl Bsdf {
    /// Only delta lobes: next event estimation is pointless here.
    pub fn is_specular(&self) -> bool {
        match *self {
            Bsdf::Lambertian { .. } => false,
            Bsdf::Conductor { alpha, .. } => alpha < MIRROR_ALPHA,
            Bsdf::Dielectric { .. } => true,
        }
    }

    /// BSDF value for local `wo`, `wi` (0 for delta lobes).
    pub fn f(&self, wo: Vec3A, wi: Vec3A) -> Vec3 {
        match *self {
            Bsdf::Lambertian { albedo } => {
                if wo.z > 0.0 && wi.z > 0.0 {
                    albedo * std::f32::consts::FRAC_1_PI
                } else {
                    Vec3::ZERO
                }
            }
            Bsdf::Conductor { f0, alpha } => {
                if alpha < MIRROR_ALPHA || wo.z <= 0.0 || wi.z <= 0.0 {
                    return Vec3::ZERO;
                }
                let wm = (wo + wi).normalize_or_zero();
                if wm == Vec3A::ZERO {
                    return Vec3::ZERO;
                }
                // Torrance-Sparrow: D G F / (4 cos_o cos_i).
                let d = ggx_d(wm, alpha);
                let g = 1.0 / (1.0 + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha));
                schlick(f0, wo.dot(wm).abs()) * (d * g / (4.0 * wo.z * wi.z))
            }
            Bsdf::Dielectric { .. } => Vec3::ZERO,
        }
    }

    /// Solid-angle pdf of sampling `wi` given `wo` (0 for delta lobes).
    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        match *self {
            Bsdf::Lambertian { .. } => {
                if wo.z > 0.0 && wi.z > 0.0 {
                    wi.z * std::f32::consts::FRAC_1_PI
                } else {
                    0.0
                }
            }
            Bsdf::Conductor { alpha, .. } => {
                if alpha < MIRROR_ALPHA || wo.z <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                let wm = (wo + wi).normalize_or_zero();
                if wm == Vec3A::ZERO {
                    return 0.0;
                }
                // Visible-normal pdf over the reflection Jacobian: G1(wo) D(wm) / (4 cos_o).
                ggx_g1(wo, alpha) * ggx_d(wm, alpha) / (4.0 * wo.z)
            }
            Bsdf::Dielectric { .. } => 0.0,
        }
    }

    /// Samples `wi` for local `wo`; `u_choice` picks reflection or refraction for glass.
    pub fn sample(&self, wo: Vec3A, u_choice: f32, u: Vec2) -> Option<BsdfSample> {
        match *self {
            Bsdf::Lambertian { albedo } => {
                if wo.z <= 0.0 {
                    return None;
                }
                let wi = cosine_hemisphere(u);
                let pdf = wi.z * std::f32::consts::FRAC_1_PI;
                (pdf > 0.0).then_some(BsdfSample {
                    wi,
                    f: albedo * std::f32::consts::FRAC_1_PI,
                    pdf,
                    specular: false,
                    transmitted: false,
                })
            }
            Bsdf::Conductor { f0, alpha } => {
                if wo.z <= 0.0 {
                    return None;
                }
                if alpha < MIRROR_ALPHA {
                    let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
                    return Some(BsdfSample {
                        wi,
                        f: schlick(f0, wo.z) / wi.z,
                        pdf: 1.0,
                        specular: true,
                        transmitted: false,
                    });
                }
                let wm = sample_ggx_visible_normal(wo, alpha, u);
                let wi = reflect(wo, wm);
                if wi.z <= 0.0 {
                    return None;
                }
                let pdf = self.pdf(wo, wi);
                (pdf > 0.0).then(|| BsdfSample {
                    wi,
                    f: self.f(wo, wi),
                    pdf,
                    specular: false,
                    transmitted: false,
                })
            }
            Bsdf::Dielectric { eta } => {
                let cos_o = wo.z;
                let reflectance = fresnel_dielectric(cos_o, eta);
                if u_choice < reflectance {
                    let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
                    return Some(BsdfSample {
                        wi,
                        f: Vec3::splat(reflectance / wi.z.abs()),
                        pdf: reflectance,
                        specular: true,
                        transmitted: false,
                    });
                }
                let wi = refract(wo, eta)?;
                let transmittance = 1.0 - reflectance;
                // Radiance is compressed into the smaller solid angle when entering a denser
                // medium: divide by eta^2 (pbrt-v4 section 9.5.2, TransportMode::Radiance).
                Some(BsdfSample {
                    wi,
                    f: Vec3::splat(transmittance / wi.z.abs() / (eta * eta)),
                    pdf: transmittance,
                    specular: true,
                    transmitted: true,
                })
            }
        }
    }
}

/// Schlick's approximation to the Fresnel reflectance of a conductor tinted `f0`.
fn schlick(f0: Vec3, cos_theta: f32) -> Vec3 {
    let m = (1.0 - cos_theta).clamp(0.0, 1.0);
    f0 + (Vec3::ONE - f0) * (m * m * m * m * m)
}

/// Exact Fresnel reflectance of unpolarised light at a dielectric boundary, for the cosine
/// on the incident side and the relative ior `eta`; 1 under total internal reflection.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(-1.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let cos_i = cos_i.abs();
    let parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (parallel * parallel + perpendicular * perpendicular)
}

/// Refracts local `wo` (on the +Z side) through the boundary; None under total internal
/// reflection.
fn refract(wo: Vec3A, eta: f32) -> Option<Vec3A> {
    let cos_i = wo.z;
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-wo / eta + Vec3A::Z * (cos_i / eta - cos_t))
}

fn reflect(wo: Vec3A, normal: Vec3A) -> Vec3A {
    -wo + normal * (2.0 * wo.dot(normal))
}

/// GGX normal distribution D(wm) for local microfacet normal `wm`.
fn ggx_d(wm: Vec3A, alpha: f32) -> f32 {
    let cos2 = wm.z * wm.z;
    if cos2 <= 0.0 {
        return 0.0;
    }
    let tan2 = (1.0 - cos2) / cos2;
    let a2 = alpha * alpha;
    let e = 1.0 + tan2 / a2;
    1.0 / (std::f32::consts::PI * a2 * cos2 * cos2 * e * e)
}

/// Smith's Lambda for GGX.
fn ggx_lambda(w: Vec3A, alpha: f32) -> f32 {
    let cos2 = w.z * w.z;
    if cos2 <= 0.0 {
        return f32::INFINITY;
    }
    let tan2 = (1.0 - cos2) / cos2;
    ((1.0 + alpha * alpha * tan2).sqrt() - 1.0) * 0.5
}

fn ggx_g1(w: Vec3A, alpha: f32) -> f32 {
    1.0 / (1.0 + ggx_lambda(w, alpha))
}

/// A microfacet normal from GGX's distribution of normals visible from `wo` (Heitz 2018,
/// "Sampling the GGX Distribution of Visible Normals").
fn sample_ggx_visible_normal(wo: Vec3A, alpha: f32, u: Vec2) -> Vec3A {
    // Stretch to the hemisphere configuration.
    let wh = Vec3A::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let t1 = if wh.z < 0.99999 {
        Vec3A::Z.cross(wh).normalize()
    } else {
        Vec3A::X
    };
    let t2 = wh.cross(t1);
    // A uniform disk point, warped to the projected hemisphere.
    let mut p = concentric_disk(u);
    let h = (1.0 - p.x * p.x).max(0.0).sqrt();
    p.y = h + (p.y - h) * (1.0 + wh.z) * 0.5;
    let pz = (1.0 - p.length_squared()).max(0.0).sqrt();
    let nh = t1 * p.x + t2 * p.y + wh * pz;
    // Unstretch.
    Vec3A::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-6)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hemisphere_grid(n: usize) -> impl Iterator<Item = Vec2> {
        (0..n * n).map(move |i| {
            Vec2::new(
                ((i % n) as f32 + 0.5) / n as f32,
                ((i / n) as f32 + 0.5) / n as f32,
            )
        })
    }

    /// Monte Carlo estimate of the directional albedo int f cos dwi using the BSDF's own
    /// sampling, and of int pdf dwi using uniform hemisphere directions.
    fn albedo_and_pdf_integral(bsdf: Bsdf, wo: Vec3A) -> (Vec3, f32) {
        let n = 256;
        let mut albedo = Vec3::ZERO;
        for u in hemisphere_grid(n) {
            if let Some(s) = bsdf.sample(wo, 0.5, u) {
                albedo += s.f * s.wi.z.abs() / s.pdf;
            }
        }
        let mut pdf_integral = 0.0;
        for u in hemisphere_grid(n) {
            // Uniform hemisphere: pdf 1 / (2 pi).
            let z = u.x;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = std::f32::consts::TAU * u.y;
            let wi = Vec3A::new(r * phi.cos(), r * phi.sin(), z);
            pdf_integral += bsdf.pdf(wo, wi) * std::f32::consts::TAU;
        }
        (albedo / (n * n) as f32, pdf_integral / (n * n) as f32)
    }

    #[test]
    fn lambertian_conserves_energy_and_its_pdf_integrates_to_one() {
        let wo = Vec3A::new(0.3, 0.2, 0.9).normalize();
        let (albedo, pdf) = albedo_and_pdf_integral(Bsdf::Lambertian { albedo: Vec3::ONE }, wo);
        assert!((albedo - Vec3::ONE).abs().max_element() < 1e-3, "{albedo}");
        assert!((pdf - 1.0).abs() < 0.01, "{pdf}");
    }

    /// Midpoint quadrature over the hemisphere, uniform in z = cos(theta) and phi. Fine z
    /// steps resolve the narrow peak of low-alpha GGX (about alpha^2 / 2 wide in z).
    fn hemisphere_integral(integrand: impl Fn(Vec3A) -> f32) -> f64 {
        let (steps_z, steps_phi) = (20_000, 120);
        let mut sum = 0.0f64;
        for i in 0..steps_z {
            let z = (i as f32 + 0.5) / steps_z as f32;
            let r = (1.0 - z * z).sqrt();
            for j in 0..steps_phi {
                let phi = std::f32::consts::TAU * (j as f32 + 0.5) / steps_phi as f32;
                sum += integrand(Vec3A::new(r * phi.cos(), r * phi.sin(), z)) as f64;
            }
        }
        sum * std::f64::consts::TAU / (steps_z * steps_phi) as f64
    }

    #[test]
    fn ggx_distribution_and_masking_satisfy_their_identities() {
        for alpha in [0.1f32, 0.4, 0.8] {
            for cos_o in [0.9f32, 0.5] {
                let wo = Vec3A::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
                // Projected microfacet area is one: int D(m) cos(theta_m) dm = 1.
                let normalisation = hemisphere_integral(|m| ggx_d(m, alpha) * m.z);
                assert!(
                    (normalisation - 1.0).abs() < 2e-3,
                    "alpha {alpha}: int D cos = {normalisation}"
                );
                // Smith: visible projected area equals the macro-surface's,
                // int G1(wo) <wo.m> D(m) dm = cos(theta_o).
                let visible = hemisphere_integral(|m| {
                    ggx_g1(wo, alpha) * wo.dot(m).max(0.0) * ggx_d(m, alpha)
                });
                assert!(
                    (visible - cos_o as f64).abs() < 2e-3,
                    "alpha {alpha} cos {cos_o}: {visible}"
                );
                // Importance sampling estimates the same albedo as direct quadrature of
                // f cos (single-scattering GGX loses energy as alpha grows, e.g. about 22%
                // at alpha 0.4, cos 0.9: Kulla & Conty 2017), and never exceeds 1.
                let bsdf = Bsdf::Conductor {
                    f0: Vec3::ONE,
                    alpha,
                };
                let (sampled, pdf_integral) = albedo_and_pdf_integral(bsdf, wo);
                let direct = hemisphere_integral(|wi| bsdf.f(wo, wi).x * wi.z);
                assert!(
                    (sampled.x as f64 - direct).abs() < 0.01,
                    "alpha {alpha} cos {cos_o}: {sampled} vs {direct}"
                );
                assert!(direct <= 1.0 + 1e-3);
                // The pdf integrates to the fraction of sampled directions above the horizon.
                assert!(
                    pdf_integral <= 1.0 + 0.02 && pdf_integral > 0.5,
                    "alpha {alpha} cos {cos_o}: {pdf_integral}"
                );
                // sample() reports the same f and pdf as f() and pdf().
                let s = bsdf.sample(wo, 0.5, Vec2::new(0.3, 0.7)).unwrap();
                assert!((s.f - bsdf.f(wo, s.wi)).length() < 1e-4 * s.f.length().max(1.0));
                assert!((s.pdf - bsdf.pdf(wo, s.wi)).abs() < 1e-4 * s.pdf.max(1.0));
            }
        }
    }

    #[test]
    fn dielectric_fresnel_matches_known_values() {
        // Normal incidence, glass: ((1.5 - 1) / (1.5 + 1))^2 = 0.04.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        // Leaving glass at 45 degrees, beyond the critical angle (41.8): total internal reflection.
        assert_eq!(fresnel_dielectric(45f32.to_radians().cos(), 1.0 / 1.5), 1.0);
        // Brewster's angle: the parallel part vanishes, R = perpendicular / 2.
        let brewster = 1.5f32.atan();
        let r = fresnel_dielectric(brewster.cos(), 1.5);
        assert!((r - 0.0739).abs() < 1e-3, "{r}");
    }

    #[test]
    fn dielectric_splits_energy_between_reflection_and_refraction() {
        let eta = 1.5;
        let wo = Vec3A::new(0.6, 0.0, 0.8);
        let bsdf = Bsdf::Dielectric { eta };
        let reflect = bsdf.sample(wo, 0.0, Vec2::ZERO).unwrap();
        let refract = bsdf.sample(wo, 0.999, Vec2::ZERO).unwrap();
        assert!(!reflect.transmitted && refract.transmitted);
        // Snell: sin_t = sin_i / eta.
        let sin_t = (refract.wi.x * refract.wi.x + refract.wi.y * refract.wi.y).sqrt();
        assert!((sin_t - 0.6 / eta).abs() < 1e-5 && refract.wi.z < 0.0);
        // Throughput weights: R and T / eta^2.
        let r = fresnel_dielectric(0.8, eta);
        assert!((reflect.f.x * reflect.wi.z.abs() / reflect.pdf - 1.0).abs() < 1e-5);
        assert!((refract.f.x * refract.wi.z.abs() / refract.pdf - 1.0 / (eta * eta)).abs() < 1e-5);
        assert!((reflect.pdf - r).abs() < 1e-6 && (refract.pdf - (1.0 - r)).abs() < 1e-6);
    }
}
