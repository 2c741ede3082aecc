//! Frame step `render`: materials and textures as the integrator reads them.
//!
//! glTF metallic-roughness, as the project's conventions read it: the base colour is the albedo; metallic 0 and
//! transmission 0 is Lambertian; metallic 1 is a conductor (perfect mirror at roughness 0,
//! GGX otherwise, alpha = roughness^2); transmission 1 is a smooth dielectric with the
//! material's ior. In-between values are a mixture of those lobes; one lobe is chosen per
//! hit with probability equal to its weight, which is an unbiased estimate of the mixture.

use glam::{Affine2, Vec2, Vec3, Vec4};

use super::bsdf::Bsdf;
use crate::scene::model::{AlphaMode, ColorEncoding, Filter, Image, Wrap};

/// A decoded texture: linear RGBA texels (sRGB already removed for colour slots), sampled
/// bilinearly with glTF's wrap modes.
#[derive(Clone, Debug)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Vec4>,
    pub wrap_u: Wrap,
    pub wrap_v: Wrap,
    pub filter: Filter,
}

impl Texture {
    pub fn from_image(
        image: &Image,
        encoding: ColorEncoding,
        wrap_u: Wrap,
        wrap_v: Wrap,
        filter: Filter,
    ) -> Texture {
        let texels = (0..image.height)
            .flat_map(|y| (0..image.width).map(move |x| (x, y)))
            .map(|(x, y)| image.texel_linear(x, y, encoding))
            .collect();
        Texture {
            width: image.width.max(1),
            height: image.height.max(1),
            texels,
            wrap_u,
            wrap_v,
            filter,
        }
    }

    /// The filtered value at `uv` (glTF: (0, 0) is the image's top-left).
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        if self.texels.is_empty() {
            return Vec4::ONE;
        }
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        if self.filter == Filter::Nearest {
            return self.texel(floor(x + 0.5) as i64, floor(y + 0.5) as i64);
        }
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        // Each of the two columns and two rows wrapped once (not once per texel).
        let (width, height) = (self.width as i64, self.height as i64);
        let (left, right) = (
            wrap(x0, width, self.wrap_u),
            wrap(x0 + 1, width, self.wrap_u),
        );
        let (upper, lower) = (
            wrap(y0, height, self.wrap_v),
            wrap(y0 + 1, height, self.wrap_v),
        );
        let row = |y: i64| &self.texels[(y * width) as usize..][..self.width as usize];
        let (upper, lower) = (row(upper), row(lower));
        let (left, right) = (left as usize, right as usize);
        let top = upper[left].lerp(upper[right], fx);
        let bottom = lower[left].lerp(lower[right], fx);
        top.lerp(bottom, fy)
    }

    fn texel(&self, x: i64, y: i64) -> Vec4 {
        let x = wrap(x, self.width as i64, self.wrap_u);
        let y = wrap(y, self.height as i64, self.wrap_v);
        self.texels[(y * self.width as i64 + x) as usize]
    }
}

/// `x.floor()`, bit for bit for every f32 (NaN, infinities and -0.0 included), inlined:
/// built for x86-64 without SSE4.1, `f32::floor` calls a portable software routine
/// (`floorf`: 1.6% of first-light's render instructions; inlined, 0.7% fewer in all).
#[inline(always)]
pub(crate) fn floor(x: f32) -> f32 {
    // From 2^23 up every f32 is a whole number, and NaN fails the test: both are their
    // own floor.
    if x.abs() < 8_388_608.0 {
        let truncated = x as i32 as f32;
        // Truncation rounds a negative fraction up: step it down. Every floor has its
        // argument's sign, which keeps floor(-0.0) = -0.0.
        (truncated - f32::from(u8::from(truncated > x))).copysign(x)
    } else {
        x
    }
}

/// Texel index `i` on an axis `n` texels long, wrapped by `mode`.
#[inline]
fn wrap(i: i64, n: i64, mode: Wrap) -> i64 {
    // Inside the texture every mode leaves the index as it is, without the 64-bit
    // division the repeating modes take (two wraps of a bilinear tap's four texels
    // were a third of `Texture::sample`).
    if (0..n).contains(&i) {
        return i;
    }
    match mode {
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::MirroredRepeat => {
            let period = i.rem_euclid(2 * n);
            if period < n {
                period
            } else {
                2 * n - 1 - period
            }
        }
    }
}

/// A material's use of a texture, resolved to an index into `RenderScene::textures`.
#[derive(Clone, Copy, Debug)]
pub struct TextureSlot {
    pub texture: u32,
    pub uv_transform: Affine2,
}

/// A material ready for shading (level overrides already applied).
#[derive(Clone, Debug)]
pub struct RenderMaterial {
    pub base_color: Vec4,
    pub base_color_texture: Option<TextureSlot>,
    pub metallic: f32,
    pub roughness: f32,
    pub metallic_roughness_texture: Option<TextureSlot>,
    /// Radiance in W/(sr m^2).
    pub emissive: Vec3,
    pub emissive_texture: Option<TextureSlot>,
    pub transmission: f32,
    pub ior: f32,
    pub alpha_mode: AlphaMode,
    pub double_sided: bool,
}

impl RenderMaterial {
    pub fn is_emissive(&self) -> bool {
        self.emissive.max_element() > 0.0
    }

    fn sample(slot: Option<TextureSlot>, textures: &[Texture], uv: Vec2) -> Vec4 {
        match slot {
            Some(slot) => {
                textures[slot.texture as usize].sample(slot.uv_transform.transform_point2(uv))
            }
            None => Vec4::ONE,
        }
    }

    /// Base colour and coverage at `uv`.
    pub fn base_color_at(&self, textures: &[Texture], uv: Vec2) -> Vec4 {
        self.base_color * Self::sample(self.base_color_texture, textures, uv)
    }

    /// The fraction of light the surface reflects or transmits at `uv`, ignoring its lobe's
    /// shape: what the denoiser divides illumination by (SVGF's demodulation). Glass and
    /// metal take their Fresnel-free weights: base colour for metal and diffuse, 1 for glass.
    pub fn albedo_at(&self, textures: &[Texture], uv: Vec2) -> Vec3 {
        let base = self.base_color_at(textures, uv).truncate();
        let glass = self.transmission.clamp(0.0, 1.0) * (1.0 - self.metallic.clamp(0.0, 1.0));
        base.lerp(Vec3::ONE, glass)
    }

    /// Emitted radiance at `uv` from the front (and from the back when double-sided).
    pub fn emission_at(&self, textures: &[Texture], uv: Vec2) -> Vec3 {
        if !self.is_emissive() {
            return Vec3::ZERO;
        }
        self.emissive * Self::sample(self.emissive_texture, textures, uv).truncate()
    }

    /// Is the point solid for rays (alpha mask)? Blend is treated as a mask at 0.5.
    pub fn is_opaque_at(&self, textures: &[Texture], uv: Vec2) -> bool {
        match self.alpha_mode {
            AlphaMode::Opaque => true,
            AlphaMode::Mask { cutoff } => self.base_color_at(textures, uv).w >= cutoff,
            AlphaMode::Blend => self.base_color_at(textures, uv).w >= 0.5,
        }
    }

    /// The BSDF lobe to use at `uv`: one of the mixture's lobes, chosen with `u_lobe` with
    /// probability equal to its weight. `entering` says `wo` is on the front side.
    pub fn bsdf_at(&self, textures: &[Texture], uv: Vec2, u_lobe: f32, entering: bool) -> Bsdf {
        let base = self.base_color_at(textures, uv).truncate();
        let metal_rough = Self::sample(self.metallic_roughness_texture, textures, uv);
        let metallic = (self.metallic * metal_rough.z).clamp(0.0, 1.0);
        let roughness = (self.roughness * metal_rough.y).clamp(0.0, 1.0);
        if u_lobe < metallic {
            return Bsdf::Conductor {
                f0: base,
                alpha: roughness * roughness,
            };
        }
        // Rescale the remaining interval to choose between glass and diffuse.
        let u = (u_lobe - metallic) / (1.0 - metallic).max(f32::MIN_POSITIVE);
        if u < self.transmission {
            let eta = if entering { self.ior } else { 1.0 / self.ior };
            return Bsdf::Dielectric { eta };
        }
        Bsdf::Lambertian { albedo: base }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_is_the_standard_librarys_bit_for_bit() {
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1.0 - f32::EPSILON / 2.0,
            -(1.0 - f32::EPSILON / 2.0),
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            3.0e9,
            -3.0e9,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        // And a spread of bit patterns over every exponent.
        values.extend((0..1 << 16).map(|i: u32| f32::from_bits(i.wrapping_mul(0x9e37_79b9))));
        for x in values {
            assert_eq!(floor(x).to_bits(), x.floor().to_bits(), "floor({x:e})");
        }
    }

    /// Wrapping as glTF defines it, index by index.
    #[test]
    fn wrap_modes_fold_every_index_onto_the_texture() {
        let n = 5;
        for i in -23i64..23 {
            assert_eq!(wrap(i, n, Wrap::ClampToEdge), i.clamp(0, n - 1));
            assert_eq!(wrap(i, n, Wrap::Repeat), i.rem_euclid(n), "repeat {i}");
            let period = i.rem_euclid(2 * n);
            let mirrored = if period < n {
                period
            } else {
                2 * n - 1 - period
            };
            assert_eq!(wrap(i, n, Wrap::MirroredRepeat), mirrored, "mirrored {i}");
        }
    }

    /// The bilinear tap is the four wrapped texels' blend, inside the texture and past
    /// each of its edges, in every wrap mode.
    #[test]
    fn a_bilinear_tap_blends_the_four_wrapped_texels() {
        let (width, height) = (5u32, 3u32);
        let texels: Vec<Vec4> = (0..width * height)
            .map(|i| Vec4::new(i as f32, (i * i % 7) as f32, 1.0, 0.5))
            .collect();
        for (wrap_u, wrap_v) in [
            (Wrap::Repeat, Wrap::ClampToEdge),
            (Wrap::MirroredRepeat, Wrap::Repeat),
            (Wrap::ClampToEdge, Wrap::MirroredRepeat),
        ] {
            let texture = Texture {
                width,
                height,
                texels: texels.clone(),
                wrap_u,
                wrap_v,
                filter: Filter::Linear,
            };
            for k in 0..200 {
                let uv = Vec2::new(k as f32 * 0.0731 - 7.3, k as f32 * -0.0517 + 5.1);
                let (x, y) = (uv.x * 5.0 - 0.5, uv.y * 3.0 - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let top = texture.texel(x0, y0).lerp(texture.texel(x0 + 1, y0), fx);
                let bottom = (texture.texel(x0, y0 + 1)).lerp(texture.texel(x0 + 1, y0 + 1), fx);
                assert_eq!(texture.sample(uv), top.lerp(bottom, fy), "uv {uv}");
            }
        }
    }
}
