//! Frame step `render`: the random numbers of every path.
//!
//! The integrator asks a `PixelSampler` only for the next 1D or 2D value; which values it
//! gets depends on the kind:
//! - `White`: independent uniform values (a hash of seed, frame, pixel, sample, dimension).
//! - `Stratified`: per pixel and dimension the N samples of a pixel are jittered strata,
//!   shuffled by a per-(pixel, dimension) permutation so dimensions are decorrelated
//!   (Kensler 2013, "Correlated Multi-Jittered Sampling"); 2D values are N-rooks (Shirley
//!   1991) or jittered grids when N is a square.
//! - `BlueNoise`: error spread as blue noise over the screen for whole paths, after Ahmed
//!   & Wonka 2020 ("Screen-space blue-noise diffusion of Monte Carlo sampling error via
//!   hierarchical ordering of pixels", SIGGRAPH Asia): every pixel draws from one
//!   image-wide Sobol' (0,2)-sequence, sample s of pixel p at index z(p) N + s (z a Morton
//!   order, N the samples per pixel rounded up to a power of two), so every aligned
//!   2^k x 2^k tile of pixels owns a whole (0,2k,2)-net (at 1 spp) in every 2D dimension
//!   and 4^k strata in every 1D one. Each dimension Owen-scrambles the index ("padding":
//!   a nested scramble keeps aligned blocks aligned) and its values, with Laine & Karras
//!   2011's hash as Burley 2020 gives it ("Practical hash-based Owen scrambling", JCGT
//!   9(4)). The pixel jitter (the first 2D dimension) is instead a shifted lattice,
//!   golden-ratio steps along rows and columns (`PixelSampler::pixel_jitter`), since edges
//!   need their run of pixels evenly covered rather than a tile stratified. Each frame
//!   scrambles anew, and steps the jitter's shift along the R2 sequence. On the Cornell
//!   box at max depth 64 (`gloam convergence`), the 1-spp error's low-band power is 0.26
//!   of white's (per-dimension blue-noise masks, Georgiev & Fajardo 2016, give 0.99), and
//!   16 spp has 0.68 of stratified's RMSE.
//!
//! A wavefront's paths reach each vertex together, so the renderer draws that vertex's
//! values (`VertexDraws`) for all of them at once (`VertexDrawBatch`): the blue-noise
//! hashes in AVX2 lanes (`HashLanes`, reversing bits with GFNI where the CPU has it), the
//! same values a path drawing alone gets, and a pinhole camera passes over its lens
//! dimension undrawn: 14% fewer instructions in the render (first-light at 640 x 360,
//! rendered at half scale), the same image.
//!
//! Determinism (the project's rule): every value derives from (seed, frame, pixel, sample index,
//! dimension) alone, so images are identical on any thread count.

use glam::Vec2;

/// Where each pixel's samples fall (the command line's `--sampler`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SamplerKind {
    /// Independent uniform random numbers.
    White,
    /// Jittered strata per dimension.
    Stratified,
    /// Blue-noise ranked sequences: the error is blue at 1-2 spp.
    #[value(name = "blue")]
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
    blue: Option<&'a BlueNoise>,
    /// `BlueNoise`: this sample's index in the image-wide sequence, bit-reversed (the
    /// form the index scramble takes it in), and what the keys are XORed with (nonzero
    /// only where the index passes 2^32: images beyond 65536 x 65536 pixel-samples).
    sequence_index: u32,
    sequence_salt: u32,
    /// `BlueNoise`: the pixel and the sample's index within it (`PixelSampler::pixel_jitter`).
    pixel: (u32, u32),
    pixel_sample: u32,
}

/// Dimensions whose keys a `BlueNoise` holds ready: a real-time path (max depth 4) draws
/// 2 at the camera and 6 a vertex, 26 in all; deeper paths hash the rest as they go.
const KEYED_DIMENSIONS: usize = 32;

/// The blue-noise sampler's keys for one (seed, frame): each dimension's scramble seeds.
/// They depend on (seed, frame, dimension) alone, so a render hashes them once here
/// instead of at every pixel sample (hashed per sample, sampling took 15% of a 640x360
/// real-time frame's CPU time).
pub struct BlueNoise {
    seed: u32,
    frame: u32,
    keys: [DimensionKeys; KEYED_DIMENSIONS],
    /// The pixel jitter's keys (`PixelSampler::pixel_jitter`): the lattice's shift (a step
    /// of the R2 sequence a frame, so each pixel's jitters over frames are that
    /// low-discrepancy sequence), and the scrambles of the per-pixel sequence's x and y.
    screen: [u32; 4],
    /// The per-pixel sequence's points (`BlueNoise::net`) of the first `HELD_NETS` sample
    /// indices, ready: every pixel of a frame draws its jitter from the same few.
    nets: [[u32; 2]; HELD_NETS],
}

/// Sample indices whose jitter net points a `BlueNoise` holds ready (real-time renders draw
/// one sample a pixel, offline ones up to a few thousand, which hash the rest as they go).
const HELD_NETS: usize = 16;

impl BlueNoise {
    pub fn new(seed: u32, frame: u32) -> Self {
        let key = |part: u32| hash3(part, seed, 0x5c4e_e111);
        let screen = [
            key(0).wrapping_add(frame.wrapping_mul(R2_FIXED[0])),
            key(1).wrapping_add(frame.wrapping_mul(R2_FIXED[1])),
            key(2),
            key(3),
        ];
        BlueNoise {
            seed,
            frame,
            keys: std::array::from_fn(|dimension| DimensionKeys::of(dimension as u32, seed, frame)),
            screen,
            nets: std::array::from_fn(|sample| net_point(sample as u32, screen)),
        }
    }

    /// Sample `sample`'s point of the per-pixel sequence the jitter adds its lattice to.
    #[inline]
    fn net(&self, sample: u32) -> [u32; 2] {
        match self.nets.get(sample as usize) {
            Some(net) => *net,
            None => net_point(sample, self.screen),
        }
    }

    #[inline]
    fn keys(&self, dimension: u32) -> DimensionKeys {
        match self.keys.get(dimension as usize) {
            Some(keys) => *keys,
            None => DimensionKeys::of(dimension, self.seed, self.frame),
        }
    }
}

/// The jitter's per-pixel sequence at `sample` (0.32 fixed point): the Owen-scrambled
/// (0,2)-sequence under the `screen` keys' scrambles.
fn net_point(sample: u32, screen: [u32; 4]) -> [u32; 2] {
    [
        owen_scramble(sample, screen[2]),
        owen_scramble_reversed(sobol_second_reversed(sample), screen[3]),
    ]
}

/// One dimension's Owen-scrambling seeds (`BlueNoise`).
#[derive(Clone, Copy, Debug)]
struct DimensionKeys {
    /// Scrambles the sequence index ("padding"): each dimension pairs the pixels with the
    /// sequence's points in its own order, so dimensions are decorrelated, while aligned
    /// blocks of indices (pixel tiles) still map to aligned blocks (nets).
    index: u32,
    /// Scramble the value of a 1D dimension or a 2D dimension's x, and a 2D dimension's y.
    values: [u32; 2],
}

impl DimensionKeys {
    fn of(dimension: u32, seed: u32, frame: u32) -> Self {
        let key = |salt: u32| hash3(dimension, seed, frame.wrapping_mul(0x2c1b_3c6d) ^ salt);
        DimensionKeys {
            index: key(0x600d_5eed),
            values: [key(0xb10e_0001), key(0xb10e_0002)],
        }
    }
}

impl<'a> PixelSampler<'a> {
    /// Sample `sample_index` of `sample_count` for `pixel`. White and stratified offset the
    /// index by `frame` so frames rendered one after another continue the sequence; blue
    /// noise draws each frame from a differently scrambled sequence (its `BlueNoise` keys).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn new(
        kind: SamplerKind,
        blue: Option<&'a BlueNoise>,
        seed: u32,
        frame: u32,
        pixel: (u32, u32),
        sample_index: u32,
        sample_count: u32,
    ) -> Self {
        debug_assert!(
            kind != SamplerKind::BlueNoise
                || blue.is_some_and(|blue| blue.seed == seed && blue.frame == frame),
            "blue noise needs its keys, for this seed and frame"
        );
        // The pixel's and sample's hashes feed only white and stratified values (five
        // hash rounds a pixel sample that blue noise never reads).
        let hashed = kind != SamplerKind::BlueNoise;
        let pixel_hash = if hashed {
            hash3(pixel.0, pixel.1, seed)
        } else {
            0
        };
        let sample_count = sample_count.max(1);
        let (sequence_index, sequence_salt) = if kind == SamplerKind::BlueNoise {
            reversed_sequence_index(pixel, sample_index, sample_count)
        } else {
            (0, 0)
        };
        let sample_index_in_frame = sample_index;
        let sample_index = frame.wrapping_mul(sample_count).wrapping_add(sample_index);
        PixelSampler {
            kind,
            pixel_hash,
            sample_hash: if hashed {
                mix(pixel_hash ^ sample_index.wrapping_mul(0x9e37_79b9))
            } else {
                0
            },
            sample_index,
            sample_count,
            dimension: 0,
            blue,
            sequence_index,
            sequence_salt,
            pixel,
            pixel_sample: sample_index_in_frame,
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
                // Van der Corput over the scrambled index, Owen-scrambled.
                let keys = self.blue_keys(dimension);
                let index = self.scrambled_index(keys.index);
                bits_to_unit(owen_scramble(index, keys.values[0] ^ self.sequence_salt))
            }
        }
    }

    /// The next pair of values in [0, 1)^2 (for directions, light points, lens, jitter).
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        // A blue-noise sampler's first pair, the pixel jitter every camera ray draws,
        // inline in the caller's loop; the rest of this function is too large to inline,
        // and the call cost as much as the jitter itself.
        if self.kind == SamplerKind::BlueNoise && self.dimension == 0 {
            self.dimension = 1;
            return self.pixel_jitter();
        }
        self.next_2d_drawn()
    }

    /// `next_2d` past a blue-noise sampler's pixel jitter.
    fn next_2d_drawn(&mut self) -> Vec2 {
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
                // The Sobol' (0,2)-sequence's two dimensions over the scrambled index, each
                // Owen-scrambled.
                let dimension = self.next_dimension();
                let keys = self.blue_keys(dimension);
                let index = self.scrambled_index(keys.index);
                let salt = self.sequence_salt;
                Vec2::new(
                    bits_to_unit(owen_scramble(index, keys.values[0] ^ salt)),
                    bits_to_unit(owen_scramble_reversed(
                        sobol_second_reversed(index),
                        keys.values[1] ^ salt,
                    )),
                )
            }
        }
    }

    /// The next path vertex's values (`VertexDraws`), drawn in their order.
    pub fn vertex_draws(&mut self) -> VertexDraws {
        // Struct fields are evaluated in the order written: the order of the dimensions.
        VertexDraws {
            lobe: self.next_1d(),
            pick: self.next_1d(),
            light: self.next_2d(),
            choice: self.next_1d(),
            direction: self.next_2d(),
            roulette: self.next_1d(),
        }
    }

    /// This sample's sequence index under the dimension's nested uniform scramble (seed
    /// `key`): a bijection that maps every aligned block of 2^k indices onto an aligned
    /// block, so a pixel tile still owns a whole net after it ("padding" that keeps the
    /// tiles, where a plain shuffle would break them).
    #[inline]
    fn scrambled_index(&self, key: u32) -> u32 {
        laine_karras(self.sequence_index, key ^ self.sequence_salt).reverse_bits()
    }

    /// The first 2D dimension, the camera's pixel jitter. At one sample a pixel the error
    /// where an edge crosses pixels (an emitter's outline seen from the camera: 91% of the
    /// Cornell box's low-band error power at max depth 64, white) comes from the jitter
    /// alone, and it is blue along the edge only if, for every coverage c, the pixels of a
    /// row whose jitter y falls below c are evenly spread along it (and likewise x down a
    /// column): the row's jitter y must be a 1D dither sequence. The golden ratio's
    /// multiples are the best spread such sequence (Schretter, Kobbelt and Dehaye 2012,
    /// "Golden ratio sequences for low-discrepancy sampling", JGT 16(2)), so the jitter is
    /// a Cranley-Patterson-rotated lattice over the screen: (x/2 + y g, x g + y/2) mod 1
    /// plus a random shift per (seed, frame), g = 0.618...: golden along each row in y and
    /// down each column in x, and neighbours across an edge's other axis half a pixel apart
    /// (antithetic). Every value is uniform; frame f adds f times the R2 step to the
    /// shift, so one pixel's jitters over frames are stratified. Low-band power over
    /// white's at 1 spp on the Cornell box at max depth 0, where only the jitter drives the
    /// error (32 seeds): 0.26 with this lattice, 0.35 with golden rows and columns shifted
    /// by hashes of the row and column, 0.45 with an Owen-scrambled Sobol' net over the
    /// whole screen (every aligned run of a row stratified, but the covered pixels clump
    /// across the runs' borders), 0.75 with the tile order below. A pixel's samples add
    /// this rotation to the Owen-scrambled (0,2)-sequence over the sample index, so they
    /// stay stratified in the pixel.
    #[inline]
    fn pixel_jitter(&self) -> Vec2 {
        let blue = self.blue.expect("blue-noise sampler has its keys");
        let (x, y) = self.pixel;
        let sample = self.pixel_sample & (self.sample_count.next_power_of_two() - 1);
        // (x/2 + y g, x g + y/2) in 0.32 fixed point, g the golden ratio's fraction.
        let rotation_x = (x << 31)
            .wrapping_add(y.wrapping_mul(GOLDEN_FIXED))
            .wrapping_add(blue.screen[0]);
        let rotation_y = x
            .wrapping_mul(GOLDEN_FIXED)
            .wrapping_add(y << 31)
            .wrapping_add(blue.screen[1]);
        let [net_x, net_y] = blue.net(sample);
        Vec2::new(
            bits_to_unit(net_x.wrapping_add(rotation_x)),
            bits_to_unit(net_y.wrapping_add(rotation_y)),
        )
    }

    /// Passes over the next 2D dimension without drawing it (a value nothing reads).
    pub fn skip_2d(&mut self) {
        match self.kind {
            SamplerKind::White => self.dimension += 2,
            SamplerKind::Stratified | SamplerKind::BlueNoise => self.dimension += 1,
        }
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

    /// `dimension`'s blue-noise keys.
    #[inline]
    fn blue_keys(&self, dimension: u32) -> DimensionKeys {
        self.blue
            .expect("blue-noise sampler has its keys")
            .keys(dimension)
    }
}

/// What one path vertex draws, in the order it draws them (`integrator::path_vertex`):
/// the material lobe, the light pick and the point on that light, the BSDF lobe choice and
/// direction, and Russian roulette's value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VertexDraws {
    pub lobe: f32,
    pub pick: f32,
    pub light: Vec2,
    pub choice: f32,
    pub direction: Vec2,
    pub roulette: f32,
}

/// The sample dimensions a `VertexDraws` takes (four 1D, two 2D).
const VERTEX_DIMENSIONS: u32 = 6;

/// One vertex's `VertexDraws` for many paths at once: the wavefront's paths reach their
/// k-th vertex together, so they all draw the same dimensions, whose blue-noise keys are
/// then the same in every lane. Blue noise is drawn 8 paths at a time in AVX2 lanes (one
/// path at a time, the sampler was a fifth of the renderer's instructions); the other
/// kinds sampler by sampler. Either way path i gets what its `vertex_draws` gives.
#[derive(Default)]
pub struct VertexDrawBatch {
    /// Blue noise: per path, its sequence index (bit-reversed) and salt ...
    sequence: Vec<u32>,
    salt: Vec<u32>,
    /// ... and its values.
    planes: VertexPlanes,
    draws: Vec<VertexDraws>,
}

/// Many paths' `VertexDraws`, a plane per value.
#[derive(Default)]
struct VertexPlanes {
    lobe: Vec<f32>,
    pick: Vec<f32>,
    light: [Vec<f32>; 2],
    choice: Vec<f32>,
    direction: [Vec<f32>; 2],
    roulette: Vec<f32>,
}

impl VertexPlanes {
    fn resize(&mut self, count: usize) {
        let [light_x, light_y] = &mut self.light;
        let [direction_x, direction_y] = &mut self.direction;
        for plane in [
            &mut self.lobe,
            &mut self.pick,
            light_x,
            light_y,
            &mut self.choice,
            direction_x,
            direction_y,
            &mut self.roulette,
        ] {
            plane.resize(count, 0.0);
        }
    }

    /// The first `count` paths' draws, in order.
    fn draws(&self, count: usize) -> impl Iterator<Item = VertexDraws> + '_ {
        // Every plane cut to `count` first: the loop then runs without bounds checks
        // (indexed plane by plane it took 2.8% more of the render's instructions).
        fn cut(plane: &[f32], count: usize) -> &[f32] {
            &plane[..count]
        }
        let (lobe, pick, choice, roulette) = (
            cut(&self.lobe, count),
            cut(&self.pick, count),
            cut(&self.choice, count),
            cut(&self.roulette, count),
        );
        let (light_x, light_y) = (cut(&self.light[0], count), cut(&self.light[1], count));
        let (direction_x, direction_y) = (
            cut(&self.direction[0], count),
            cut(&self.direction[1], count),
        );
        (0..count).map(move |i| VertexDraws {
            lobe: lobe[i],
            pick: pick[i],
            light: Vec2::new(light_x[i], light_y[i]),
            choice: choice[i],
            direction: Vec2::new(direction_x[i], direction_y[i]),
            roulette: roulette[i],
        })
    }
}

impl VertexDrawBatch {
    /// The next vertex's draws of `samplers[i]` for each i of `paths`, in that order. The
    /// samplers are one render's (one kind, one `BlueNoise`), all at the same dimension.
    pub fn draw(
        &mut self,
        samplers: &mut [PixelSampler],
        paths: impl IntoIterator<Item = usize>,
    ) -> &[VertexDraws] {
        self.draws.clear();
        let mut paths = paths.into_iter().peekable();
        // The lanes draw from the first sampler's keys and dimension, so all must share
        // them; dimension 0 is the pixel jitter, which `next_2d` draws apart.
        let lanes = paths.peek().and_then(|&first| {
            let sampler = &samplers[first];
            let blue = sampler
                .blue
                .filter(|_| sampler.kind == SamplerKind::BlueNoise)?;
            (sampler.dimension > 0).then_some((blue, sampler.dimension))
        });
        let Some((blue, dimension)) = lanes else {
            self.draws
                .extend(paths.map(|path| samplers[path].vertex_draws()));
            return &self.draws;
        };
        self.sequence.clear();
        self.salt.clear();
        for path in paths {
            let sampler = &mut samplers[path];
            debug_assert!(
                sampler.blue.is_some_and(|keys| std::ptr::eq(keys, blue))
                    && sampler.dimension == dimension,
                "a batch's samplers share their keys and dimension"
            );
            self.sequence.push(sampler.sequence_index);
            self.salt.push(sampler.sequence_salt);
            sampler.dimension += VERTEX_DIMENSIONS;
        }
        let count = self.sequence.len();
        self.planes.resize(count);
        HashLanes::best().blue_vertex(
            blue,
            dimension,
            &self.sequence,
            &self.salt,
            &mut self.planes,
        );
        self.draws.extend(self.planes.draws(count));
        &self.draws
    }
}

/// The builds of the blue-noise hashes' lanes: integer lanes, so each gives the same bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum HashLanes {
    Portable,
    /// Eight lanes.
    Avx2,
    /// Eight lanes whose `reverse_bits` is one GFNI affine step and a byte shuffle in
    /// place of six shifts, masks and shuffles: the bounces phase fell 3.5% and the shade
    /// phase 3.5% on first-light (one thread, 2 alternated pairs). The same function
    /// built for AVX-512's sixteen lanes made every phase of the render 6-11% slower (two
    /// threads, 3 pairs), even those that draw nothing: the core clocks down after 512-bit
    /// work.
    Avx2Gfni,
}

impl HashLanes {
    /// The fastest build this CPU runs.
    fn best() -> HashLanes {
        if crate::simd::avx2_gfni() {
            HashLanes::Avx2Gfni
        } else if crate::simd::avx2() {
            HashLanes::Avx2
        } else {
            HashLanes::Portable
        }
    }

    fn blue_vertex(
        self,
        blue: &BlueNoise,
        dimension: u32,
        sequence: &[u32],
        salt: &[u32],
        planes: &mut VertexPlanes,
    ) {
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx2")]
            fn avx2(blue: &BlueNoise, d: u32, q: &[u32], s: &[u32], p: &mut VertexPlanes) {
                blue_vertex_lanes(blue, d, q, s, p);
            }
            #[target_feature(enable = "avx2,gfni")]
            fn avx2_gfni(blue: &BlueNoise, d: u32, q: &[u32], s: &[u32], p: &mut VertexPlanes) {
                blue_vertex_lanes(blue, d, q, s, p);
            }
            match self {
                // SAFETY: `best` chose these only where the CPU has their features.
                HashLanes::Avx2 => return unsafe { avx2(blue, dimension, sequence, salt, planes) },
                HashLanes::Avx2Gfni => {
                    return unsafe { avx2_gfni(blue, dimension, sequence, salt, planes) };
                }
                HashLanes::Portable => {}
            }
        }
        blue_vertex_lanes(blue, dimension, sequence, salt, planes);
    }
}

/// A vertex's six blue-noise dimensions from `dimension` on, for the paths whose sequence
/// indices and salts are `sequence` and `salt`, into `planes`.
#[inline(always)]
fn blue_vertex_lanes(
    blue: &BlueNoise,
    dimension: u32,
    sequence: &[u32],
    salt: &[u32],
    planes: &mut VertexPlanes,
) {
    let VertexPlanes {
        lobe,
        pick,
        light: [light_x, light_y],
        choice,
        direction: [direction_x, direction_y],
        roulette,
    } = planes;
    let keys = |offset: u32| blue.keys(dimension + offset);
    blue_1d_lanes(sequence, salt, keys(0), lobe);
    blue_1d_lanes(sequence, salt, keys(1), pick);
    blue_2d_lanes(sequence, salt, keys(2), light_x, light_y);
    blue_1d_lanes(sequence, salt, keys(3), choice);
    blue_2d_lanes(sequence, salt, keys(4), direction_x, direction_y);
    blue_1d_lanes(sequence, salt, keys(5), roulette);
}

/// `PixelSampler::next_1d`'s blue noise, lane by lane (the slices cut to one length so the
/// loop vectorises).
#[inline(always)]
fn blue_1d_lanes(sequence: &[u32], salt: &[u32], keys: DimensionKeys, out: &mut [f32]) {
    let count = out.len();
    let (sequence, salt) = (&sequence[..count], &salt[..count]);
    for i in 0..count {
        let index = laine_karras(sequence[i], keys.index ^ salt[i]).reverse_bits();
        out[i] = bits_to_unit(owen_scramble(index, keys.values[0] ^ salt[i]));
    }
}

/// `PixelSampler::next_2d`'s blue noise past the pixel jitter, lane by lane.
#[inline(always)]
fn blue_2d_lanes(
    sequence: &[u32],
    salt: &[u32],
    keys: DimensionKeys,
    out_x: &mut [f32],
    out_y: &mut [f32],
) {
    let count = out_x.len();
    let (sequence, salt, out_y) = (&sequence[..count], &salt[..count], &mut out_y[..count]);
    for i in 0..count {
        let index = laine_karras(sequence[i], keys.index ^ salt[i]).reverse_bits();
        out_x[i] = bits_to_unit(owen_scramble(index, keys.values[0] ^ salt[i]));
        out_y[i] = bits_to_unit(owen_scramble_reversed(
            sobol_second_reversed(index),
            keys.values[1] ^ salt[i],
        ));
    }
}

/// The blue-noise sampler's index of `sample` of `pixel` in the image-wide sequence
/// (Ahmed & Wonka 2020): the pixel's place in a Morton order, so every aligned block of 4^k
/// places is an aligned 2^k x 2^k tile (any image covered by the next power-of-two
/// square), times the samples per pixel rounded up to a power of two, plus the sample.
/// Ahmed & Wonka scramble the Z-order's children per node to make its error isotropic;
/// here each dimension's nested scramble of the index does that (it flips each level's
/// two digits by a hash of the levels above). Ordering each quad's children so that
/// aligned pairs are diagonal neighbours instead measured worse (a smooth 2D integrand's
/// low band 0.14 of white's against 0.08).
pub fn sequence_index((x, y): (u32, u32), sample: u32, sample_count: u32) -> u64 {
    let order = spread_bits(x) | spread_bits(y) << 1;
    let stride = sample_count.max(1).next_power_of_two();
    (order << stride.trailing_zeros()) | u64::from(sample & (stride - 1))
}

/// `sequence_index` as `PixelSampler` keeps it: its low 32 bits reversed, and what the
/// keys are XORed with (a hash of its high bits, 0 when there are none).
#[inline]
fn reversed_sequence_index(pixel: (u32, u32), sample: u32, sample_count: u32) -> (u32, u32) {
    let stride = sample_count.max(1).next_power_of_two();
    let shift = stride.trailing_zeros();
    let (x, y) = pixel;
    // Reversed, the Morton order is the rows' and columns' reversed bits interleaved (x's
    // bit i lands on bit 31 - 2i, y's on 30 - 2i): four lookups of a byte table, where
    // spreading both and reversing the whole took about 40 instructions.
    let half = |v: u32| {
        u32::from(SPREAD_REVERSED_BYTE[(v & 0xff) as usize]) << 16
            | u32::from(SPREAD_REVERSED_BYTE[(v >> 8 & 0xff) as usize])
    };
    let morton = half(x) << 1 | half(y);
    // The index fits 32 bits when x and y do 16 and the Morton order's top `shift` bits
    // (the reversed order's bottom ones) are clear for the sample's (a stride past 2^31
    // wraps to 0, shift 32: the general path's case).
    if x <= 0xffff && y <= 0xffff && shift < 32 && morton & ((1 << shift) - 1) == 0 {
        return (
            (morton >> shift) | (sample & (stride - 1)).reverse_bits(),
            0,
        );
    }
    reversed_sequence_index_in_full(pixel, sample, sample_count)
}

/// `reversed_sequence_index` from the 64-bit `sequence_index`: its general path.
fn reversed_sequence_index_in_full(
    pixel: (u32, u32),
    sample: u32,
    sample_count: u32,
) -> (u32, u32) {
    let index = sequence_index(pixel, sample, sample_count);
    let salt = match (index >> 32) as u32 {
        0 => 0,
        high => mix(high),
    };
    ((index as u32).reverse_bits(), salt)
}

/// Each byte's bits reversed, then spread to the even bit positions of a u16.
const SPREAD_REVERSED_BYTE: [u16; 256] = {
    let mut table = [0u16; 256];
    let mut byte = 0;
    while byte < 256 {
        let reversed = (byte as u8).reverse_bits() as u16;
        let mut spread = 0u16;
        let mut bit = 0;
        while bit < 8 {
            spread |= (reversed >> bit & 1) << (2 * bit);
            bit += 1;
        }
        table[byte] = spread;
        byte += 1;
    }
    table
};

/// The bits of `v` moved to the even bit positions of a u64 (a Morton code's half).
#[inline]
fn spread_bits(v: u32) -> u64 {
    let mut v = u64::from(v);
    v = (v | v << 16) & 0x0000_ffff_0000_ffff;
    v = (v | v << 8) & 0x00ff_00ff_00ff_00ff;
    v = (v | v << 4) & 0x0f0f_0f0f_0f0f_0f0f;
    v = (v | v << 2) & 0x3333_3333_3333_3333;
    (v | v << 1) & 0x5555_5555_5555_5555
}

/// Laine & Karras 2011's hash-based stand-in for a nested uniform (Owen) scramble of a
/// bit-reversed value, with Burley 2020's constants ("Practical Hash-based Owen
/// Scrambling", JCGT 9(4), listing 3): every output bit depends only on the input bits
/// below it, so reversed back, each binary digit is flipped by a hash of the digits
/// before it.
#[inline]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// The van der Corput value (0.32 fixed point) of `index`, Owen-scrambled with `seed`.
#[inline]
fn owen_scramble(index: u32, seed: u32) -> u32 {
    // Van der Corput's digits are the index's bits reversed, so its reversed form, the one
    // the hash takes, is the index itself.
    owen_scramble_reversed(index, seed)
}

/// The value whose binary digits (first digit in bit 0) are `reversed`, Owen-scrambled.
#[inline]
fn owen_scramble_reversed(reversed: u32, seed: u32) -> u32 {
    laine_karras(reversed, seed).reverse_bits()
}

/// The second dimension of Sobol's sequence at `index`, its binary digits reversed (first
/// digit in bit 0). Its generator matrix is Pascal's triangle mod 2: digit r is the parity
/// of the index bits c with r a bitwise subset of c (Lucas's theorem), a superset sum over
/// the bits of c, one shift-mask-XOR step each instead of a loop over the index's bits.
#[inline]
fn sobol_second_reversed(index: u32) -> u32 {
    let mut v = index;
    v ^= (v >> 1) & 0x5555_5555;
    v ^= (v >> 2) & 0x3333_3333;
    v ^= (v >> 4) & 0x0f0f_0f0f;
    v ^= (v >> 8) & 0x00ff_00ff;
    v ^= (v >> 16) & 0x0000_ffff;
    v
}

/// The golden ratio's fraction 0.6180339887 in 0.32 fixed point (its multiples stay exact).
const GOLDEN_FIXED: u32 = 2_654_435_769;

/// The R2 sequence's step (0.7548776662, 0.5698402910) in 0.32 fixed point (Roberts 2018,
/// "The unreasonable effectiveness of quasirandom sequences"): 1/p and 1/p^2, p the plastic
/// number, the 2D analogue of the golden ratio.
const R2_FIXED: [u32; 2] = [3_242_174_889, 2_447_445_414];

const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// A 0.32 fixed-point value as an f32 in [0, 1) (its top 24 bits, exact in an f32).
#[inline]
fn bits_to_unit(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
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
        let blue = BlueNoise::new(0, 0);
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

#[cfg(test)]
mod blue_noise_tests {
    use super::*;

    /// The first `2d` 2D draws and then one 1D draw of `sample` of `pixel` (blue noise).
    fn draws(
        blue: &BlueNoise,
        pixel: (u32, u32),
        sample: u32,
        count: u32,
        skip_2d: u32,
    ) -> (Vec2, f32) {
        let mut sampler = PixelSampler::new(
            SamplerKind::BlueNoise,
            Some(blue),
            blue.seed,
            blue.frame,
            pixel,
            sample,
            count,
        );
        let mut v = Vec2::ZERO;
        for _ in 0..skip_2d {
            v = sampler.next_2d();
        }
        (v, sampler.next_1d())
    }

    #[test]
    fn sobol_second_dimension_matches_its_direction_numbers() {
        // Direction numbers of the polynomial x + 1: v_0 = 1/2, v_i = v_(i-1) xor v_(i-1)/2.
        let mut directions = [0u32; 32];
        let mut v = 1u32 << 31;
        for direction in &mut directions {
            *direction = v;
            v ^= v >> 1;
        }
        for index in [0u32, 1, 2, 3, 5, 77, 1000, 65_535, 0xdead_beef] {
            let expected = (0..32)
                .filter(|bit| index >> bit & 1 == 1)
                .fold(0, |sum, bit| sum ^ directions[bit]);
            assert_eq!(sobol_second_reversed(index).reverse_bits(), expected);
        }
    }

    #[test]
    fn pixel_jitter_spreads_every_coverage_evenly_along_rows_and_columns() {
        // Whatever fraction c of a pixel an edge covers, the pixels of a run along a row
        // whose jitter y falls below c (down a column, x) number w c within 2 in every
        // window of w pixels: the edge's error has no low frequencies along it.
        for (seed, frame) in [(0, 0), (7, 3)] {
            let blue = BlueNoise::new(seed, frame);
            let jitter = |x: u32, y: u32| draws(&blue, (x, y), 0, 1, 1).0;
            for line in [0u32, 5, 1000] {
                let along_row: Vec<f32> = (0..128).map(|x| jitter(x, line).y).collect();
                let along_column: Vec<f32> = (0..128).map(|y| jitter(line, y).x).collect();
                for values in [along_row, along_column] {
                    assert!(values.iter().all(|v| (0.0..1.0).contains(v)));
                    for c in [0.05f32, 0.107, 0.25, 0.356, 0.5, 0.8] {
                        for w in [8usize, 13, 22, 64] {
                            for window in values.windows(w) {
                                let covered = window.iter().filter(|&&v| v < c).count();
                                assert!(
                                    (covered as f32 - w as f32 * c).abs() <= 2.0,
                                    "line {line}, c {c}: {covered} of {w}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn pixel_jitter_neighbours_across_a_line_are_antithetic() {
        // Side by side, jitter x is half a pixel apart; one above the other, jitter y.
        let blue = BlueNoise::new(2, 5);
        let jitter = |x: u32, y: u32| draws(&blue, (x, y), 0, 1, 1).0;
        for (x, y) in [(0, 0), (17, 3), (300, 41)] {
            let here = jitter(x, y);
            let apart = |a: f32, b: f32| ((a - b).rem_euclid(1.0) - 0.5).abs();
            assert!(apart(here.x, jitter(x + 1, y).x) < 1e-6, "({x}, {y})");
            assert!(apart(here.y, jitter(x, y + 1).y) < 1e-6, "({x}, {y})");
        }
    }

    #[test]
    fn a_pixels_jitters_over_frames_are_stratified() {
        // Frames step the jitter lattice's shift along the R2 sequence: over 64 frames at
        // 1 spp one pixel's jitters fill most cells of an 8 x 8 grid (independent
        // uniforms fill 63% on average).
        for pixel in [(0, 0), (37, 11)] {
            let mut cells = std::collections::HashSet::new();
            for frame in 0..64 {
                let blue = BlueNoise::new(4, frame);
                let jitter = draws(&blue, pixel, 0, 1, 1).0;
                cells.insert(((jitter.x * 8.0) as u32, (jitter.y * 8.0) as u32));
            }
            assert!(cells.len() >= 52, "{pixel:?}: {} of 64 cells", cells.len());
        }
    }

    #[test]
    fn a_pixels_jitters_are_stratified() {
        // 16 samples of one pixel, a rotated (0,2)-net: x and y each one per sixteenth up
        // to the rotation, so no gap between neighbours (cyclically) reaches 2/16.
        let blue = BlueNoise::new(3, 0);
        for pixel in [(0, 0), (13, 200), (70_000, 9)] {
            let points: Vec<Vec2> = (0..16).map(|s| draws(&blue, pixel, s, 16, 1).0).collect();
            for axis in [0, 1] {
                let mut values: Vec<f32> = points.iter().map(|p| p[axis]).collect();
                values.sort_by(f32::total_cmp);
                let wrap = values[0] + 1.0 - values[15];
                let widest = values.windows(2).map(|w| w[1] - w[0]).fold(wrap, f32::max);
                assert!(widest < 2.0 / 16.0, "{pixel:?} axis {axis}: gap {widest}");
            }
        }
    }

    /// One point of `points` (2^m of them) in each elementary interval of area 2^-m.
    fn assert_is_net(points: &[Vec2], m: u32) {
        for a in 0..=m {
            let (columns, rows) = (1u32 << a, 1u32 << (m - a));
            let mut cells = vec![0; points.len()];
            for p in points {
                assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
                let cell = (p.y * rows as f32) as u32 * columns + (p.x * columns as f32) as u32;
                cells[cell as usize] += 1;
            }
            assert!(
                cells.iter().all(|&c| c == 1),
                "{columns} x {rows}: {cells:?}"
            );
        }
    }

    #[test]
    fn the_reversed_sequence_index_is_the_sequence_index_reversed() {
        let mut state = 0x2545_f491u32;
        let mut next = || {
            state = mix(state);
            state
        };
        for count in [1, 2, 3, 16, 1000, 4096, 1 << 20, u32::MAX] {
            for _ in 0..2000 {
                // Small pixels, pixels at the 16-bit edge and past it.
                let (r, s, t) = (next(), next(), next());
                let pixel = match r % 3 {
                    0 => (s % 640, t % 360),
                    1 => (0xff00 + s % 0x200, 0xff00 + t % 0x200),
                    _ => (s, t),
                };
                let sample = next();
                assert_eq!(
                    reversed_sequence_index(pixel, sample, count),
                    reversed_sequence_index_in_full(pixel, sample, count),
                    "pixel {pixel:?} sample {sample} of {count}"
                );
            }
        }
    }

    #[test]
    fn every_aligned_tile_draws_a_net_in_each_dimension() {
        // At 1 spp the pixels of an aligned 2^k x 2^k tile share a (0, 2k, 2)-net in every
        // 2D dimension after the jitter, and 4^k strata in every 1D dimension.
        let blue = BlueNoise::new(11, 2);
        for k in 1..=3u32 {
            let side = 1u32 << k;
            for (tx, ty) in [(0u32, 0u32), (3, 5)] {
                for skip in 2..6 {
                    let tile: Vec<(Vec2, f32)> = (0..side * side)
                        .map(|i| {
                            let pixel = (tx * side + i % side, ty * side + i / side);
                            draws(&blue, pixel, 0, 1, skip)
                        })
                        .collect();
                    let points: Vec<Vec2> = tile.iter().map(|t| t.0).collect();
                    assert_is_net(&points, 2 * k);
                    let mut strata = vec![0; tile.len()];
                    for (_, v) in &tile {
                        strata[(v * tile.len() as f32) as usize] += 1;
                    }
                    assert!(
                        strata.iter().all(|&c| c == 1),
                        "1D after {skip}: {strata:?}"
                    );
                }
            }
        }
    }

    /// A pinhole camera passes over the lens dimension (`PixelSampler::skip_2d`): the
    /// dimensions after it are drawn as if it had been.
    #[test]
    fn skipping_a_2d_dimension_leaves_the_later_ones_as_drawing_it_does() {
        let blue = BlueNoise::new(2, 3);
        for kind in [
            SamplerKind::BlueNoise,
            SamplerKind::White,
            SamplerKind::Stratified,
        ] {
            let new = || PixelSampler::new(kind, Some(&blue), 2, 3, (5, 8), 1, 4);
            let (mut drawn, mut skipped) = (new(), new());
            assert_eq!(drawn.next_2d(), skipped.next_2d());
            drawn.next_2d();
            skipped.skip_2d();
            assert_eq!(
                drawn.vertex_draws(),
                skipped.vertex_draws(),
                "{}",
                kind.name()
            );
        }
    }

    /// A batch's draws are what each sampler draws alone, in its AVX2 lanes and in the
    /// portable ones, for pixels past 65536 x 65536 pixel-samples (salted indices) and
    /// dimensions past the keys held ready; and the samplers go on from the same place.
    #[test]
    fn a_vertex_batch_draws_what_each_sampler_draws() {
        let blue = BlueNoise::new(11, 7);
        let pixels: Vec<(u32, u32)> = (0..37)
            .map(|i| (i * 13 % 40, i * 7 % 23))
            .chain([(70_000, 3), (65_535, 65_535)])
            .collect();
        let new = |kind, pixel| PixelSampler::new(kind, Some(&blue), 11, 7, pixel, 1, 2);
        for kind in [
            SamplerKind::BlueNoise,
            SamplerKind::White,
            SamplerKind::Stratified,
        ] {
            let mut alone: Vec<PixelSampler> = pixels.iter().map(|&p| new(kind, p)).collect();
            let mut batched: Vec<PixelSampler> = pixels.iter().map(|&p| new(kind, p)).collect();
            let mut batch = VertexDrawBatch::default();
            for sampler in alone.iter_mut().chain(&mut batched) {
                sampler.next_2d();
                sampler.next_2d();
            }
            for vertex in 0..7 {
                let expected: Vec<VertexDraws> =
                    alone.iter_mut().map(|s| s.vertex_draws()).collect();
                let drawn = batch.draw(&mut batched, 0..pixels.len());
                assert_eq!(drawn, &expected[..], "{} vertex {vertex}", kind.name());
            }
            let next = |samplers: &mut Vec<PixelSampler>| -> Vec<f32> {
                samplers.iter_mut().map(|s| s.next_1d()).collect()
            };
            assert_eq!(next(&mut alone), next(&mut batched));
        }
        // Every build of the lanes this CPU runs (the batch above took the best).
        let samplers: Vec<PixelSampler> = pixels
            .iter()
            .map(|&p| new(SamplerKind::BlueNoise, p))
            .collect();
        let sequence: Vec<u32> = samplers.iter().map(|s| s.sequence_index).collect();
        let salt: Vec<u32> = samplers.iter().map(|s| s.sequence_salt).collect();
        assert!(
            salt.iter().any(|&salt| salt != 0),
            "a salted index is covered"
        );
        let best = HashLanes::best();
        let builds = [HashLanes::Portable, HashLanes::Avx2, HashLanes::Avx2Gfni];
        let runnable = match best {
            HashLanes::Portable => &builds[..1],
            HashLanes::Avx2 => &builds[..2],
            HashLanes::Avx2Gfni => &builds[..],
        };
        for &lanes in runnable {
            let mut planes = VertexPlanes::default();
            planes.resize(pixels.len());
            lanes.blue_vertex(&blue, 30, &sequence, &salt, &mut planes);
            let drawn = planes.draws(pixels.len());
            for (drawn, &pixel) in drawn.zip(&pixels) {
                let mut alone = new(SamplerKind::BlueNoise, pixel);
                alone.dimension = 30;
                assert_eq!(drawn, alone.vertex_draws(), "{lanes:?}, pixel {pixel:?}");
            }
        }
    }

    #[test]
    fn blue_noise_is_deterministic_and_frames_decorrelate() {
        let (one, again, next) = (
            BlueNoise::new(5, 0),
            BlueNoise::new(5, 0),
            BlueNoise::new(5, 1),
        );
        let mut products = 0.0;
        let n = 4096;
        for i in 0..n {
            let pixel = (i % 64, i / 64);
            for skip in 2..5 {
                let (a, a1) = draws(&one, pixel, 0, 1, skip);
                assert_eq!((a, a1), draws(&again, pixel, 0, 1, skip));
                let (b, b1) = draws(&next, pixel, 0, 1, skip);
                products += f64::from((a.x - 0.5) * (b.x - 0.5) + (a1 - 0.5) * (b1 - 0.5));
            }
        }
        // Independent uniforms: each product has mean 0 and deviation 1/12.
        let correlation = products / f64::from(n * 3 * 2) * 12.0;
        assert!(
            correlation.abs() < 0.05,
            "frame to frame correlation {correlation}"
        );
    }

    #[test]
    fn one_sample_error_of_a_path_like_integrand_is_blue() {
        // A smooth integrand of the jitter and four later dimensions (a product across
        // dimensions, as a bounce's direction times the next vertex's light sample): at
        // 1 spp over 64 x 64 pixels the error's low band (radii to a quarter of Nyquist)
        // holds far less power than white noise's.
        let f = |samples: &[Vec2], u: f32| {
            let [jitter, light, direction, next] = [samples[0], samples[1], samples[2], samples[3]];
            jitter.x * jitter.y
                + (3.0 * light.x).sin() * light.y
                + direction.x * next.y
                + direction.y * direction.y * u
        };
        let size = 64u32;
        let low_band = |kind: SamplerKind| -> f32 {
            (0..4)
                .map(|seed| {
                    let blue = BlueNoise::new(seed, 0);
                    let error: Vec<f32> = (0..size * size)
                        .map(|i| {
                            let pixel = (i % size, i / size);
                            let mut sampler =
                                PixelSampler::new(kind, Some(&blue), seed, 0, pixel, 0, 1);
                            let samples: Vec<Vec2> = (0..4).map(|_| sampler.next_2d()).collect();
                            f(&samples, sampler.next_1d())
                        })
                        .collect();
                    crate::render::spectrum::low_frequency_power(
                        &error,
                        size as usize,
                        size as usize,
                        0.25,
                    )
                })
                .sum()
        };
        let ratio = low_band(SamplerKind::BlueNoise) / low_band(SamplerKind::White);
        assert!(ratio < 0.3, "low-band power, blue over white: {ratio}");
    }
}
