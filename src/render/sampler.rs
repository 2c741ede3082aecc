//! Frame step `render`: the random numbers of every path.
//!
//! The integrator asks a `PixelSampler` only for the next 1D or 2D value; which values it
//! gets depends on the kind:
//! - `White`: independent uniform values (a hash of seed, frame, pixel, sample, dimension).
//! - `Stratified`: per pixel and dimension the N samples of a pixel are jittered strata,
//!   shuffled by a per-(pixel, dimension) permutation so dimensions are decorrelated
//!   (Kensler 2013, "Correlated Multi-Jittered Sampling"); 2D values are N-rooks (Shirley
//!   1991) or jittered grids when N is a square.
//! - `BlueNoise`: a void-and-cluster blue-noise mask (Ulichney 1993) read at the pixel,
//!   toroidally shifted per dimension, plus a rank-1 sequence over the sample index
//!   (Roberts 2018, "The unreasonable effectiveness of quasirandom sequences"), so one
//!   sample per pixel spreads its error as blue noise over the screen (Georgiev & Fajardo
//!   2016, "Blue-noise dithered sampling") and successive frames decorrelate.
//!
//! Determinism (the project's rule): every value derives from (seed, frame, pixel, sample index,
//! dimension) alone, so images are identical on any thread count.

use glam::Vec2;

use super::blue_noise::BlueNoiseMask;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SamplerKind {
    White,
    Stratified,
    BlueNoise,
}

impl SamplerKind {
    pub fn name(self) -> &'static str {
        match self {
            SamplerKind::White => "white",
            SamplerKind::Stratified => "stratified",
            SamplerKind::BlueNoise => "blue",
        }
    }
}

/// Values for one sample of one pixel. Cheap to create: one per pixel sample.
pub struct PixelSampler<'a> {
    kind: SamplerKind,
    pixel: (u32, u32),
    pixel_hash: u32,
    /// Hash of (pixel, sample index), computed once: each white value then costs two
    /// mixing rounds instead of three chained ones per dimension (sampling was 29% of a
    /// Cornell render).
    sample_hash: u32,
    /// Index of this sample among all the pixel's samples over all frames.
    sample_index: u32,
    /// Samples per pixel over the whole render (the stratification count).
    sample_count: u32,
    dimension: u32,
    blue: Option<&'a BlueNoise<'a>>,
}

/// Dimensions whose keys a `BlueNoise` holds ready: a real-time path (max depth 4) draws
/// 2 at the camera and 6 a vertex, 26 in all; deeper paths hash the rest as they go.
const KEYED_DIMENSIONS: usize = 32;

/// The blue-noise sampler's mask and, for one seed, each dimension's keys: where the
/// dimension reads the mask and how it pads the sample index. The keys depend on (seed,
/// dimension) alone, so a render hashes them once here instead of at every pixel sample
/// (with them hashed per sample, sampling took 15% of a 640x360 real-time frame's CPU
/// time; 5% since).
pub struct BlueNoise<'a> {
    mask: &'a BlueNoiseMask,
    seed: u32,
    keys: [DimensionKeys; KEYED_DIMENSIONS],
}

impl<'a> BlueNoise<'a> {
    pub fn new(mask: &'a BlueNoiseMask, seed: u32) -> Self {
        BlueNoise {
            mask,
            seed,
            keys: std::array::from_fn(|dimension| DimensionKeys::of(dimension as u32, seed)),
        }
    }

    #[inline]
    fn keys(&self, dimension: u32) -> DimensionKeys {
        match self.keys.get(dimension as usize) {
            Some(keys) => *keys,
            None => DimensionKeys::of(dimension, self.seed),
        }
    }
}

/// One dimension's blue-noise keys (`BlueNoise`).
#[derive(Clone, Copy, Debug)]
struct DimensionKeys {
    /// Toroidal shifts of the mask (x in the low 16 bits, y in the high), for a 1D value
    /// or a 2D value's x, and for a 2D value's y.
    shifts: [u32; 2],
    /// The permutation pattern that pads the sample index (`PixelSampler::padded_index`).
    padding: u32,
}

impl DimensionKeys {
    fn of(dimension: u32, seed: u32) -> Self {
        let shift = |dimension| hash3(dimension, seed, 0xb10e_0001);
        DimensionKeys {
            shifts: [shift(dimension), shift(dimension ^ 0x00ff_0000)],
            padding: hash3(dimension, seed, 0x600d_5eed),
        }
    }
}

impl<'a> PixelSampler<'a> {
    /// Sample `sample_index` of `sample_count` for `pixel`; `frame` offsets the index so
    /// frames rendered one after another continue the sequence.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        kind: SamplerKind,
        blue: Option<&'a BlueNoise<'a>>,
        seed: u32,
        frame: u32,
        pixel: (u32, u32),
        sample_index: u32,
        sample_count: u32,
    ) -> Self {
        debug_assert!(
            kind != SamplerKind::BlueNoise || blue.is_some_and(|blue| blue.seed == seed),
            "blue noise needs its mask and keys, for this seed"
        );
        let pixel_hash = hash3(pixel.0, pixel.1, seed);
        let sample_index = frame.wrapping_mul(sample_count).wrapping_add(sample_index);
        PixelSampler {
            kind,
            pixel,
            pixel_hash,
            sample_hash: mix(pixel_hash ^ sample_index.wrapping_mul(0x9e37_79b9)),
            sample_index,
            sample_count: sample_count.max(1),
            dimension: 0,
            blue,
        }
    }

    /// The next value in [0, 1).
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        let dimension = self.next_dimension();
        match self.kind {
            SamplerKind::White => self.white(dimension),
            SamplerKind::Stratified => {
                let n = self.sample_count;
                let stratum = permute(
                    self.sample_index % n,
                    n,
                    self.pattern(dimension, 0x5a5a_0001),
                );
                to_unit((stratum as f32 + self.white(dimension)) / n as f32)
            }
            SamplerKind::BlueNoise => {
                // Golden-ratio rank-1 sequence over the (per-dimension shuffled) sample index,
                // shifted per pixel by the blue-noise mask (a Cranley-Patterson rotation).
                let (blue, keys) = self.blue_keys(dimension);
                let index = self.padded_index(keys.padding);
                fixed_to_unit(
                    self.mask_value(blue, keys.shifts[0])
                        .wrapping_add(index.wrapping_mul(GOLDEN_FIXED)),
                )
            }
        }
    }

    /// The next pair of values in [0, 1)^2 (for directions, light points, lens, jitter).
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        match self.kind {
            SamplerKind::White => Vec2::new(self.next_1d(), self.next_1d()),
            SamplerKind::Stratified => {
                let dimension = self.next_dimension();
                let n = self.sample_count;
                let index = permute(
                    self.sample_index % n,
                    n,
                    self.pattern(dimension, 0x5a5a_0002),
                );
                let jitter = Vec2::new(
                    self.white(dimension.wrapping_add(0x4000_0000)),
                    self.white(dimension.wrapping_add(0x8000_0000)),
                );
                let side = (n as f32).sqrt() as u32;
                if side * side == n {
                    // Jittered grid.
                    let cell = Vec2::new((index % side) as f32, (index / side) as f32);
                    ((cell + jitter) / side as f32)
                        .clamp(Vec2::ZERO, Vec2::splat(ONE_MINUS_EPSILON))
                } else {
                    // N-rooks: x and y strata under independent permutations.
                    let y = permute(
                        self.sample_index % n,
                        n,
                        self.pattern(dimension, 0x5a5a_0003),
                    );
                    Vec2::new(
                        to_unit((index as f32 + jitter.x) / n as f32),
                        to_unit((y as f32 + jitter.y) / n as f32),
                    )
                }
            }
            SamplerKind::BlueNoise => {
                let dimension = self.next_dimension();
                let (blue, keys) = self.blue_keys(dimension);
                let index = self.padded_index(keys.padding);
                // R2 sequence: alpha = (1/g, 1/g^2), g the plastic number 1.3247...
                let x = self
                    .mask_value(blue, keys.shifts[0])
                    .wrapping_add(index.wrapping_mul(R2_FIXED[0]));
                let y = self
                    .mask_value(blue, keys.shifts[1])
                    .wrapping_add(index.wrapping_mul(R2_FIXED[1]));
                Vec2::new(fixed_to_unit(x), fixed_to_unit(y))
            }
        }
    }

    /// The sample index, shuffled within each block of `sample_count` by a permutation that
    /// differs per dimension ("padding", pbrt-v4 section 8.7): every dimension still visits
    /// the same well-spread set of sequence points, but in an order uncorrelated with the
    /// other dimensions'. Without it, two dimensions of a pixel would be perfectly
    /// correlated and a pixel would integrate along a line instead of over its domain.
    /// `pattern` is the dimension's `DimensionKeys::padding`.
    #[inline]
    fn padded_index(&self, pattern: u32) -> u32 {
        let n = self.sample_count;
        if n == 1 {
            // Blocks of one: nothing to shuffle (and no division in the real-time path).
            return self.sample_index;
        }
        let block = self.sample_index / n;
        block
            .wrapping_mul(n)
            .wrapping_add(permute(self.sample_index % n, n, pattern))
    }

    fn next_dimension(&mut self) -> u32 {
        let dimension = self.dimension;
        self.dimension += 1;
        dimension
    }

    #[inline]
    fn white(&self, dimension: u32) -> f32 {
        // Two rounds over a Weyl-sequence key: one round left the 2D jitter's x and y
        // (dimension keys differing in their top bits) measurably correlated.
        let h = mix(mix(self
            .sample_hash
            .wrapping_add(dimension.wrapping_mul(0x9e37_79b9))));
        (h >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// The permutation pattern of one stratified dimension (fixed per pixel).
    #[inline]
    fn pattern(&self, dimension: u32, salt: u32) -> u32 {
        mix(self.pixel_hash ^ dimension.wrapping_mul(0xc2b2_ae35) ^ salt)
    }

    /// The blue-noise mask and `dimension`'s keys.
    #[inline]
    fn blue_keys(&self, dimension: u32) -> (&'a BlueNoise<'a>, DimensionKeys) {
        let blue = self.blue.expect("blue-noise sampler has its mask and keys");
        (blue, blue.keys(dimension))
    }

    /// The mask at this pixel (0.32 fixed point), toroidally shifted by one of a
    /// dimension's `shifts` so dimensions see decorrelated (but each blue) patterns.
    #[inline]
    fn mask_value(&self, blue: &BlueNoise, shift: u32) -> u32 {
        blue.mask.value_fixed(
            self.pixel.0.wrapping_add(shift & 0xffff),
            self.pixel.1.wrapping_add(shift >> 16),
        )
    }
}

const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Rank-1 steps in 0.32 fixed point, so index x step stays exact for any index (an f32
/// product loses the fraction after a few thousand samples): the golden ratio's fraction
/// 0.6180339887 and R2's (0.7548776662, 0.5698402910).
const GOLDEN_FIXED: u32 = 2_654_435_769;
const R2_FIXED: [u32; 2] = [3_242_174_889, 2_447_445_414];

fn fixed_to_unit(fixed: u32) -> f32 {
    to_unit((fixed >> 8) as f32 * (1.0 / (1u32 << 24) as f32))
}

fn to_unit(x: f32) -> f32 {
    x.min(ONE_MINUS_EPSILON)
}

/// One round of Chris Wellons's lowbias32 integer hash (a bijection on u32).
#[inline]
fn mix(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// A 32-bit hash of three words (lowbias32 rounds, chained).
#[inline]
pub fn hash3(a: u32, b: u32, c: u32) -> u32 {
    mix(mix(mix(a) ^ b.wrapping_add(0x9e37_79b9)) ^ c.wrapping_add(0x85eb_ca6b))
}

/// A pseudo-random permutation of [0, n) chosen by `pattern` (Kensler 2013, listing 3):
/// cycle-walking over a bijective hash on the next power of two.
pub fn permute(mut index: u32, n: u32, pattern: u32) -> u32 {
    if n <= 1 {
        return 0;
    }
    let mut w = n - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
        index ^= pattern;
        index = index.wrapping_mul(0xe170_893d);
        index ^= pattern >> 16;
        index ^= (index & w) >> 4;
        index ^= pattern >> 8;
        index = index.wrapping_mul(0x0929_eb3f);
        index ^= pattern >> 23;
        index ^= (index & w) >> 1;
        index = index.wrapping_mul(1 | pattern >> 27);
        index = index.wrapping_mul(0x6935_fa69);
        index ^= (index & w) >> 11;
        index = index.wrapping_mul(0x74dc_b303);
        index ^= (index & w) >> 2;
        index = index.wrapping_mul(0x9e50_1cc3);
        index ^= (index & w) >> 2;
        index = index.wrapping_mul(0xc860_a3df);
        index &= w;
        index ^= index >> 5;
        if index < n {
            return (index.wrapping_add(pattern)) % n;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn permutations_are_bijections() {
        for n in [1u32, 2, 3, 7, 16, 100, 257] {
            for pattern in [0u32, 1, 0xdead_beef] {
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let p = permute(i, n, pattern) as usize;
                    assert!(!seen[p], "n={n} pattern={pattern}: {p} twice");
                    seen[p] = true;
                }
            }
        }
    }

    #[test]
    fn stratified_1d_puts_one_sample_per_stratum() {
        let n = 16;
        for dimension_skip in 0..3 {
            let mut strata = vec![0; n as usize];
            for s in 0..n {
                let mut sampler =
                    PixelSampler::new(SamplerKind::Stratified, None, 7, 0, (3, 5), s, n);
                for _ in 0..dimension_skip {
                    sampler.next_1d();
                }
                let v = sampler.next_1d();
                assert!((0.0..1.0).contains(&v));
                strata[(v * n as f32) as usize] += 1;
            }
            assert!(strata.iter().all(|&c| c == 1), "{strata:?}");
        }
    }

    #[test]
    fn stratified_2d_is_a_jittered_grid_for_square_counts() {
        let n = 16;
        let mut cells = vec![0; 16];
        for s in 0..n {
            let mut sampler = PixelSampler::new(SamplerKind::Stratified, None, 1, 0, (0, 0), s, n);
            let v = sampler.next_2d();
            cells[(v.y * 4.0) as usize * 4 + (v.x * 4.0) as usize] += 1;
        }
        assert!(cells.iter().all(|&c| c == 1), "{cells:?}");
    }

    #[test]
    fn blue_noise_dimensions_are_decorrelated_across_samples() {
        // Two dimensions of one pixel over 256 samples must fill the square, not a line:
        // count occupied cells of a 16 x 16 grid (a line would touch about 16-32).
        let blue = BlueNoise::new(crate::render::blue_noise::BlueNoiseMask::shipped(), 0);
        let n = 256;
        let mut cells = std::collections::HashSet::new();
        for s in 0..n {
            let mut sampler =
                PixelSampler::new(SamplerKind::BlueNoise, Some(&blue), 0, 0, (5, 9), s, n);
            let (a, b) = (sampler.next_1d(), sampler.next_1d());
            cells.insert(((a * 16.0) as u32, (b * 16.0) as u32));
        }
        assert!(
            cells.len() > 140,
            "only {} of 256 cells occupied",
            cells.len()
        );
    }

    #[test]
    fn white_values_are_uniform_and_deterministic() {
        let mut sum = 0.0;
        for s in 0..10_000 {
            let mut sampler =
                PixelSampler::new(SamplerKind::White, None, 3, 0, (s % 100, s / 100), 0, 1);
            let v = sampler.next_1d();
            assert!((0.0..1.0).contains(&v));
            sum += v as f64;
            let mut again =
                PixelSampler::new(SamplerKind::White, None, 3, 0, (s % 100, s / 100), 0, 1);
            assert_eq!(again.next_1d(), v);
        }
        assert!((sum / 10_000.0 - 0.5).abs() < 0.01);
    }
}
