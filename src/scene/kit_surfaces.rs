//! Load-time tooling: the kit's surfaces, the tileable textures every kit material but the
//! glows and the mirror carries (`scene::kit` embeds them in each `.glb`).
//!
//! A surface is drawn texel by texel in code from a few hash-seeded noise fields, no
//! image from outside: per texel an albedo detail, a roughness and metalness multiplier,
//! and a height in metres. Three PNGs come out of it, as glTF's metallic-roughness
//! material reads them:
//! - `baseColorTexture` (sRGB): the detail. The material's `baseColorFactor` is the colour
//!   it always had divided by the detail's mean, channel by channel, so the texture's
//!   mean (its last mip level, what a far wall shows) is that colour exactly and the
//!   levels keep their brightness;
//! - `metallicRoughnessTexture` (linear): roughness in G and metalness in B, multiplying the
//!   material's factors;
//! - `normalTexture` (linear): the height's slopes as tangent-space normals, x along +u and
//!   y along -v (glTF's convention), by central differences that wrap at the edges.
//!
//! Each texture tiles: every noise lattice and every block, plank and thread pattern
//! repeats exactly once per texture. One texture spans [`Surface::period`] metres; the
//! kit's UVs are in metres and are divided by that period. Only `+`, `*`, division, floor
//! and square roots go into a texel (no libm), so the PNGs are the same bytes on any
//! machine and build profile.

use anyhow::Context as _;
use glam::{Vec2, Vec3};
use image::ImageEncoder as _;

/// The kit's surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Surface {
    /// Dressed stone blocks in courses 0.25 m high, 0.5 m long, each course's joints
    /// shifted, in 2.4 cm of recessed dark mortar: the walls.
    Ashlar,
    /// Square stone slabs 0.5 m across, each row's joints shifted, domed a little between
    /// 2 cm mortar joints: the floor.
    Flagstones,
    /// Tooled stone with no joints (speckle and chisel marks): the pillar and the stairs.
    DressedStone,
    /// Planks 0.125 m wide along u, with grain, ends and 3 mm gaps: the crate, the table,
    /// the door, the bookcase, the sill and frames.
    Planks,
    /// Hammered metal with tarnished patches (rougher, and darker): iron and brass.
    Metal,
    /// A plain weave of 3.9 mm threads: the banner and the wardens' cloaks.
    Cloth,
    /// Grained leather: the books.
    Leather,
    /// Mottled wax: the candle.
    Wax,
    /// Glass with faint smears (rougher where they lie): the bottle.
    Glass,
}

/// One surface's three PNG images and the mean of its detail in linear RGB.
pub struct SurfaceImages {
    pub base_color: Vec<u8>,
    pub metallic_roughness: Vec<u8>,
    pub normal: Vec<u8>,
    /// The decoded base-colour texture's mean (after 8-bit sRGB rounding).
    pub mean_detail: Vec3,
}

/// What a surface is at one texel.
struct Texel {
    /// Linear albedo detail, each channel in (0, 1].
    detail: Vec3,
    /// Roughness and metalness multipliers in [0, 1].
    roughness: f32,
    metalness: f32,
    /// Height above the surface in metres.
    height: f32,
}

impl Surface {
    /// Every surface, in a fixed order.
    pub const ALL: [Surface; 9] = [
        Surface::Ashlar,
        Surface::Flagstones,
        Surface::DressedStone,
        Surface::Planks,
        Surface::Metal,
        Surface::Cloth,
        Surface::Leather,
        Surface::Wax,
        Surface::Glass,
    ];

    /// The name its images carry.
    pub fn name(self) -> &'static str {
        match self {
            Surface::Ashlar => "ashlar",
            Surface::Flagstones => "flagstones",
            Surface::DressedStone => "dressed stone",
            Surface::Planks => "planks",
            Surface::Metal => "metal",
            Surface::Cloth => "cloth",
            Surface::Leather => "leather",
            Surface::Wax => "wax",
            Surface::Glass => "glass",
        }
    }

    /// Metres one repeat of the texture spans, along u and along v.
    pub fn period(self) -> f32 {
        match self {
            Surface::Ashlar | Surface::Flagstones | Surface::DressedStone | Surface::Planks => 1.0,
            Surface::Metal => 0.5,
            Surface::Cloth | Surface::Leather | Surface::Wax | Surface::Glass => 0.25,
        }
    }

    /// Texels along each side: 4 mm texels for the large surfaces, fewer for the small
    /// pieces that never fill the view.
    pub fn size(self) -> u32 {
        match self {
            Surface::Ashlar | Surface::Flagstones | Surface::Planks => 256,
            Surface::DressedStone | Surface::Metal | Surface::Cloth => 128,
            Surface::Leather | Surface::Wax | Surface::Glass => 64,
        }
    }

    /// The surface at texel (x, y) of a `size`-texel tile.
    fn texel(self, x: u32, y: u32) -> Texel {
        let size = self.size();
        // Position in metres within the tile, at the texel's centre.
        let metres = self.period() / size as f32;
        let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) * metres;
        match self {
            Surface::Ashlar => ashlar(p),
            Surface::Flagstones => flagstones(p),
            Surface::DressedStone => dressed_stone(p),
            Surface::Planks => planks(p),
            Surface::Metal => metal(p),
            Surface::Cloth => cloth(p),
            Surface::Leather => leather(p),
            Surface::Wax => wax(p),
            Surface::Glass => glass(p),
        }
    }

    /// Draws the surface and encodes its three images.
    pub fn images(self) -> anyhow::Result<SurfaceImages> {
        let size = self.size();
        let texels: Vec<Texel> = (0..size)
            .flat_map(|y| (0..size).map(move |x| (x, y)))
            .map(|(x, y)| self.texel(x, y))
            .collect();
        let at = |x: i64, y: i64| {
            let n = i64::from(size);
            &texels[(y.rem_euclid(n) * n + x.rem_euclid(n)) as usize]
        };
        let texel_metres = self.period() / size as f32;
        let mut base_color = Vec::with_capacity(texels.len() * 3);
        let mut metallic_roughness = Vec::with_capacity(texels.len() * 3);
        let mut normal = Vec::with_capacity(texels.len() * 3);
        let mut sum = Vec3::ZERO;
        for y in 0..i64::from(size) {
            for x in 0..i64::from(size) {
                let texel = at(x, y);
                let encoded = texel.detail.to_array().map(linear_to_srgb8);
                sum += Vec3::from(encoded.map(srgb8_to_linear));
                base_color.extend(encoded);
                metallic_roughness.extend([0, unit8(texel.roughness), unit8(texel.metalness)]);
                // Slopes along +u and along "up" (-v); the normal is (-dh/du, -dh/dup, 1).
                let dh_du = (at(x + 1, y).height - at(x - 1, y).height) / (2.0 * texel_metres);
                let dh_dup = (at(x, y - 1).height - at(x, y + 1).height) / (2.0 * texel_metres);
                let n = Vec3::new(-dh_du, -dh_dup, 1.0);
                let n = n / n.length();
                normal.extend(n.to_array().map(|c| unit8(0.5 * c + 0.5)));
            }
        }
        let name = self.name();
        Ok(SurfaceImages {
            base_color: png(&base_color, size).with_context(|| format!("{name} base colour"))?,
            metallic_roughness: png(&metallic_roughness, size)
                .with_context(|| format!("{name} metallic-roughness"))?,
            normal: png(&normal, size).with_context(|| format!("{name} normals"))?,
            mean_detail: sum / texels.len() as f32,
        })
    }
}

fn png(rgb: &[u8], size: u32) -> anyhow::Result<Vec<u8>> {
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png).write_image(
        rgb,
        size,
        size,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(png)
}

/// [0, 1] to a byte, rounded.
fn unit8(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// The sRGB transfer function's inverse, to a byte: by bisection over the 256 codes of
/// `srgb8_to_linear` (no `powf`, so the same byte everywhere).
fn linear_to_srgb8(linear: f32) -> u8 {
    let linear = linear.clamp(0.0, 1.0);
    let (mut low, mut high) = (0u8, 255u8);
    while low < high {
        let mid = low + (high - low) / 2;
        // The boundary between codes mid and mid + 1: their decoded midpoint.
        let boundary = 0.5 * (srgb8_to_linear(mid) + srgb8_to_linear(mid + 1));
        if linear > boundary {
            low = mid + 1;
        } else {
            high = mid;
        }
    }
    low
}

/// An sRGB byte decoded to linear, as glTF's importers decode it.
fn srgb8_to_linear(code: u8) -> f32 {
    let c = f32::from(code) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        // ((c + 0.055) / 1.055)^2.4 without a libm: x^2.4 = x^2 (x^(1/5))^2.
        let x = (c + 0.055) / 1.055;
        x * x * fifth_root(x) * fifth_root(x)
    }
}

/// x^(1/5) for x in (0, 1], by Newton's method from 1 (converges from above).
fn fifth_root(x: f32) -> f32 {
    let mut r = 1.0f32;
    for _ in 0..12 {
        let r4 = r * r * r * r;
        r -= (r4 * r - x) / (5.0 * r4);
    }
    r
}

// ---- noise ----------------------------------------------------------------------------------

/// A small integer hash: the seed of every random choice (and of the kit's books).
pub(super) fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// A hash of two integers and a seed, in [0, 1).
fn random(a: i32, b: i32, seed: u32) -> f32 {
    let h = hash((a as u32).wrapping_mul(0x9e37_79b9) ^ hash((b as u32) ^ hash(seed)));
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Value noise in [0, 1] over a lattice of `cells` x `cells` per unit square, repeating
/// every unit (so a tile of the texture repeats with it), smoothly interpolated.
fn value_noise(p: Vec2, cells: Vec2, seed: u32) -> f32 {
    let q = p * cells;
    let (x0, y0) = (q.x.floor(), q.y.floor());
    let (fx, fy) = (q.x - x0, q.y - y0);
    let (cx, cy) = (cells.x as i32, cells.y as i32);
    let corner = |dx: i32, dy: i32| {
        random(
            (x0 as i32 + dx).rem_euclid(cx),
            (y0 as i32 + dy).rem_euclid(cy),
            seed,
        )
    };
    let smooth = |t: f32| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (smooth(fx), smooth(fy));
    let top = corner(0, 0) + (corner(1, 0) - corner(0, 0)) * sx;
    let bottom = corner(0, 1) + (corner(1, 1) - corner(0, 1)) * sx;
    top + (bottom - top) * sy
}

/// Fractal noise in about [0, 1]: `octaves` of value noise from `cells`, each twice as fine
/// and half as strong.
fn fbm(p: Vec2, cells: Vec2, octaves: u32, seed: u32) -> f32 {
    let (mut sum, mut weight, mut total) = (0.0, 1.0, 0.0);
    let mut cells = cells;
    for octave in 0..octaves {
        sum += weight * value_noise(p, cells, seed.wrapping_add(octave * 101));
        total += weight;
        weight *= 0.5;
        cells *= 2.0;
    }
    sum / total
}

/// `p` (metres) as a fraction of the tile `period` metres wide.
fn unit(p: Vec2, period: f32) -> Vec2 {
    p / period
}

/// 0 at `edge0`, 1 at `edge1`, smooth between.
fn smoothstep(edge0: f32, edge1: f32, x: f32) -> f32 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

// ---- the surfaces ----------------------------------------------------------------------------

/// Stone blocks and recessed mortar in a bond: `course` metres high, `length` long, each
/// course's joints shifted by a hashed multiple of `length / 4`; `joint` metres of mortar.
/// Returns (block id, distance to the nearest joint's centre line in metres).
fn bond(p: Vec2, course: f32, length: f32, seed: u32) -> ((i32, i32), f32) {
    let row = (p.y / course).floor() as i32;
    let shift = (hash(row as u32 ^ seed) % 4) as f32 * length * 0.25;
    let along = p.x + shift;
    let column = (along / length).floor() as i32;
    let to_horizontal = {
        let f = p.y - row as f32 * course;
        f.min(course - f)
    };
    let to_vertical = {
        let f = along - column as f32 * length;
        f.min(length - f)
    };
    // Blocks repeat with the tile: a 1 m tile holds a whole number of them in each course.
    let blocks = (1.0 / length) as i32;
    (
        (row, column.rem_euclid(blocks)),
        to_horizontal.min(to_vertical),
    )
}

fn ashlar(p: Vec2) -> Texel {
    let u = unit(p, 1.0);
    let ((row, column), to_joint) = bond(p, 0.25, 0.5, 11);
    // Joints 2.4 cm wide and blocks of clearly different tones: a course should read at
    // a glance in a 480 x 270 frame, where a pixel is 1.6 cm across at 3 m.
    let joint = 0.012;
    let mortar = smoothstep(joint + 0.003, joint - 0.002, to_joint);
    let tone = 0.68 + 0.3 * random(row, column, 12);
    let warmth = 0.03 * (random(row, column, 13) - 0.5);
    let grain = fbm(u, Vec2::splat(16.0), 4, 14);
    let pits = smoothstep(0.68, 0.78, fbm(u, Vec2::splat(32.0), 3, 15));
    let stone = Vec3::new(1.0 + warmth, 0.96, 0.9 - warmth)
        * tone
        * (0.84 + 0.22 * grain)
        * (1.0 - 0.25 * pits);
    let mortar_colour = Vec3::new(0.42, 0.4, 0.37) * (0.8 + 0.2 * grain);
    // The block face is dressed flat, rounding off over the last 2 cm into the joint.
    let face = 0.006 * smoothstep(joint, joint + 0.02, to_joint) + 0.0015 * grain - 0.001 * pits;
    Texel {
        detail: (stone.lerp(mortar_colour, mortar) * 0.95).min(Vec3::ONE),
        roughness: 0.85 + 0.15 * mortar - 0.1 * (1.0 - grain),
        metalness: 1.0,
        height: face * (1.0 - mortar) - 0.006 * mortar,
    }
}

fn flagstones(p: Vec2) -> Texel {
    let u = unit(p, 1.0);
    let ((row, column), to_joint) = bond(p, 0.5, 0.5, 21);
    let joint = 0.01;
    let mortar = smoothstep(joint + 0.003, joint - 0.002, to_joint);
    let tone = 0.62 + 0.36 * random(row, column, 22);
    let cool = 0.04 * random(row, column, 23);
    let grain = fbm(u, Vec2::splat(8.0), 5, 24);
    let wear = fbm(u, Vec2::splat(4.0), 2, 25);
    let stone = Vec3::new(0.94 - cool, 0.93, 0.9 + cool) * tone * (0.8 + 0.3 * grain);
    let mortar_colour = Vec3::new(0.3, 0.29, 0.27) * (0.85 + 0.15 * grain);
    let dome = 0.003 * smoothstep(joint, joint + 0.06, to_joint);
    Texel {
        detail: stone.lerp(mortar_colour, mortar).min(Vec3::ONE),
        // Feet polish the middle of a slab.
        roughness: 0.9 - 0.25 * wear * (1.0 - mortar),
        metalness: 1.0,
        height: (dome + 0.002 * grain) * (1.0 - mortar) - 0.003 * mortar,
    }
}

fn dressed_stone(p: Vec2) -> Texel {
    let u = unit(p, 1.0);
    let speckle = fbm(u, Vec2::splat(64.0), 2, 31);
    let cloud = fbm(u, Vec2::splat(4.0), 4, 32);
    // Chisel marks: fine diagonal furrows, drawn as a ramp along u + v broken by noise.
    let furrow = {
        let along = (u.x + u.y) * 48.0 + 2.0 * fbm(u, Vec2::splat(8.0), 2, 33);
        let f = along - along.floor();
        f.min(1.0 - f)
    };
    let grey = 0.78 + 0.14 * cloud + 0.1 * (speckle - 0.5);
    Texel {
        detail: Vec3::new(1.0, 0.99, 0.96) * grey,
        roughness: 0.9 - 0.1 * cloud,
        metalness: 1.0,
        height: 0.0008 * furrow + 0.0008 * speckle,
    }
}

fn planks(p: Vec2) -> Texel {
    let width = 0.125;
    let plank = (p.y / width).floor() as i32;
    let across = p.y - plank as f32 * width;
    // Each plank has one end joint somewhere along the tile.
    let end = random(plank, 0, 41);
    let along = (p.x - end).rem_euclid(1.0);
    let to_end = along.min(1.0 - along);
    let to_edge = across.min(width - across);
    let gap = smoothstep(0.003, 0.0012, to_edge.min(to_end));
    let u = unit(p, 1.0);
    // Grain: stretched noise along u, its level lines drawn as rings.
    let seed = 42 + plank as u32 * 7;
    let figure = fbm(u, Vec2::new(2.0, 48.0), 3, seed) * 6.0;
    let ring = {
        let f = figure - figure.floor();
        smoothstep(0.0, 0.25, f) * smoothstep(1.0, 0.6, f)
    };
    let fibre = value_noise(u, Vec2::new(8.0, 256.0), seed + 1);
    let tone = 0.7 + 0.28 * random(plank, 1, 43);
    let wood = Vec3::new(1.0, 0.93, 0.85) * tone * (0.66 + 0.26 * ring + 0.08 * fibre);
    Texel {
        detail: wood.lerp(Vec3::splat(0.25), gap),
        roughness: 0.8 + 0.2 * (1.0 - ring) * 0.5,
        metalness: 1.0,
        height: 0.0004 * ring + 0.0002 * fibre - 0.002 * gap,
    }
}

fn metal(p: Vec2) -> Texel {
    let u = unit(p, 0.5);
    let tarnish = smoothstep(0.5, 0.7, fbm(u, Vec2::splat(4.0), 4, 51));
    let dents = fbm(u, Vec2::splat(24.0), 2, 52);
    let scratches = value_noise(u, Vec2::new(96.0, 6.0), 53);
    Texel {
        detail: Vec3::splat(0.92 - 0.4 * tarnish - 0.06 * scratches),
        roughness: 0.7 + 0.3 * tarnish - 0.1 * scratches,
        metalness: 1.0 - 0.5 * tarnish,
        height: 0.0004 * dents,
    }
}

fn cloth(p: Vec2) -> Texel {
    let u = unit(p, 0.25);
    // A plain weave: 64 threads each way per tile (3.9 mm apart), each crossing over
    // then under its neighbours.
    let threads = 64.0;
    let (tx, ty) = (u.x * threads, u.y * threads);
    let (ix, iy) = (tx.floor() as i32, ty.floor() as i32);
    let (fx, fy) = (tx - tx.floor(), ty - ty.floor());
    let warp_on_top = (ix + iy).rem_euclid(2) == 0;
    // Each thread's round profile across it, and its rise and fall along it.
    let round = |f: f32| {
        let d = 2.0 * f - 1.0;
        (1.0 - d * d).max(0.0).sqrt()
    };
    let (warp, weft) = (round(fx), round(fy));
    let top = if warp_on_top { warp } else { weft };
    let slub = fbm(u, Vec2::new(4.0, 64.0), 2, 61);
    Texel {
        detail: Vec3::splat(0.8 + 0.12 * top + 0.08 * slub),
        roughness: 1.0,
        metalness: 1.0,
        height: 0.0006 * top,
    }
}

fn leather(p: Vec2) -> Texel {
    let u = unit(p, 0.25);
    let grain = fbm(u, Vec2::splat(16.0), 3, 71);
    let crease = smoothstep(0.45, 0.5, value_noise(u, Vec2::splat(8.0), 72));
    Texel {
        detail: Vec3::splat(0.8 + 0.15 * grain - 0.08 * crease),
        roughness: 0.75 + 0.25 * grain,
        metalness: 1.0,
        height: 0.0002 * grain - 0.0002 * crease,
    }
}

fn wax(p: Vec2) -> Texel {
    let u = unit(p, 0.25);
    let mottle = fbm(u, Vec2::splat(4.0), 4, 81);
    Texel {
        detail: Vec3::new(1.0, 0.99, 0.97) * (0.93 + 0.07 * mottle),
        roughness: 0.8 + 0.2 * mottle,
        metalness: 1.0,
        height: 0.0003 * mottle,
    }
}

fn glass(p: Vec2) -> Texel {
    let u = unit(p, 0.25);
    let smear = smoothstep(0.45, 0.75, fbm(u, Vec2::new(2.0, 8.0), 3, 91));
    let ripple = value_noise(u, Vec2::new(2.0, 32.0), 92);
    Texel {
        detail: Vec3::splat(0.95 - 0.1 * smear),
        roughness: 0.6 + 0.4 * smear,
        metalness: 1.0,
        height: 0.0001 * ripple,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_bytes_round_trip() {
        for code in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb8_to_linear(code)), code);
        }
        // The decode is glTF's: within float rounding of the formula.
        for code in [10u8, 64, 128, 200, 255] {
            let c = f32::from(code) / 255.0;
            let exact = if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            };
            assert!((srgb8_to_linear(code) - exact).abs() < 1e-5, "{code}");
        }
    }

    /// Every surface tiles: no step between neighbouring texels across the tile's edges
    /// is larger than the largest step between neighbours inside it (where a joint or a
    /// thread may fall).
    #[test]
    fn every_surface_tiles() {
        for surface in Surface::ALL {
            let size = surface.size() as usize;
            let texels: Vec<Texel> = (0..size * size)
                .map(|i| surface.texel((i % size) as u32, (i / size) as u32))
                .collect();
            let step = |a: usize, b: usize| {
                (texels[a].height - texels[b].height).abs() * 1000.0
                    + (texels[a].detail - texels[b].detail).abs().max_element()
            };
            let (mut inside, mut across) = (0.0f32, 0.0f32);
            for y in 0..size {
                for x in 0..size {
                    let here = y * size + x;
                    let right = y * size + (x + 1) % size;
                    let below = ((y + 1) % size) * size + x;
                    let right_step = step(here, right);
                    let below_step = step(here, below);
                    if x + 1 == size {
                        across = across.max(right_step);
                    } else {
                        inside = inside.max(right_step);
                    }
                    if y + 1 == size {
                        across = across.max(below_step);
                    } else {
                        inside = inside.max(below_step);
                    }
                }
            }
            assert!(
                across <= inside + 1e-4,
                "{}: a step of {across} across the wrap, at most {inside} inside",
                surface.name()
            );
        }
    }

    /// The images decode to the size asked, and the mean the factors divide by is the
    /// decoded image's.
    #[test]
    fn images_are_the_size_asked_with_their_mean() {
        let images = Surface::Leather.images().unwrap();
        for png in [
            &images.base_color,
            &images.metallic_roughness,
            &images.normal,
        ] {
            let decoded = image::load_from_memory(png).unwrap().to_rgb8();
            assert_eq!(decoded.dimensions(), (64, 64));
        }
        let decoded = image::load_from_memory(&images.base_color)
            .unwrap()
            .to_rgb8();
        let mut sum = Vec3::ZERO;
        for pixel in decoded.pixels() {
            sum += Vec3::from(pixel.0.map(srgb8_to_linear));
        }
        let mean = sum / (64.0 * 64.0);
        assert!((mean - images.mean_detail).abs().max_element() < 1e-5);
        assert!(images.mean_detail.min_element() > 0.5);
    }

    /// Normals lean away from a raised face in glTF's convention (x along +u, y along
    /// -v): the ashlar's block faces slope down into their recessed joints, so just left
    /// of a vertical joint the normal leans to +u, and just above a horizontal joint
    /// (larger v) it leans down, to -y; just below one, up.
    #[test]
    fn normals_lean_away_from_a_raised_face_in_gltfs_convention() {
        let surface = Surface::Ashlar;
        let images = surface.images().unwrap();
        let normal = image::load_from_memory(&images.normal).unwrap().to_rgb8();
        // Along the middle of course 0 (texel row 32), the first joint going right.
        let heights: Vec<f32> = (0..256).map(|x| surface.texel(x, 32).height).collect();
        let joint = (1..255)
            .find(|&x| heights[x] < -0.003 && heights[x - 1] > 0.0)
            .expect("a joint along the row") as u32;
        let before = normal.get_pixel(joint - 2, 32).0;
        assert!(
            before[0] > 140,
            "leans to +u into a joint on the right: {before:?}"
        );
        // Course 0 is texel rows 0..64: row 61 lies above its bottom joint, row 2 below
        // its top one (the tile's wrap).
        let mean_y = |row: u32| {
            (0..256)
                .map(|x| f32::from(normal.get_pixel(x, row).0[1]))
                .sum::<f32>()
                / 256.0
        };
        assert!(
            mean_y(61) < 120.0,
            "leans down above a joint: {}",
            mean_y(61)
        );
        assert!(mean_y(2) > 136.0, "leans up below a joint: {}", mean_y(2));
    }
}
