//! Frame step `render`, its output: `HdrImage`, the linear radiance image a render
//! produces, the files it is written to and read from, and how it compares with a
//! reference (`gloam compare`). The `film` step works on these images frame after frame
//! (`crate::film`).
//!
//! A pixel holds the mean radiance over the pixel's area (box filter, uniform jitter),
//! in linear Rec.709 RGB, W/(sr m^2). `.exr` files store exactly that (no exposure, no tone
//! mapping) so they compare with any reference renderer. `.png` files and the window go
//! through the one tone mapper below.
//!
//! Tone mapper: radiance x exposure, then the ACES filmic curve fitted by Narkowicz 2015
//! ("ACES Filmic Tone Mapping Curve": (x (2.51 x + 0.03)) / (x (2.43 x + 0.59) + 0.14) per
//! channel, clamped to [0, 1]), then the sRGB transfer function, then 8 bits.

use std::io::Cursor;
use std::path::Path;

use anyhow::{Context as _, bail};
use glam::Vec3;
use rayon::prelude::*;

use crate::scene::files::write_atomically;

#[derive(Clone, Debug, PartialEq)]
pub struct HdrImage {
    pub width: u32,
    pub height: u32,
    /// Mean radiance per pixel, row-major from the top-left.
    pub pixels: Vec<Vec3>,
}

impl HdrImage {
    pub fn new(width: u32, height: u32) -> HdrImage {
        HdrImage {
            width,
            height,
            pixels: vec![Vec3::ZERO; (width * height) as usize],
        }
    }

    pub fn pixel(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Mean over every pixel.
    pub fn mean(&self) -> Vec3 {
        self.pixels.iter().copied().sum::<Vec3>() / self.pixels.len().max(1) as f32
    }

    /// This image tone mapped (`tone_map`) into `rgba`, a `width` x `height` buffer of 8-bit
    /// RGBA pixels (opaque), resized bilinearly first when the sizes differ (a still frame
    /// summed at a lowered resolution): what a window shows of it.
    pub fn tone_map_into(&self, rgba: &mut [u8], width: u32, height: u32, exposure: f32) {
        if (width, height) != (self.width, self.height) {
            let resized = self.resized(width, height);
            return resized.tone_map_into(rgba, width, height, exposure);
        }
        // A row per job (`DisplayCodes` has the figures).
        let (row, codes) = (width as usize, &*DISPLAY_CODES);
        let avx2 = crate::simd::avx2();
        rgba.par_chunks_mut(row * 4)
            .zip(self.pixels.par_chunks(row))
            .for_each(|(rgba, pixels)| codes.tone_map_row(avx2, pixels, exposure, rgba));
    }

    /// Bilinearly resampled to `width` x `height`, pixel centres aligned (the window shows
    /// a lowered internal resolution this way).
    pub fn resized(&self, width: u32, height: u32) -> HdrImage {
        if (width, height) == (self.width, self.height) {
            return self.clone();
        }
        let (sx, sy) = (
            self.width as f32 / width as f32,
            self.height as f32 / height as f32,
        );
        let mut pixels = Vec::with_capacity((width * height) as usize);
        for y in 0..height {
            let fy = ((y as f32 + 0.5) * sy - 0.5).clamp(0.0, (self.height - 1) as f32);
            let (y0, ty) = (fy.floor() as u32, fy.fract());
            let y1 = (y0 + 1).min(self.height - 1);
            for x in 0..width {
                let fx = ((x as f32 + 0.5) * sx - 0.5).clamp(0.0, (self.width - 1) as f32);
                let (x0, tx) = (fx.floor() as u32, fx.fract());
                let x1 = (x0 + 1).min(self.width - 1);
                let top = self.pixel(x0, y0).lerp(self.pixel(x1, y0), tx);
                let bottom = self.pixel(x0, y1).lerp(self.pixel(x1, y1), tx);
                pixels.push(top.lerp(bottom, ty));
            }
        }
        HdrImage {
            width,
            height,
            pixels,
        }
    }

    /// Root-mean-square difference from `reference` over all pixels and channels.
    pub fn rmse(&self, reference: &HdrImage) -> f32 {
        debug_assert_eq!(self.pixels.len(), reference.pixels.len());
        let sum: f64 = self
            .pixels
            .iter()
            .zip(&reference.pixels)
            .map(|(a, b)| (*a - *b).length_squared() as f64)
            .sum();
        (sum / (3 * self.pixels.len().max(1)) as f64).sqrt() as f32
    }

    /// Writes `.exr` (linear radiance) or `.png` (tone mapped with `exposure`), by extension.
    pub fn write(&self, path: &Path, exposure: f32) -> anyhow::Result<()> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let bytes = match extension.as_deref() {
            Some("exr") => self.exr_bytes()?,
            Some("png") => self.png_bytes(exposure)?,
            _ => bail!("{}: the output must end in .exr or .png", path.display()),
        };
        write_atomically(path, &bytes)
    }

    fn exr_bytes(&self) -> anyhow::Result<Vec<u8>> {
        let data: Vec<f32> = self.pixels.iter().flat_map(|p| p.to_array()).collect();
        let image =
            image::Rgb32FImage::from_raw(self.width, self.height, data).context("image size")?;
        let mut bytes = Cursor::new(Vec::new());
        image::DynamicImage::ImageRgb32F(image)
            .write_to(&mut bytes, image::ImageFormat::OpenExr)
            .context("encoding EXR")?;
        Ok(bytes.into_inner())
    }

    fn png_bytes(&self, exposure: f32) -> anyhow::Result<Vec<u8>> {
        let data: Vec<u8> = self
            .pixels
            .iter()
            .flat_map(|p| tone_map(*p, exposure))
            .collect();
        let image =
            image::RgbImage::from_raw(self.width, self.height, data).context("image size")?;
        let mut bytes = Cursor::new(Vec::new());
        image
            .write_to(&mut bytes, image::ImageFormat::Png)
            .context("encoding PNG")?;
        Ok(bytes.into_inner())
    }
}

/// How an image compares with a reference of the same size (`gloam compare`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Comparison {
    pub mean: Vec3,
    pub reference_mean: Vec3,
    pub rmse: f32,
    /// The RMSE over the reference's mean radiance (averaged over the channels).
    pub relative_rmse: f32,
    /// The image's summed radiance over the reference's in a 4 x 4 grid of regions, top
    /// row first: a local bias shows there.
    pub region_ratios: [[f32; 4]; 4],
}

impl Comparison {
    /// The report `gloam compare` prints, naming the two images.
    pub fn report(&self, image: &str, reference: &str) -> String {
        let mut text = format!(
            "mean radiance: {image} [{:.5}, {:.5}, {:.5}] | {reference} [{:.5}, {:.5}, {:.5}]\n",
            self.mean.x,
            self.mean.y,
            self.mean.z,
            self.reference_mean.x,
            self.reference_mean.y,
            self.reference_mean.z
        );
        text += &format!(
            "RMSE: {:.6} (relative to the reference mean: {:.4})\n",
            self.rmse, self.relative_rmse
        );
        text += "region mean ratios (image / reference), 4 x 4 grid, top row first:\n";
        for row in &self.region_ratios {
            text += &row.iter().map(|r| format!(" {r:6.3}")).collect::<String>();
            text += "\n";
        }
        text
    }
}

impl HdrImage {
    /// Reads an .exr (as `gloam render` writes them) into an image.
    pub fn read_exr(path: &Path) -> anyhow::Result<HdrImage> {
        let image = image::open(path)
            .with_context(|| format!("reading {}", path.display()))?
            .into_rgb32f();
        let (width, height) = image.dimensions();
        Ok(HdrImage {
            width,
            height,
            pixels: image.pixels().map(|p| Vec3::from_array(p.0)).collect(),
        })
    }

    /// This image against `reference`, which must be the same size.
    pub fn compare(&self, reference: &HdrImage) -> anyhow::Result<Comparison> {
        if (self.width, self.height) != (reference.width, reference.height) {
            bail!(
                "the image is {}x{} but the reference is {}x{}",
                self.width,
                self.height,
                reference.width,
                reference.height
            );
        }
        let rmse = self.rmse(reference);
        let mut region_ratios = [[0.0; 4]; 4];
        for (region_y, row) in region_ratios.iter_mut().enumerate() {
            for (region_x, ratio) in row.iter_mut().enumerate() {
                let (mut sum_a, mut sum_b) = (Vec3::ZERO, Vec3::ZERO);
                let (region_x, region_y) = (region_x as u32, region_y as u32);
                for y in region_y * self.height / 4..(region_y + 1) * self.height / 4 {
                    for x in region_x * self.width / 4..(region_x + 1) * self.width / 4 {
                        sum_a += self.pixel(x, y);
                        sum_b += reference.pixel(x, y);
                    }
                }
                *ratio = sum_a.element_sum() / sum_b.element_sum().max(1e-12);
            }
        }
        Ok(Comparison {
            mean: self.mean(),
            reference_mean: reference.mean(),
            rmse,
            relative_rmse: rmse / reference.mean().element_sum().max(1e-12) * 3.0,
            region_ratios,
        })
    }
}

/// Linear radiance to the display's 8-bit sRGB codes: `display_value` quantised, to the
/// nearest code.
pub fn tone_map(radiance: Vec3, exposure: f32) -> [u8; 3] {
    tone_curve(radiance, exposure).to_array().map(display_code)
}

/// `tone_map` with the code tables already in hand (a frame's worth of pixels).
#[inline]
fn tone_map_by(codes: &DisplayCodes, radiance: Vec3, exposure: f32) -> [u8; 3] {
    // Each channel spelled out: an array's `map` here stayed a call (`try_map`, perf).
    let linear = tone_curve(radiance, exposure);
    [
        codes.code(linear.x),
        codes.code(linear.y),
        codes.code(linear.z),
    ]
}

/// Linear radiance to the display's sRGB-encoded values in [0, 1], before quantisation:
/// what a viewer sees, so image errors are measured on it.
pub fn display_value(radiance: Vec3, exposure: f32) -> Vec3 {
    Vec3::from_array(tone_curve(radiance, exposure).to_array().map(srgb_encode))
}

/// The tone curve (Narkowicz 2015, "ACES Filmic Tone Mapping Curve"): exposed linear
/// radiance to linear display values in [0, 1].
#[inline]
fn tone_curve(radiance: Vec3, exposure: f32) -> Vec3 {
    let [a, b, c, d, e] = ACES_FIT;
    let x = (radiance * exposure).max(Vec3::ZERO);
    let mapped = (x * (x * a + b)) / (x * (x * c + d) + e);
    mapped.clamp(Vec3::ZERO, Vec3::ONE)
}

/// Narkowicz's fit, (x (a x + b)) / (x (c x + d) + e): `tone_curve`'s, and its lanes' in
/// `DisplayCodes::tone_map_row_avx2`.
const ACES_FIT: [f32; 5] = [2.51, 0.03, 2.43, 0.59, 0.14];

/// The 8-bit code of a linear display value `linear` in [0, 1] (NaN: 0): the nearest code
/// to its sRGB encoding, `(srgb_encode(linear) * 255 + 0.5) as u8`, without the `powf`
/// (`DisplayCodes`).
#[inline]
fn display_code(linear: f32) -> u8 {
    DISPLAY_CODES.code(linear)
}

static DISPLAY_CODES: std::sync::LazyLock<DisplayCodes> =
    std::sync::LazyLock::new(DisplayCodes::new);

/// The encoder's 8-bit codes by table: the same byte as `powf` for every f32 (the encoding
/// rises monotonically; test `codes_from_tables_are_the_encoders_own`). With `powf`, on the
/// window's thread, tone mapping a 1280 x 720 frame took 24 ms (perf, the-keep); with the
/// tables, in parallel rows on two threads, 4.0 ms.
struct DisplayCodes {
    /// `thresholds[k - 1]`: the least f32 in [0, 1] whose code is at least `k` (k in
    /// 1..=255); then infinity, which nothing reaches.
    thresholds: [f32; 256],
    /// The code at the start of each bucket of f32s sharing their top 16 bits (for
    /// [0, 1], the exponent and 7 mantissa bits: at most one threshold lies inside any
    /// bucket, the steepest being near 0.003 where 128 buckets span about 7 codes).
    bucket_codes: Vec<u8>,
}

impl DisplayCodes {
    fn new() -> DisplayCodes {
        let code = |linear: f32| (srgb_encode(linear) * 255.0 + 0.5) as u8;
        let mut thresholds = [f32::INFINITY; 256];
        for (k, threshold) in thresholds.iter_mut().enumerate().take(255) {
            let wanted = k as u8 + 1;
            // The least bits in (low, high] whose code reaches `wanted`, bisecting the bit
            // patterns (ordered as the values are, for non-negative floats): code(low)
            // falls short (0.0's code is 0) and code(high) reaches it (1.0's is 255).
            let (mut low, mut high) = (0f32.to_bits(), 1f32.to_bits());
            while high - low > 1 {
                let middle = low + (high - low) / 2;
                if code(f32::from_bits(middle)) >= wanted {
                    high = middle;
                } else {
                    low = middle;
                }
            }
            *threshold = f32::from_bits(high);
        }
        let buckets = (1f32.to_bits() >> 16) as usize + 1;
        let bucket_codes = (0..buckets)
            .map(|bucket| code(f32::from_bits((bucket as u32) << 16)))
            .collect();
        DisplayCodes {
            thresholds,
            bucket_codes,
        }
    }

    /// `pixels` tone mapped (`tone_map`) into `rgba`, four bytes a pixel (opaque), eight
    /// pixels at a time in AVX2 lanes where `avx2`: the same codes (test
    /// `the_avx2_tone_map_gives_the_scalar_codes`).
    fn tone_map_row(&self, avx2: bool, pixels: &[Vec3], exposure: f32, rgba: &mut [u8]) {
        let mut done = 0;
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: `avx2` is true only where the CPU has AVX2, the only feature enabled.
            done = unsafe { self.tone_map_row_avx2(pixels, exposure, rgba) };
        }
        let _ = avx2;
        for (rgba, radiance) in rgba[4 * done..].chunks_exact_mut(4).zip(&pixels[done..]) {
            let [r, g, b] = tone_map_by(self, *radiance, exposure);
            rgba.copy_from_slice(&[r, g, b, 255]);
        }
    }

    /// `tone_map_row`'s whole groups of eight pixels (returns how many pixels it did). The
    /// channels are independent, so the row is read as a flat run of floats, 24 (three
    /// vectors) to eight pixels, and each lane does what `tone_curve` does, in the same
    /// IEEE operations (no fused multiply-adds); then `code_in_range` codes them.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn tone_map_row_avx2(&self, pixels: &[Vec3], exposure: f32, rgba: &mut [u8]) -> usize {
        use std::arch::x86_64::*;
        let groups = pixels.len().min(rgba.len() / 4) / 8;
        // `Vec3` is three f32s and nothing else (`repr(C)`, 12 bytes): the row as floats.
        const _: () = assert!(std::mem::size_of::<Vec3>() == 12);
        let floats = pixels.as_ptr().cast::<f32>();
        let (zero, one, exposure) = (
            _mm256_setzero_ps(),
            _mm256_set1_ps(1.0),
            _mm256_set1_ps(exposure),
        );
        let [a, b, c, d, e] = ACES_FIT.map(|k| _mm256_set1_ps(k));
        // A group's 24 display values, tone mapped in lanes, coded below.
        let mut values = [0f32; 24];
        for group in 0..groups {
            for (k, eight) in values.chunks_exact_mut(8).enumerate() {
                // SAFETY: group < groups keeps the 24 floats inside `pixels`.
                let radiance = unsafe { _mm256_loadu_ps(floats.add(24 * group + 8 * k)) };
                // `tone_curve`: max with the variable first, as f32::max, so NaN gives 0.
                let x = _mm256_max_ps(_mm256_mul_ps(radiance, exposure), zero);
                let numerator = _mm256_mul_ps(x, _mm256_add_ps(_mm256_mul_ps(x, a), b));
                let denominator =
                    _mm256_add_ps(_mm256_mul_ps(x, _mm256_add_ps(_mm256_mul_ps(x, c), d)), e);
                let mapped = _mm256_div_ps(numerator, denominator);
                let linear = _mm256_min_ps(_mm256_max_ps(mapped, zero), one);
                // `code`'s 0 where not above 0 (NaN, -0): such a value becomes +0, whose
                // code is 0.
                let above = _mm256_cmp_ps::<_CMP_GT_OQ>(linear, zero);
                // SAFETY: `eight` is 8 f32s, as many as a vector holds.
                unsafe { _mm256_storeu_ps(eight.as_mut_ptr(), _mm256_and_ps(linear, above)) };
            }
            // The tables read one value at a time: two AVX2 gathers a vector took longer
            // than these loads (a 1280 x 720 frame on one thread: 7.8 ms a pixel at a time,
            // 4.4 with gathers, 3.4 so). bench first-light 1280 x 720 from a quarter, two
            // threads, 4 alternated rounds: present p50 5.19 -> 2.53 ms.
            let out = &mut rgba[32 * group..][..32];
            for (pixel, rgb) in out.chunks_exact_mut(4).zip(values.chunks_exact(3)) {
                pixel.copy_from_slice(&[
                    self.code_in_range(rgb[0]),
                    self.code_in_range(rgb[1]),
                    self.code_in_range(rgb[2]),
                    255,
                ]);
            }
        }
        8 * groups
    }

    /// `code` of a value already in [+0, 1] (not NaN, not -0).
    #[inline(always)]
    fn code_in_range(&self, linear: f32) -> u8 {
        debug_assert!((0.0..=1.0).contains(&linear) && linear.is_sign_positive());
        let bucket = (linear.to_bits() >> 16) as usize;
        // SAFETY: in [+0, 1] a bucket is at most `1f32.to_bits() >> 16`, the table's last;
        // a code is at most 255, the thresholds' last.
        let code = unsafe { *self.bucket_codes.get_unchecked(bucket) };
        // The bucket's start code, raised past the one threshold its range may hold
        // (never two: the test walks every bucket). Without a branch: about half the
        // pixels cross it, and as a loop the mispredictions took half the time.
        let threshold = unsafe { *self.thresholds.get_unchecked(code as usize) };
        code + u8::from(threshold <= linear)
    }

    #[inline]
    fn code(&self, linear: f32) -> u8 {
        // NaN and anything not above 0 is code 0; past 1, code 255.
        if !(linear > 0.0) {
            return 0;
        }
        self.code_in_range(linear.min(1.0))
    }
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1).
pub fn srgb_encode(linear: f32) -> f32 {
    if linear <= 0.003_130_8 {
        linear * 12.92
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comparison_finds_a_local_bias_and_refuses_other_sizes() {
        let reference = HdrImage {
            width: 8,
            height: 8,
            pixels: vec![Vec3::splat(0.5); 64],
        };
        let same = reference.compare(&reference).unwrap();
        assert_eq!(same.rmse, 0.0);
        assert!(same.region_ratios.iter().flatten().all(|&r| r == 1.0));
        // The top-left quarter's top-left region twice as bright.
        let mut brighter = reference.clone();
        for y in 0..2 {
            for x in 0..2 {
                brighter.pixels[(y * 8 + x) as usize] = Vec3::ONE;
            }
        }
        let found = brighter.compare(&reference).unwrap();
        assert_eq!(found.region_ratios[0][0], 2.0);
        assert_eq!(found.region_ratios[3][3], 1.0);
        assert!(found.rmse > 0.0);
        assert!(found.report("a.exr", "b.exr").contains(" 2.000"));
        let error = HdrImage::new(4, 4)
            .compare(&reference)
            .unwrap_err()
            .to_string();
        assert!(error.contains("4x4") && error.contains("8x8"), "{error}");
    }

    #[test]
    fn codes_from_tables_are_the_encoders_own() {
        let by_encoder = |linear: f32| (srgb_encode(linear) * 255.0 + 0.5) as u8;
        let check = |linear: f32| {
            assert_eq!(display_code(linear), by_encoder(linear), "{linear:e}");
        };
        // Around every threshold, to a few ulps either side ...
        for &threshold in DISPLAY_CODES.thresholds.iter().take(255) {
            let bits = threshold.to_bits();
            for bits in bits.saturating_sub(4)..=(bits + 4).min(1f32.to_bits()) {
                check(f32::from_bits(bits));
            }
        }
        // ... and a sweep of every 97th f32 in [0, 1] (10 million).
        for bits in (0..=1f32.to_bits()).step_by(97) {
            check(f32::from_bits(bits));
        }
        // ... and every bucket's first and last f32.
        // (none of which spans more than one threshold, so a code costs one comparison).
        for bucket in 0..=(1f32.to_bits() >> 16) {
            let (first, last) = (
                f32::from_bits(bucket << 16),
                f32::from_bits((bucket << 16) | 0xffff).min(1.0),
            );
            check(first);
            check(last);
            assert!(display_code(last) - display_code(first) <= 1, "{first:e}");
        }
        assert_eq!(display_code(f32::NAN), 0);
        assert_eq!(display_code(-1.0), 0);
        assert_eq!(display_code(1.0), 255);
        assert_eq!(display_code(2.0), 255);
    }

    #[test]
    fn the_avx2_tone_map_gives_the_scalar_codes() {
        if !crate::simd::avx2() {
            println!("skipped: this CPU has no AVX2");
            return;
        }
        // The specials, then every 1999th f32 from 0 up to 64 (about 540,000 channels,
        // past the curve's shoulder at every exposure below) and their negatives, then a
        // tail shorter than eight pixels, so the scalar tail runs too.
        let specials = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            -1.0,
            f32::MAX,
            f32::MIN_POSITIVE,
            1e-40,
        ];
        let sweep = (0..=64f32.to_bits()).step_by(1999).map(f32::from_bits);
        let channels: Vec<f32> = specials
            .into_iter()
            .chain(sweep.clone())
            .chain(sweep.map(|c| -c))
            .collect();
        let mut pixels: Vec<Vec3> = channels
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect();
        pixels.truncate(pixels.len() / 8 * 8);
        pixels.extend([Vec3::splat(0.5); 5]);
        let pixels = &pixels[..];
        let codes = &*DISPLAY_CODES;
        for exposure in [0.0, 0.37, 1.0, 2.5, 16.0] {
            let mut lanes = vec![0u8; 4 * pixels.len()];
            let mut scalar = lanes.clone();
            codes.tone_map_row(true, pixels, exposure, &mut lanes);
            codes.tone_map_row(false, pixels, exposure, &mut scalar);
            for (i, (a, b)) in lanes.chunks(4).zip(scalar.chunks(4)).enumerate() {
                assert_eq!(a, b, "pixel {i} {:?} at exposure {exposure}", pixels[i]);
            }
        }
    }

    #[test]
    fn tone_map_is_monotonic_and_bounded() {
        let mut last = 0u8;
        for i in 0..1000 {
            let [r, _, _] = tone_map(Vec3::splat(i as f32 * 0.02), 1.0);
            assert!(r >= last);
            last = r;
        }
        assert_eq!(tone_map(Vec3::ZERO, 1.0), [0, 0, 0]);
        assert_eq!(tone_map(Vec3::splat(1e6), 1.0), [255, 255, 255]);
    }

    #[test]
    fn resizing_keeps_flat_images_flat_and_samples_between_pixels() {
        let mut film = HdrImage::new(2, 1);
        film.pixels = vec![Vec3::ZERO, Vec3::ONE];
        let wide = film.resized(4, 1);
        assert_eq!(
            wide.pixels.iter().map(|p| p.x).collect::<Vec<_>>(),
            vec![0.0, 0.25, 0.75, 1.0]
        );
        let mut flat = HdrImage::new(3, 3);
        flat.pixels.fill(Vec3::splat(0.5));
        assert!(
            flat.resized(7, 5)
                .pixels
                .iter()
                .all(|p| *p == Vec3::splat(0.5))
        );
    }

    #[test]
    fn exr_round_trips_radiance_exactly() {
        let mut film = HdrImage::new(3, 2);
        film.pixels[4] = Vec3::new(17.0, 12.0, 4.0);
        film.pixels[1] = Vec3::new(1e-4, 0.5, 2.25);
        let bytes = film.exr_bytes().unwrap();
        let decoded = image::load_from_memory(&bytes).unwrap().into_rgb32f();
        let back: Vec<Vec3> = decoded.pixels().map(|p| Vec3::from_array(p.0)).collect();
        assert_eq!(back, film.pixels);
    }
}
