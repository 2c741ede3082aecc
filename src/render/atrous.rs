//! Frame step `film`, second filter: the edge-avoiding a-trous wavelet filter of SVGF
//! (Dammertz et al. 2010, "Edge-Avoiding A-Trous Wavelet Transform for fast Global
//! Illumination Filtering"; Schied et al. 2017 for the variance-guided luminance weight),
//! on the demodulated illumination `temporal` accumulated.
//!
//! Each iteration i blurs with a 3 x 3 B-spline kernel (1/4, 1/2, 1/4 per axis) whose taps
//! are 2^i pixels apart, so `iterations` passes reach 2^(iterations+1) - 1 pixels across at
//! the cost of 9 taps each. A tap's kernel weight is multiplied by edge-stopping terms:
//! - normal: max(0, n_p . n_q)^128;
//! - depth: exp(-|z_p - z_q| / (sigma_depth |grad z| |p - q| + eps)), the depth change
//!   the surface's own slope explains is free;
//! - luminance: exp(-|l_p - l_q| / (sigma_luminance sqrt(g3x3(variance_p)) + eps)), noise
//!   of the expected size is smoothed, real edges in the lighting are kept;
//! - albedo: exp(-|a_p - a_q|_1 / sigma_albedo), so light is not averaged across materials;
//! - instance: taps on another instance count zero.
//!
//! The variance is filtered alongside (weights squared), so later, wider iterations trust
//! the already-smoothed luminance more. Rows are filtered in parallel bands.

use glam::Vec3;
use rayon::prelude::*;

use super::guides::{Guides, NO_INSTANCE};
use super::temporal::{BAND_ROWS, luminance};

#[derive(Clone, Debug, PartialEq)]
pub struct AtrousSettings {
    /// Passes, each with twice the tap spacing of the last (0 turns the filter off).
    pub iterations: u32,
    pub sigma_luminance: f32,
    pub sigma_depth: f32,
    pub sigma_albedo: f32,
}

impl Default for AtrousSettings {
    fn default() -> Self {
        AtrousSettings {
            iterations: 4,
            sigma_luminance: 4.0,
            sigma_depth: 1.0,
            sigma_albedo: 0.1,
        }
    }
}

/// The filtered illumination, and the first iteration's (SVGF keeps it as history).
pub struct Filtered {
    pub illumination: Vec<Vec3>,
    pub first_iteration: Vec<Vec3>,
}

/// B-spline weights of the 3-tap kernel (the variance prefilter's; the wavelet passes
/// spell out the products in their `TAPS`).
const KERNEL: [f32; 3] = [0.25, 0.5, 0.25];

/// What a tap reads of a pixel's guides, packed into 32 bytes (a `GuidePixel` is 80: the
/// packed copy cut the filter's time by a third at 320x180, `gloam flythrough`).
#[derive(Clone, Copy, Debug)]
struct Texel {
    normal: Vec3,
    depth: f32,
    albedo: Vec3,
    instance: u32,
}

pub fn filter(
    illumination: &[Vec3],
    variance: &[f32],
    guides: &Guides,
    settings: &AtrousSettings,
) -> Filtered {
    let (width, height) = (guides.width as usize, guides.height as usize);
    let depth_slope = depth_slopes(guides);
    let texels: Vec<Texel> = guides
        .pixels
        .par_iter()
        .map(|g| Texel {
            normal: g.normal.into(),
            depth: g.depth,
            albedo: g.albedo,
            instance: g.instance,
        })
        .collect();
    let mut colour = illumination.to_vec();
    let mut spread = variance.to_vec();
    let mut first_iteration = Vec::new();
    let mut next_colour = vec![Vec3::ZERO; colour.len()];
    let mut next_spread = vec![0.0f32; colour.len()];
    // SVGF prefilters the variance before every pass; here only before the first (later
    // passes read the variance the wavelet passes themselves filtered), a pass's cost less.
    let blurred_variance = blur_variance(&spread, guides);
    for iteration in 0..settings.iterations {
        let step = 1usize << iteration;
        let luminances: Vec<f32> = colour.par_iter().map(|c| luminance(*c)).collect();
        // The 8 taps around the centre: offset, kernel weight, distance in taps.
        const TAPS: [(i64, i64, f32, f32); 8] = [
            (-1, -1, 0.0625, std::f32::consts::SQRT_2),
            (0, -1, 0.125, 1.0),
            (1, -1, 0.0625, std::f32::consts::SQRT_2),
            (-1, 0, 0.125, 1.0),
            (1, 0, 0.125, 1.0),
            (-1, 1, 0.0625, std::f32::consts::SQRT_2),
            (0, 1, 0.125, 1.0),
            (1, 1, 0.0625, std::f32::consts::SQRT_2),
        ];
        next_colour
            .par_chunks_mut(width * BAND_ROWS)
            .zip(next_spread.par_chunks_mut(width * BAND_ROWS))
            .enumerate()
            .for_each(|(band, (colours, spreads))| {
                let first = band * width * BAND_ROWS;
                for (offset, (out_colour, out_spread)) in
                    colours.iter_mut().zip(spreads.iter_mut()).enumerate()
                {
                    let p = first + offset;
                    let centre = &texels[p];
                    if centre.instance == NO_INSTANCE {
                        *out_colour = colour[p];
                        *out_spread = spread[p];
                        continue;
                    }
                    let (x, y) = ((p % width) as i64, (p / width) as i64);
                    let luminance_p = luminances[p];
                    // Later passes read the variance the earlier ones already filtered.
                    let variance_p = if iteration == 0 {
                        blurred_variance[p]
                    } else {
                        spread[p]
                    };
                    let luminance_scale =
                        1.0 / (settings.sigma_luminance * variance_p.max(0.0).sqrt() + 1e-6);
                    // Per-tap divisions hoisted: one reciprocal per tap distance.
                    let depth_epsilon = 1e-3 * centre.depth + 1e-4;
                    let depth_slope_step = settings.sigma_depth * depth_slope[p] * step as f32;
                    let depth_straight = 1.0 / (depth_slope_step + depth_epsilon);
                    let depth_diagonal =
                        1.0 / (depth_slope_step * std::f32::consts::SQRT_2 + depth_epsilon);
                    let albedo_scale = 1.0 / settings.sigma_albedo;
                    // The centre tap: kernel 1/2 x 1/2, every edge term 1.
                    let mut sum = colour[p] * 0.25;
                    let mut sum_spread = spread[p] * 0.0625;
                    let mut weights = 0.25f32;
                    for (dx, dy, kernel, distance) in TAPS {
                        let (qx, qy) = (x + dx * step as i64, y + dy * step as i64);
                        if qx < 0 || qy < 0 || qx >= width as i64 || qy >= height as i64 {
                            continue;
                        }
                        let q = qy as usize * width + qx as usize;
                        let tap = &texels[q];
                        let same_instance = (tap.instance == centre.instance) as u32 as f32;
                        let depth_scale = if distance > 1.0 {
                            depth_diagonal
                        } else {
                            depth_straight
                        };
                        let weight = kernel
                            * same_instance
                            * normal_weight(centre.normal, tap.normal)
                            * fast_exp(
                                -((centre.depth - tap.depth).abs() * depth_scale
                                    + (luminance_p - luminances[q]).abs() * luminance_scale
                                    + (centre.albedo - tap.albedo).abs().element_sum()
                                        * albedo_scale),
                            );
                        sum += colour[q] * weight;
                        sum_spread += spread[q] * weight * weight;
                        weights += weight;
                    }
                    *out_colour = sum / weights;
                    *out_spread = sum_spread / (weights * weights);
                }
            });
        std::mem::swap(&mut colour, &mut next_colour);
        std::mem::swap(&mut spread, &mut next_spread);
        if iteration == 0 {
            first_iteration = colour.clone();
        }
    }
    if settings.iterations == 0 {
        first_iteration = colour.clone();
    }
    Filtered {
        illumination: colour,
        first_iteration,
    }
}

/// n_p . n_q raised to the 128th power by seven squarings (powf per tap cost more than
/// the rest of the weight).
#[inline]
fn normal_weight(p: Vec3, q: Vec3) -> f32 {
    let mut w = p.dot(q).max(0.0);
    for _ in 0..7 {
        w *= w;
    }
    w
}

/// e^x for x <= 0 to about 1e-4 relative: 2^(x log2 e) from the exponent bits and a cubic
/// for the fraction. libm's expf was a third of the filter's time; a weight needs no more.
#[inline]
fn fast_exp(x: f32) -> f32 {
    let y = (x * std::f32::consts::LOG2_E).clamp(-126.0, 0.0);
    // floor() is a libm call on baseline x86-64 (no SSE4.1 roundss): truncate instead,
    // which for y <= 0 rounds up, and step down when it did.
    let mut whole = y as i32;
    if (whole as f32) > y {
        whole -= 1;
    }
    let f = y - whole as f32;
    let fraction = 1.0 + f * (0.695_834_5 + f * (0.226_067_3 + f * 0.078_024_5));
    f32::from_bits(((whole + 127) as u32) << 23) * fraction
}

/// Per pixel, how fast depth changes per pixel across the surface: the smaller of the
/// forward and backward differences on each axis (so an edge beside the pixel does not
/// count), the larger axis.
fn depth_slopes(guides: &Guides) -> Vec<f32> {
    let (width, height) = (guides.width as usize, guides.height as usize);
    let depth_at = |x: usize, y: usize, instance: u32| {
        let g = &guides.pixels[y * width + x];
        (g.instance == instance).then_some(g.depth)
    };
    (0..width * height)
        .into_par_iter()
        .map(|p| {
            let centre = &guides.pixels[p];
            if centre.is_sky() {
                return 0.0;
            }
            let (x, y) = (p % width, p / width);
            let axis = |before: Option<f32>, after: Option<f32>| {
                let slopes = [before, after].map(|d| d.map(|d| (d - centre.depth).abs()));
                match slopes {
                    [Some(a), Some(b)] => a.min(b),
                    [Some(a), None] | [None, Some(a)] => a,
                    [None, None] => 0.0,
                }
            };
            let horizontal = axis(
                (x > 0)
                    .then(|| depth_at(x - 1, y, centre.instance))
                    .flatten(),
                (x + 1 < width)
                    .then(|| depth_at(x + 1, y, centre.instance))
                    .flatten(),
            );
            let vertical = axis(
                (y > 0)
                    .then(|| depth_at(x, y - 1, centre.instance))
                    .flatten(),
                (y + 1 < height)
                    .then(|| depth_at(x, y + 1, centre.instance))
                    .flatten(),
            );
            horizontal.max(vertical)
        })
        .collect()
}

/// The variance under a 3 x 3 Gaussian (1/4, 1/2, 1/4 per axis), over non-sky pixels:
/// SVGF's prefilter, so one noisy variance estimate does not decide a weight.
fn blur_variance(variance: &[f32], guides: &Guides) -> Vec<f32> {
    let (width, height) = (guides.width as usize, guides.height as usize);
    (0..width * height)
        .into_par_iter()
        .map(|p| {
            let (x, y) = (p % width, p / width);
            let (mut sum, mut weights) = (0.0f32, 0.0f32);
            for (ky, dy) in [-1i64, 0, 1].into_iter().enumerate() {
                for (kx, dx) in [-1i64, 0, 1].into_iter().enumerate() {
                    let (qx, qy) = (x as i64 + dx, y as i64 + dy);
                    if qx < 0 || qy < 0 || qx >= width as i64 || qy >= height as i64 {
                        continue;
                    }
                    let q = qy as usize * width + qx as usize;
                    if guides.pixels[q].is_sky() {
                        continue;
                    }
                    let w = KERNEL[kx] * KERNEL[ky];
                    sum += variance[q] * w;
                    weights += w;
                }
            }
            if weights > 0.0 { sum / weights } else { 0.0 }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::guides::GuidePixel;
    use glam::Vec3A;

    fn flat_guides(width: u32, height: u32) -> Guides {
        let mut guides = Guides::new(width, height);
        for g in &mut guides.pixels {
            *g = GuidePixel {
                position: Vec3A::ZERO,
                normal: Vec3A::Z,
                depth: 3.0,
                instance: 0,
                albedo: Vec3::splat(0.5),
                emission: Vec3::ZERO,
            };
        }
        guides
    }

    /// A fixed pseudo-random sequence in [0, 1).
    fn noise(i: usize) -> f32 {
        let mut h = (i as u32).wrapping_mul(0x9e37_79b9) ^ 0x5bd1_e995;
        h ^= h >> 15;
        h = h.wrapping_mul(0x2c1b_3c6d);
        h ^= h >> 12;
        (h >> 8) as f32 / (1u32 << 24) as f32
    }

    #[test]
    fn fast_exp_is_close_to_exp() {
        for i in 0..2000 {
            let x = -(i as f32) * 0.01;
            let (fast, exact) = (fast_exp(x), x.exp());
            assert!(
                (fast - exact).abs() <= 2e-4 * exact + 1e-30,
                "{x}: {fast} vs {exact}"
            );
        }
        assert_eq!(fast_exp(-1e9), fast_exp(-126.0 / std::f32::consts::LOG2_E));
    }

    #[test]
    fn noise_on_a_flat_wall_is_smoothed_and_its_mean_kept() {
        let guides = flat_guides(64, 64);
        let illumination: Vec<Vec3> = (0..64 * 64).map(|i| Vec3::splat(noise(i))).collect();
        let variance = vec![1.0 / 12.0; 64 * 64];
        let out = filter(
            &illumination,
            &variance,
            &guides,
            &AtrousSettings::default(),
        );
        let mean = |v: &[Vec3]| v.iter().map(|c| c.x).sum::<f32>() / v.len() as f32;
        let spread = |v: &[Vec3]| {
            let m = mean(v);
            (v.iter().map(|c| (c.x - m).powi(2)).sum::<f32>() / v.len() as f32).sqrt()
        };
        assert!((mean(&out.illumination) - mean(&illumination)).abs() < 0.01);
        // Uniform noise has a deviation of 0.29; four passes take it well below a third.
        assert!(
            spread(&out.illumination) < spread(&illumination) / 3.0,
            "{} -> {}",
            spread(&illumination),
            spread(&out.illumination)
        );
    }

    #[test]
    fn edges_in_normal_depth_albedo_and_instance_are_kept() {
        for edge in ["normal", "depth", "albedo", "instance"] {
            let mut guides = flat_guides(32, 32);
            let mut illumination = vec![Vec3::splat(0.2); 32 * 32];
            for p in 0..32 * 32 {
                if p % 32 >= 16 {
                    illumination[p] = Vec3::splat(1.0);
                    let g = &mut guides.pixels[p];
                    match edge {
                        "normal" => g.normal = Vec3A::X,
                        "depth" => g.depth = 6.0,
                        "albedo" => g.albedo = Vec3::splat(0.9),
                        _ => g.instance = 1,
                    }
                }
            }
            let out = filter(
                &illumination,
                &vec![100.0; 32 * 32],
                &guides,
                &AtrousSettings::default(),
            );
            // Next to the edge, on either side, the other side does not leak in.
            assert!(
                (out.illumination[10 * 32 + 15].x - 0.2).abs() < 0.01,
                "{edge}"
            );
            assert!(
                (out.illumination[10 * 32 + 16].x - 1.0).abs() < 0.01,
                "{edge}"
            );
        }
    }
}
