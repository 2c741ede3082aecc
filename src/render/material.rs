//! Frame step `render`: materials and textures as the integrator reads them.
//!
//! glTF metallic-roughness, as the project's conventions read it: the base colour is the albedo; metallic 0 and
//! transmission 0 is Lambertian; metallic 1 is a conductor (perfect mirror at roughness 0,
//! GGX otherwise, alpha = roughness^2); transmission 1 is a smooth dielectric with the
//! material's ior. In-between values are a mixture of those lobes; one lobe is chosen per
//! hit with probability equal to its weight, which is an unbiased estimate of the mixture.

use std::sync::Arc;

use glam::{Affine2, Vec2, Vec3, Vec4};

use super::bsdf::Bsdf;
use crate::scene::model::{AlphaMode, ColorEncoding, Filter, Image, Wrap};

/// A decoded texture: linear RGBA texels (sRGB already removed for colour slots), sampled
/// with glTF's wrap modes from a mip pyramid at the level a ray cone asks for
/// ([`Texture::sample`]).
#[derive(Clone, Debug)]
pub struct Texture {
    /// Level 0 (the image itself) first, then each level half the one before (rounded
    /// down, at least one texel), down to 1 x 1. Shared by the textures that read one
    /// image with other samplers (`with_sampler`).
    levels: Arc<[MipLevel]>,
    wrap_u: Wrap,
    wrap_v: Wrap,
    filter: Filter,
    /// 0.5 log2(width x height) of level 0: added to a footprint in UV units to give the
    /// level whose texels are that wide.
    log2_size: f32,
    /// Repeating both ways, bilinear, and under 2^23 texels a side: taps take
    /// `Texture::tap_repeating`'s short road.
    repeats: bool,
}

/// Where a bilinear tap reads: a level's four texels (upper left, upper right, lower left,
/// lower right) and the weights between them. Textures of the same shape share it, so a
/// material's base colour and normals are read with one set of index arithmetic.
#[derive(Clone, Copy, Debug)]
pub struct Tap {
    level: usize,
    corners: [usize; 4],
    fx: f32,
    fy: f32,
    /// The tap reads the 1 x 1 level: the footprint covers the whole texture.
    coarsest: bool,
}

/// One level of the pyramid. Texels are linear values in [0, 1] held as 16-bit integers
/// (65535 is 1), which keeps the darkest step of an 8-bit sRGB image (1/3295 in linear)
/// and is half the bytes of four floats, so twice as many texels stay in a core's caches.
#[derive(Clone, Debug)]
struct MipLevel {
    width: u32,
    height: u32,
    /// (width, height) as floats, for the UV to texel step.
    size: Vec2,
    texels: Vec<[u16; 4]>,
}

/// The footprint that always reads level 0 bilinearly: a ray with no cone (emission,
/// alpha tests, the reference paths of tests).
pub const FINEST: f32 = f32::NEG_INFINITY;

/// A stored texel's value for 1.0.
const TEXEL_ONE: f32 = 65535.0;

fn quantise(value: Vec4) -> [u16; 4] {
    // NaN clamps to 0.
    value
        .to_array()
        .map(|c| (c.clamp(0.0, 1.0) * TEXEL_ONE + 0.5) as u16)
}

/// A stored texel in stored units (65535 is 1).
#[inline(always)]
fn widen(texel: [u16; 4]) -> Vec4 {
    // Lane by lane, the four conversions were 40% of a tap's instructions (callgrind).
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2, the only feature these use, is part of every x86-64 CPU; the load
    // reads the texel's 8 bytes.
    unsafe {
        use std::arch::x86_64::{
            _mm_cvtepi32_ps, _mm_loadl_epi64, _mm_setzero_si128, _mm_unpacklo_epi16,
        };
        let bits = _mm_loadl_epi64(texel.as_ptr().cast());
        Vec4::from(_mm_cvtepi32_ps(_mm_unpacklo_epi16(
            bits,
            _mm_setzero_si128(),
        )))
    }
    #[cfg(not(target_arch = "x86_64"))]
    Vec4::new(
        f32::from(texel[0]),
        f32::from(texel[1]),
        f32::from(texel[2]),
        f32::from(texel[3]),
    )
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
        Texture::from_texels(image.width, image.height, texels, wrap_u, wrap_v, filter)
    }

    /// A texture over `texels` (linear values in [0, 1], row by row from the top-left,
    /// `width x height` of them or none), with its mip pyramid: each level's texel the
    /// mean of the 2 x 2 texels under it (a level of odd size folds its last row or column
    /// into the texels before).
    pub fn from_texels(
        width: u32,
        height: u32,
        texels: Vec<Vec4>,
        wrap_u: Wrap,
        wrap_v: Wrap,
        filter: Filter,
    ) -> Texture {
        let complete = texels.len() == width as usize * height as usize && !texels.is_empty();
        let (width, height) = if complete { (width, height) } else { (1, 1) };
        let mut levels = vec![MipLevel::new(
            width,
            height,
            if complete {
                texels.into_iter().map(quantise).collect()
            } else {
                Vec::new()
            },
        )];
        while let Some(above) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
            levels.push(above.halved());
        }
        let log2_size = 0.5 * ((width as f32) * (height as f32)).log2();
        Texture {
            levels: levels.into(),
            wrap_u,
            wrap_v,
            filter,
            log2_size,
            repeats: false,
        }
        .with_sampler(wrap_u, wrap_v, filter)
    }

    /// The same texels and pyramid (shared, not copied), read with another sampler.
    pub fn with_sampler(&self, wrap_u: Wrap, wrap_v: Wrap, filter: Filter) -> Texture {
        const SHORT_ROAD_SIDE: u32 = 1 << 23;
        let (width, height) = self.size();
        Texture {
            repeats: !self.levels[0].texels.is_empty()
                && (wrap_u, wrap_v) == (Wrap::Repeat, Wrap::Repeat)
                && filter == Filter::Linear
                && width < SHORT_ROAD_SIDE
                && height < SHORT_ROAD_SIDE,
            levels: Arc::clone(&self.levels),
            wrap_u,
            wrap_v,
            filter,
            log2_size: self.log2_size,
        }
    }

    /// Whether `other` reads this texture's very texels (one decoded image, two samplers or
    /// two engines).
    pub fn shares_pyramid_with(&self, other: &Texture) -> bool {
        Arc::ptr_eq(&self.levels, &other.levels)
    }

    /// Level 0's size in texels.
    pub fn size(&self) -> (u32, u32) {
        (self.levels[0].width, self.levels[0].height)
    }

    /// Whether a footprint `footprint` wide covers the whole texture, so a tap reads the
    /// texels' mean (the 1 x 1 level).
    pub fn is_covered_by(&self, footprint: f32) -> bool {
        footprint + self.log2_size >= (self.levels.len() - 1) as f32
    }

    /// The filtered value at `uv` (glTF: (0, 0) is the image's top-left) for a footprint
    /// `footprint` = log2 of the ray cone's width on the surface in UV units
    /// (`integrator::RayCone`). Where a texel is at least that wide, level 0 is read
    /// bilinearly (exactly `FINEST`'s tap, so a close-up is as sharp as the image);
    /// farther, one of the two levels around it (Williams 1983, "Pyramidal Parametrics"),
    /// chosen at random with the trilinear blend's weights, so a wall far off reads its
    /// texels' mean and does not shimmer from one 1-spp frame to the next. One bilinear tap
    /// instead of trilinear's two: its expectation is the trilinear value, and the film's
    /// filters average the choice away (Pharr et al. 2024, "Filtering After Shading with
    /// Stochastic Texture Filtering"); the random number is a hash of the UV's bits, the
    /// same on every thread and machine.
    pub fn sample(&self, uv: Vec2, footprint: f32) -> Vec4 {
        if self.levels[0].texels.is_empty() {
            return Vec4::ONE;
        }
        if self.repeats {
            return match self.tap(uv, footprint) {
                Some(tap) => self.read(&tap),
                None => self.mean(),
            };
        }
        // Into the first period once, so the texel indices below fall inside the texture
        // but at its edges: the kit's UVs run over many periods, and wrapping each index
        // there took a 64-bit division apiece (a quarter of the sampling's time, perf).
        let uv = Vec2::new(
            into_first_period(uv.x, self.wrap_u),
            into_first_period(uv.y, self.wrap_v),
        );
        if self.filter == Filter::Nearest {
            return self.sample_level(0, uv);
        }
        match self.level_at(uv, footprint) {
            // The 1 x 1 level: its one texel, without a tap's arithmetic.
            level if level + 1 == self.levels.len() => self.mean(),
            level => self.sample_level(level, uv),
        }
    }

    /// The level `sample` reads for a footprint `footprint` at `uv` (in its first
    /// period): 0 where a texel is at least as wide, the last (1 x 1) where the footprint
    /// covers the texture, and between, one of the two levels around it, the coarser with
    /// the footprint's fraction for its probability.
    #[inline]
    fn level_at(&self, uv: Vec2, footprint: f32) -> usize {
        let level = footprint + self.log2_size;
        if !(level > 0.0) {
            0
        } else if self.is_covered_by(footprint) {
            self.levels.len() - 1
        } else {
            let below = floor(level);
            // SAFETY: 0 <= below < levels - 1 here (level > 0 and the footprint does not
            // cover the texture), so it fits an i32.
            let below_index = unsafe { below.to_int_unchecked::<i32>() } as usize;
            below_index + usize::from(uv_hash(uv) < level - below)
        }
    }

    /// Whether `other`'s taps read where this one's do (`tap`): the same shape, both on
    /// the short road.
    pub fn shares_taps_with(&self, other: &Texture) -> bool {
        self.repeats && other.repeats && self.size() == other.size()
    }

    /// The texels' mean: the 1 x 1 level.
    fn mean(&self) -> Vec4 {
        match self.levels.last() {
            Some(last) if !last.texels.is_empty() => widen(last.texels[0]) * (1.0 / TEXEL_ONE),
            _ => Vec4::ONE,
        }
    }

    /// Where `sample` reads for a repeating texture (`repeats`), as `sample` chooses the
    /// level; None for a UV that is not finite (the caller reads the mean).
    #[inline]
    pub fn tap(&self, uv: Vec2, footprint: f32) -> Option<Tap> {
        if !uv.is_finite() {
            return None;
        }
        // `floor`, not glam's, which calls libm's floorf on x86-64 without SSE4.1.
        let uv = uv - Vec2::new(floor(uv.x), floor(uv.y));
        let level = self.level_at(uv, footprint);
        if level + 1 == self.levels.len() {
            // The 1 x 1 level: its one texel (most hits past a rough bounce).
            return Some(Tap {
                level,
                corners: [0; 4],
                fx: 0.0,
                fy: 0.0,
                coarsest: true,
            });
        }
        let mip = &self.levels[level];
        // uv is in [0, 1] (1 where a tiny negative rounds up), so p = uv size + 0.5, one
        // more than the tap's texel coordinate, lies in [0.5, size + 0.5]: truncating it
        // floors it, and the texel columns are x - 1 and x, wrapped.
        let p = uv * mip.size + 0.5;
        // SAFETY: p is finite, positive and under 2^23 + 1 (`repeats` bounds the sizes),
        // so it fits an i32; the bounds are checked before this (uv is finite) or hold by
        // construction. An i32, not a u32: SSE2 converts i32 and f32 both ways in one
        // instruction, where a u32 took six (callgrind).
        let (x, y) = unsafe { (p.x.to_int_unchecked::<i32>(), p.y.to_int_unchecked::<i32>()) };
        let (fx, fy) = (p.x - x as f32, p.y - y as f32);
        let (x, y) = (x as u32, y as u32);
        let (width, height) = (mip.width, mip.height);
        let left = if x == 0 { width - 1 } else { x - 1 };
        let right = if x >= width { 0 } else { x };
        let upper = if y == 0 { height - 1 } else { y - 1 };
        let lower = if y >= height { 0 } else { y };
        let (upper, lower) = ((upper * width) as usize, (lower * width) as usize);
        let (left, right) = (left as usize, right as usize);
        Some(Tap {
            level,
            corners: [upper + left, upper + right, lower + left, lower + right],
            fx,
            fy,
            coarsest: false,
        })
    }

    /// The bilinear value at `tap` (from `tap` on this texture or one it
    /// `shares_taps_with`).
    #[inline]
    pub fn read(&self, tap: &Tap) -> Vec4 {
        let texels = &self.levels[tap.level].texels;
        let [upper_left, upper_right, lower_left, lower_right] =
            tap.corners.map(|i| widen(texels[i]));
        let top = upper_left.lerp(upper_right, tap.fx);
        let bottom = lower_left.lerp(lower_right, tap.fx);
        top.lerp(bottom, tap.fy) * (1.0 / TEXEL_ONE)
    }

    /// The bilinear (or, for `Filter::Nearest`, the nearest) tap of one level.
    #[inline]
    fn sample_level(&self, level: usize, uv: Vec2) -> Vec4 {
        let mip = &self.levels[level];
        // Past +-2^24 texels an f32 holds no fraction: clamping there keeps the index
        // arithmetic below far from i64's ends for any UV a file or a transform makes.
        const LIMIT: f32 = 16_777_216.0;
        let p = (uv * mip.size - 0.5).clamp(Vec2::splat(-LIMIT), Vec2::splat(LIMIT));
        if self.filter == Filter::Nearest {
            let texel = self.texel(mip, floor(p.x + 0.5) as i64, floor(p.y + 0.5) as i64);
            return widen(texel) * (1.0 / TEXEL_ONE);
        }
        // A NaN UV clamps to NaN and indexes texel (0, 0) with a NaN weight: the caller's
        // finiteness checks drop the path.
        let (x0, y0) = (floor(p.x), floor(p.y));
        let (fx, fy) = (p.x - x0, p.y - y0);
        let (left, right) = wrap_pair(x0 as i64, mip.width as i64, self.wrap_u);
        let (upper, lower) = wrap_pair(y0 as i64, mip.height as i64, self.wrap_v);
        let (upper, lower) = (upper * mip.width as usize, lower * mip.width as usize);
        let texels = &mip.texels;
        let top = widen(texels[upper + left]).lerp(widen(texels[upper + right]), fx);
        let bottom = widen(texels[lower + left]).lerp(widen(texels[lower + right]), fx);
        top.lerp(bottom, fy) * (1.0 / TEXEL_ONE)
    }

    fn texel(&self, mip: &MipLevel, x: i64, y: i64) -> [u16; 4] {
        let x = wrap(x, mip.width as i64, self.wrap_u);
        let y = wrap(y, mip.height as i64, self.wrap_v);
        mip.texels[(y * mip.width as i64 + x) as usize]
    }
}

impl MipLevel {
    fn new(width: u32, height: u32, texels: Vec<[u16; 4]>) -> MipLevel {
        MipLevel {
            width,
            height,
            size: Vec2::new(width as f32, height as f32),
            texels,
        }
    }

    /// The next level down: half the size (at least 1), each texel the mean of those it
    /// covers.
    fn halved(&self) -> MipLevel {
        let (width, height) = ((self.width / 2).max(1), (self.height / 2).max(1));
        let mut texels = Vec::with_capacity(width as usize * height as usize);
        let span = |i: u32, new: u32, old: u32| 2 * i..if i + 1 == new { old } else { 2 * i + 2 };
        for y in 0..height {
            let rows = span(y, height, self.height);
            for x in 0..width {
                let columns = span(x, width, self.width);
                let mut sum = Vec4::ZERO;
                let mut count = 0.0;
                for row in rows.clone() {
                    for column in columns.clone() {
                        sum += widen(self.texels[(row * self.width + column) as usize]);
                        count += 1.0;
                    }
                }
                texels.push(quantise(sum / (count * TEXEL_ONE)));
            }
        }
        MipLevel::new(width, height, texels)
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
        // SAFETY: |x| < 2^23 fits an i32 (`as i32` would also test for NaN and saturate:
        // six instructions more, three floors a texture tap).
        let truncated = unsafe { x.to_int_unchecked::<i32>() } as f32;
        // Truncation rounds a negative fraction up: step it down. Every floor has its
        // argument's sign, which keeps floor(-0.0) = -0.0.
        (truncated - f32::from(u8::from(truncated > x))).copysign(x)
    } else {
        x
    }
}

/// A number in [0, 1) from where `uv` (in its first period) falls on a 4096 x 4096 grid:
/// UVs a grid step apart give unrelated numbers, and UVs that differ by rounding almost
/// always the same one. (Hashing the UV's bits, a skinned mesh and the same pose baked
/// static chose different levels wherever their UVs differed in the last bit: 0.4% RMSE
/// between two renders that should agree to rounding.)
#[inline]
fn uv_hash(uv: Vec2) -> f32 {
    let cell = uv * 4096.0;
    let (x, y) = (cell.x as u32, cell.y as u32);
    let mut h = x.wrapping_mul(0x9e37_79b1) ^ y.wrapping_mul(0x85eb_ca77);
    h ^= h >> 15;
    h = h.wrapping_mul(0xc2b2_ae3d);
    h ^= h >> 13;
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// A texture coordinate moved by whole periods of `mode` into [0, 1) (repeat) or [0, 2)
/// (mirrored repeat); clamped coordinates are left as they are.
#[inline]
fn into_first_period(u: f32, mode: Wrap) -> f32 {
    match mode {
        Wrap::ClampToEdge => u,
        Wrap::Repeat => u - floor(u),
        Wrap::MirroredRepeat => u - 2.0 * floor(0.5 * u),
    }
}

/// Texel indices `i` and `i + 1` on an axis `n` texels long, wrapped by `mode`: inside
/// the texture, as they are (most taps, once the UV is in its first period).
#[inline(always)]
fn wrap_pair(i: i64, n: i64, mode: Wrap) -> (usize, usize) {
    if i >= 0 && i + 1 < n {
        return (i as usize, i as usize + 1);
    }
    (wrap(i, n, mode) as usize, wrap(i + 1, n, mode) as usize)
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
    /// Tangent-space normals, their x and y scaled by `normal_scale` (glTF's
    /// `normalTexture`).
    pub normal_texture: Option<TextureSlot>,
    pub normal_scale: f32,
    /// The base colour and normal textures are read with one tap (`Texture::tap`): both
    /// present, with one UV transform, and of one shape on the short road
    /// (`Texture::shares_taps_with`). Worked out once, where the material is made
    /// (`RenderMaterial::pairs_taps`): asking at every hit, and reading a footprint over the
    /// whole texture with two taps, cost first-light 1.4% of its frame's instructions
    /// (callgrind, 320 x 180).
    pub paired_tap: bool,
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

    fn sample(slot: Option<TextureSlot>, textures: &[Texture], uv: Vec2, footprint: f32) -> Vec4 {
        match slot {
            Some(slot) => textures[slot.texture as usize]
                .sample(slot.uv_transform.transform_point2(uv), footprint),
            None => Vec4::ONE,
        }
    }

    /// Base colour and coverage at `uv`, for a ray cone's `footprint` (`Texture::sample`).
    pub fn base_color_at(&self, textures: &[Texture], uv: Vec2, footprint: f32) -> Vec4 {
        self.base_color * Self::sample(self.base_color_texture, textures, uv, footprint)
    }

    /// The fraction of light the surface reflects or transmits at `uv`, ignoring its lobe's
    /// shape: what the denoiser divides illumination by (SVGF's demodulation). Glass and
    /// metal take their Fresnel-free weights: base colour for metal and diffuse, 1 for glass.
    pub fn albedo_at(&self, textures: &[Texture], uv: Vec2, footprint: f32) -> Vec3 {
        self.albedo_of(self.base_color_at(textures, uv, footprint).truncate())
    }

    /// `albedo_at` from the base colour already read there.
    pub fn albedo_of(&self, base: Vec3) -> Vec3 {
        let glass = self.transmission.clamp(0.0, 1.0) * (1.0 - self.metallic.clamp(0.0, 1.0));
        base.lerp(Vec3::ONE, glass)
    }

    /// Emitted radiance at `uv` from the front (and from the back when double-sided),
    /// read at level 0: light sampling, which also asks, has no cone.
    pub fn emission_at(&self, textures: &[Texture], uv: Vec2) -> Vec3 {
        if !self.is_emissive() {
            return Vec3::ZERO;
        }
        self.emissive * Self::sample(self.emissive_texture, textures, uv, FINEST).truncate()
    }

    /// Is the point solid for rays (alpha mask)? Blend is treated as a mask at 0.5. Read
    /// at level 0: a ray's visibility must not depend on where it came from.
    pub fn is_opaque_at(&self, textures: &[Texture], uv: Vec2) -> bool {
        match self.alpha_mode {
            AlphaMode::Opaque => true,
            AlphaMode::Mask { cutoff } => self.base_color_at(textures, uv, FINEST).w >= cutoff,
            AlphaMode::Blend => self.base_color_at(textures, uv, FINEST).w >= 0.5,
        }
    }

    /// The tangent-space normal at `uv` (x along the surface's +u, y along its -v, z out of
    /// it; not normalised), or None without a normal texture or where it is flat.
    pub fn normal_at(&self, textures: &[Texture], uv: Vec2, footprint: f32) -> Option<Vec3> {
        let slot = self.normal_texture?;
        // A footprint over the whole texture sees its mean normal, flat for a height field
        // that tiles (its slopes sum to zero over a period): not read, as past most rough
        // bounces.
        if textures[slot.texture as usize].is_covered_by(footprint) {
            return None;
        }
        Some(self.decode_normal(Self::sample(Some(slot), textures, uv, footprint)))
    }

    /// A normal texture's filtered value as a tangent-space normal, not normalised (a
    /// filtered texel of differing normals is short; `shading_frame` normalises once).
    fn decode_normal(&self, stored: Vec4) -> Vec3 {
        let scale = Vec3::new(self.normal_scale, self.normal_scale, 1.0);
        (stored.truncate() * 2.0 - Vec3::ONE) * scale
    }

    /// Whether this material's base colour and normal textures can share one tap
    /// (`paired_tap`), over the scene's `textures`.
    pub fn pairs_taps(&self, textures: &[Texture]) -> bool {
        match (self.base_color_texture, self.normal_texture) {
            (Some(base), Some(normal)) => {
                base.uv_transform == normal.uv_transform
                    && textures[base.texture as usize]
                        .shares_taps_with(&textures[normal.texture as usize])
            }
            _ => false,
        }
    }

    /// `base_color_at` and `normal_at` together: where the two textures share a tap
    /// (`paired_tap`: every kit material), read with one tap's index arithmetic.
    pub fn base_and_normal_at(
        &self,
        textures: &[Texture],
        uv: Vec2,
        footprint: f32,
    ) -> (Vec4, Option<Vec3>) {
        if self.paired_tap
            && let (Some(base), Some(normal)) = (self.base_color_texture, self.normal_texture)
        {
            let base_texture = &textures[base.texture as usize];
            if let Some(tap) = base_texture.tap(base.uv_transform.transform_point2(uv), footprint) {
                let colour = self.base_color * base_texture.read(&tap);
                // A footprint over the whole texture sees its mean normal: flat
                // (`normal_at`).
                let normal = (!tap.coarsest)
                    .then(|| self.decode_normal(textures[normal.texture as usize].read(&tap)));
                return (colour, normal);
            }
        }
        (
            self.base_color_at(textures, uv, footprint),
            self.normal_at(textures, uv, footprint),
        )
    }

    /// The BSDF lobe to use at `uv`, whose base colour (`base_color_at`, already read
    /// there) is `base`: one of the mixture's lobes, chosen with `u_lobe` with probability
    /// equal to its weight. `entering` says `wo` is on the front side.
    pub fn bsdf_with_base(
        &self,
        base: Vec3,
        textures: &[Texture],
        uv: Vec2,
        footprint: f32,
        u_lobe: f32,
        entering: bool,
    ) -> Bsdf {
        // Roughness and metalness shape only the conductor lobe: a material whose
        // metallic factor is 0 (stone, wood, cloth) never reads its metallic-roughness
        // texture.
        let mut metallic = 0.0;
        if self.metallic > 0.0 {
            let metal_rough =
                Self::sample(self.metallic_roughness_texture, textures, uv, footprint);
            metallic = (self.metallic * metal_rough.z).clamp(0.0, 1.0);
            let roughness = (self.roughness * metal_rough.y).clamp(0.0, 1.0);
            if u_lobe < metallic {
                return Bsdf::Conductor {
                    f0: base,
                    alpha: roughness * roughness,
                };
            }
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
            .map(|i| Vec4::new(i as f32 / 15.0, (i * i % 7) as f32 / 7.0, 1.0, 0.5))
            .collect();
        for (wrap_u, wrap_v) in [
            (Wrap::Repeat, Wrap::ClampToEdge),
            (Wrap::MirroredRepeat, Wrap::Repeat),
            (Wrap::ClampToEdge, Wrap::MirroredRepeat),
        ] {
            let texture = Texture::from_texels(
                width,
                height,
                texels.clone(),
                wrap_u,
                wrap_v,
                Filter::Linear,
            );
            let level = &texture.levels[0];
            for k in 0..200 {
                let uv = Vec2::new(k as f32 * 0.0731 - 7.3, k as f32 * -0.0517 + 5.1);
                let (x, y) = (uv.x * 5.0 - 0.5, uv.y * 3.0 - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let texel = |x, y| widen(texture.texel(level, x, y)) / TEXEL_ONE;
                let top = texel(x0, y0).lerp(texel(x0 + 1, y0), fx);
                let bottom = texel(x0, y0 + 1).lerp(texel(x0 + 1, y0 + 1), fx);
                // Equal but for the rounding of moving the UV into the first period.
                let expected = top.lerp(bottom, fy);
                let close = |a: Vec4| (a - expected).abs().max_element() < 1e-4;
                assert!(close(texture.sample(uv, FINEST)), "uv {uv}");
                // A footprint no wider than a texel reads level 0 the same way.
                assert_eq!(
                    texture.sample(uv, -4.0),
                    texture.sample(uv, FINEST),
                    "uv {uv}"
                );
            }
        }
    }

    /// Each level is half the one before down to 1 x 1, every texel the mean of those it
    /// covers, so every level keeps the image's mean; odd sizes fold their last row and
    /// column in.
    #[test]
    fn the_pyramid_keeps_the_mean_at_every_level() {
        for (width, height) in [(8u32, 8u32), (5, 3), (1, 6), (16, 2)] {
            let texels: Vec<Vec4> = (0..width * height)
                .map(|i| Vec4::splat(((i * 37) % 11) as f32 / 10.0))
                .collect();
            let mean = texels.iter().sum::<Vec4>() / texels.len() as f32;
            let texture = Texture::from_texels(
                width,
                height,
                texels,
                Wrap::Repeat,
                Wrap::Repeat,
                Filter::Linear,
            );
            let last = texture.levels.last().unwrap();
            assert_eq!((last.width, last.height), (1, 1), "{width} x {height}");
            for pair in texture.levels.windows(2) {
                assert_eq!(pair[1].width, (pair[0].width / 2).max(1));
                assert_eq!(pair[1].height, (pair[0].height / 2).max(1));
            }
            let last_value = widen(last.texels[0]) / TEXEL_ONE;
            if width.is_power_of_two() && height.is_power_of_two() {
                assert!(
                    (last_value - mean).abs().max_element() < 1e-4,
                    "{width} x {height}"
                );
            }
            // A footprint as wide as the texture reads the last level, everywhere.
            let far = texture.sample(Vec2::new(0.3, 0.7), 2.0);
            assert!((far - last_value).abs().max_element() < 1e-6);
        }
    }

    /// Between two levels a tap reads one of them, the coarser with the footprint's
    /// fraction for its probability: over many taps, the trilinear blend; at a whole
    /// level, that level.
    #[test]
    fn taps_between_levels_average_to_the_trilinear_blend() {
        let texels: Vec<Vec4> = (0..64u32)
            .map(|i| Vec4::splat(((i * 7) % 5) as f32 / 4.0))
            .collect();
        let texture =
            Texture::from_texels(8, 8, texels, Wrap::Repeat, Wrap::Repeat, Filter::Linear);
        let uv = Vec2::new(0.3, 0.6);
        // log2_size is 3: footprint -2 is level 1, -1.75 is level 1.25.
        assert_eq!(texture.sample(uv, -2.0), texture.sample_level(1, uv));
        let taps = 4000;
        let (mut stochastic, mut trilinear) = (Vec4::ZERO, Vec4::ZERO);
        let mut coarser = 0;
        for i in 0..taps {
            let uv = uv + Vec2::new(i as f32 * 7.31e-4, i as f32 * 4.17e-4);
            let uv = uv - uv.floor();
            let tap = texture.sample(uv, -1.75);
            let (level_1, level_2) = (texture.sample_level(1, uv), texture.sample_level(2, uv));
            let near = |a: Vec4, b: Vec4| (a - b).abs().max_element() < 1e-5;
            assert!(
                near(tap, level_1) || near(tap, level_2),
                "one level or the other"
            );
            coarser += usize::from(near(tap, level_2) && !near(level_1, level_2));
            stochastic += tap;
            trilinear += level_1.lerp(level_2, 0.25);
        }
        let (stochastic, trilinear) = (stochastic / taps as f32, trilinear / taps as f32);
        assert!(
            (stochastic - trilinear).abs().max_element() < 0.02,
            "mean {stochastic}, trilinear {trilinear}"
        );
        // A quarter of the taps, less those where the two levels agree.
        assert!(
            (500..1200).contains(&coarser),
            "{coarser} of {taps} read the coarser level"
        );
    }
}
