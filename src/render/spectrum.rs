//! Fourier analysis of sample and error images: power spectra, their radial averages and
//! the power in the low band. Used by tests and by the sampler-quality command to show that
//! the blue-noise sampler pushes error to high frequencies; never per frame, so these
//! functions allocate freely.
//!
//! Conventions: images are row-major `width x height` arrays of `f32`; the DFT is the
//! unnormalised one, X(u, v) = sum over pixels of x(p, q) e^(-2 pi i (u p / width + v q / height)),
//! computed in `f64` (a radix-2 FFT on power-of-two sides, a direct DFT otherwise). So by
//! Parseval the total power is `width * height` times the sum of squared deviations, and
//! white noise of variance s^2 has expected power `width * height * s^2` at every
//! frequency but DC. Frequencies are in cycles per image side: index `u` above `width / 2`
//! stands for the negative frequency `u - width`.

use std::f64::consts::TAU;

/// The power spectrum |DFT|^2 of `image` minus its mean, `width x height`, row-major,
/// not shifted: DC (which is zero after the mean is removed, up to rounding) at index 0,
/// frequency (u, v) at index `v * width + u`.
pub fn power_spectrum(image: &[f32], width: usize, height: usize) -> Vec<f32> {
    assert_eq!(
        image.len(),
        width * height,
        "power_spectrum: image is not {width}x{height}"
    );
    if image.is_empty() {
        return Vec::new();
    }
    let mean = image.iter().map(|&value| f64::from(value)).sum::<f64>() / image.len() as f64;
    let mut real: Vec<f64> = image.iter().map(|&value| f64::from(value) - mean).collect();
    let mut imaginary = vec![0.0; image.len()];

    let row_transform = Dft::new(width);
    for (real_row, imaginary_row) in real.chunks_mut(width).zip(imaginary.chunks_mut(width)) {
        row_transform.transform(real_row, imaginary_row);
    }
    let column_transform = Dft::new(height);
    let mut column_real = vec![0.0; height];
    let mut column_imaginary = vec![0.0; height];
    for column in 0..width {
        for row in 0..height {
            column_real[row] = real[row * width + column];
            column_imaginary[row] = imaginary[row * width + column];
        }
        column_transform.transform(&mut column_real, &mut column_imaginary);
        for row in 0..height {
            real[row * width + column] = column_real[row];
            imaginary[row * width + column] = column_imaginary[row];
        }
    }
    real.iter()
        .zip(&imaginary)
        .map(|(&re, &im)| (re * re + im * im) as f32)
        .collect()
}

/// The mean of `power` (as from [`power_spectrum`]) over each integer frequency radius:
/// bin `r` averages the frequencies (u, v), negative above half the side, whose radius
/// sqrt(u^2 + v^2) rounds to `r`. Bins run over `0..=min(width, height) / 2` (up to the
/// Nyquist frequency of the shorter side); frequencies beyond it (the corners) are left out.
pub fn radial_average(power: &[f32], width: usize, height: usize) -> Vec<f32> {
    assert_eq!(
        power.len(),
        width * height,
        "radial_average: spectrum is not {width}x{height}"
    );
    let nyquist = width.min(height) / 2;
    let mut sums = vec![0.0f64; nyquist + 1];
    let mut counts = vec![0usize; nyquist + 1];
    for v in 0..height {
        let frequency_v = signed_frequency(v, height);
        for u in 0..width {
            let frequency_u = signed_frequency(u, width);
            let radius = (frequency_u * frequency_u + frequency_v * frequency_v)
                .sqrt()
                .round();
            let bin = radius as usize;
            if bin <= nyquist {
                sums[bin] += f64::from(power[v * width + u]);
                counts[bin] += 1;
            }
        }
    }
    sums.iter()
        .zip(&counts)
        .map(|(&sum, &count)| {
            if count == 0 {
                0.0
            } else {
                (sum / count as f64) as f32
            }
        })
        .collect()
}

/// The mean power of the low band of `image` (mean subtracted): the mean of the
/// [`radial_average`] bins of radius 1 to `floor(max_fraction * N / 2)`, N being the
/// shorter side, so the band is the radii in (0, max_fraction x Nyquist], DC excluded, and
/// every radius counts equally however many frequencies lie on it. The band always holds
/// at least radius 1; `max_fraction` is clamped to 1 (Nyquist).
pub fn low_frequency_power(image: &[f32], width: usize, height: usize, max_fraction: f32) -> f32 {
    let radial = radial_average(&power_spectrum(image, width, height), width, height);
    let nyquist = width.min(height) / 2;
    let highest_radius =
        ((max_fraction.clamp(0.0, 1.0) * nyquist as f32).floor() as usize).clamp(1, nyquist.max(1));
    mean_over_radii(&radial, 1, highest_radius)
}

/// The mean of the radial bins `lowest..=highest` (0 if none exist).
fn mean_over_radii(radial: &[f32], lowest: usize, highest: usize) -> f32 {
    let highest = highest.min(radial.len().saturating_sub(1));
    if radial.is_empty() || lowest > highest {
        return 0.0;
    }
    let band = &radial[lowest..=highest];
    (band.iter().map(|&power| f64::from(power)).sum::<f64>() / band.len() as f64) as f32
}

/// Index `index` of an `length`-point DFT as a signed frequency: above `length / 2` it
/// stands for `index - length`.
fn signed_frequency(index: usize, length: usize) -> f64 {
    if index <= length / 2 {
        index as f64
    } else {
        index as f64 - length as f64
    }
}

/// A one-dimensional DFT of a fixed length, in place on separate real and imaginary parts.
struct Dft {
    length: usize,
    /// cos(2 pi k / length) and sin(2 pi k / length) for k in 0..length.
    cosines: Vec<f64>,
    sines: Vec<f64>,
}

impl Dft {
    fn new(length: usize) -> Self {
        let angle = |k: usize| TAU * k as f64 / length as f64;
        Self {
            length,
            cosines: (0..length).map(|k| angle(k).cos()).collect(),
            sines: (0..length).map(|k| angle(k).sin()).collect(),
        }
    }

    fn transform(&self, real: &mut [f64], imaginary: &mut [f64]) {
        debug_assert!(real.len() == self.length && imaginary.len() == self.length);
        if self.length.is_power_of_two() {
            self.fast_transform(real, imaginary);
        } else {
            self.direct_transform(real, imaginary);
        }
    }

    /// O(n^2): X(k) = sum x(n) e^(-2 pi i k n / length).
    fn direct_transform(&self, real: &mut [f64], imaginary: &mut [f64]) {
        let input: Vec<(f64, f64)> = real
            .iter()
            .copied()
            .zip(imaginary.iter().copied())
            .collect();
        for k in 0..self.length {
            let (mut sum_real, mut sum_imaginary) = (0.0, 0.0);
            for (n, &(re, im)) in input.iter().enumerate() {
                let twiddle = (k * n) % self.length;
                let (cos, sin) = (self.cosines[twiddle], self.sines[twiddle]);
                // (re + i im)(cos - i sin)
                sum_real += re * cos + im * sin;
                sum_imaginary += im * cos - re * sin;
            }
            real[k] = sum_real;
            imaginary[k] = sum_imaginary;
        }
    }

    /// Iterative radix-2 Cooley-Tukey, O(n log n); `length` a power of two.
    fn fast_transform(&self, real: &mut [f64], imaginary: &mut [f64]) {
        let length = self.length;
        if length <= 1 {
            return;
        }
        let bits = length.trailing_zeros();
        for index in 0..length {
            let reversed = index.reverse_bits() >> (usize::BITS - bits);
            if reversed > index {
                real.swap(index, reversed);
                imaginary.swap(index, reversed);
            }
        }
        let mut half = 1;
        while half < length {
            let twiddle_step = length / (2 * half);
            for start in (0..length).step_by(2 * half) {
                for offset in 0..half {
                    let twiddle = offset * twiddle_step;
                    let (cos, sin) = (self.cosines[twiddle], self.sines[twiddle]);
                    let top = start + offset;
                    let bottom = top + half;
                    // bottom * e^(-i angle) = (re + i im)(cos - i sin)
                    let rotated_real = real[bottom] * cos + imaginary[bottom] * sin;
                    let rotated_imaginary = imaginary[bottom] * cos - real[bottom] * sin;
                    real[bottom] = real[top] - rotated_real;
                    imaginary[bottom] = imaginary[top] - rotated_imaginary;
                    real[top] += rotated_real;
                    imaginary[top] += rotated_imaginary;
                }
            }
            half *= 2;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SplitMix64 (Steele, Lea and Flood 2014): a tiny, fast, seedable generator, for the
    /// white-noise images the tests compare with.
    #[derive(Debug, Clone)]
    struct SplitMix64 {
        state: u64,
    }

    impl SplitMix64 {
        /// A generator whose sequence is fixed by `seed`.
        fn new(seed: u64) -> Self {
            Self { state: seed }
        }

        /// The next 64 random bits.
        fn next_u64(&mut self) -> u64 {
            self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
    }

    fn cosine_image(width: usize, height: usize, cycles_x: usize, cycles_y: usize) -> Vec<f32> {
        let mut image = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                let phase = TAU
                    * (cycles_x as f64 * x as f64 / width as f64
                        + cycles_y as f64 * y as f64 / height as f64);
                image.push((0.5 + 0.25 * phase.cos()) as f32);
            }
        }
        image
    }

    /// Fraction of the total power whose frequency radius rounds to `radius`.
    fn power_fraction_at_radius(power: &[f32], width: usize, height: usize, radius: usize) -> f64 {
        let mut at_radius = 0.0;
        let mut total = 0.0;
        for v in 0..height {
            for u in 0..width {
                let (fu, fv) = (signed_frequency(u, width), signed_frequency(v, height));
                let p = f64::from(power[v * width + u]);
                total += p;
                if (fu * fu + fv * fv).sqrt().round() as usize == radius {
                    at_radius += p;
                }
            }
        }
        at_radius / total
    }

    #[test]
    fn a_cosine_puts_its_power_at_its_frequency() {
        // Power-of-two sides (FFT) and other sides (direct DFT), along x and along y.
        for &(width, height, cycles_x, cycles_y) in &[
            (64, 64, 5, 0),
            (64, 64, 0, 13),
            (32, 16, 7, 0),
            (12, 10, 0, 3),
            (64, 64, 32, 0),
        ] {
            let power = power_spectrum(
                &cosine_image(width, height, cycles_x, cycles_y),
                width,
                height,
            );
            let k = cycles_x + cycles_y;
            let fraction = power_fraction_at_radius(&power, width, height, k);
            assert!(
                fraction >= 0.99,
                "{width}x{height} cosine of frequency {k}: {fraction} at radius {k}"
            );
            let radial = radial_average(&power, width, height);
            let peak = (0..radial.len())
                .max_by(|&a, &b| radial[a].total_cmp(&radial[b]))
                .unwrap();
            assert_eq!(
                peak, k,
                "{width}x{height}: radial average peaks at {peak}, not {k}"
            );
        }
    }

    #[test]
    fn a_constant_image_has_no_power() {
        let image = vec![0.7f32; 32 * 24];
        let power = power_spectrum(&image, 32, 24);
        assert!(
            power.iter().all(|&p| p < 1e-9),
            "max power {}",
            power.iter().fold(0.0f32, |a, &b| a.max(b))
        );
        assert!(low_frequency_power(&image, 32, 24, 0.5) < 1e-9);
    }

    #[test]
    fn the_fft_matches_the_direct_dft_and_parseval() {
        let mut random = SplitMix64::new(99);
        let length = 64;
        let real: Vec<f64> = (0..length)
            .map(|_| random.next_u64() as f64 / u64::MAX as f64)
            .collect();
        let imaginary: Vec<f64> = (0..length)
            .map(|_| random.next_u64() as f64 / u64::MAX as f64)
            .collect();
        let dft = Dft::new(length);
        let (mut fast_re, mut fast_im) = (real.clone(), imaginary.clone());
        dft.fast_transform(&mut fast_re, &mut fast_im);
        let (mut direct_re, mut direct_im) = (real, imaginary);
        dft.direct_transform(&mut direct_re, &mut direct_im);
        for k in 0..length {
            assert!(
                (fast_re[k] - direct_re[k]).abs() < 1e-9
                    && (fast_im[k] - direct_im[k]).abs() < 1e-9
            );
        }

        let (width, height) = (16, 8);
        let image: Vec<f32> = (0..width * height)
            .map(|_| (random.next_u64() >> 40) as f32 / (1u64 << 24) as f32)
            .collect();
        let mean = image.iter().map(|&v| f64::from(v)).sum::<f64>() / image.len() as f64;
        let squared_deviations: f64 = image.iter().map(|&v| (f64::from(v) - mean).powi(2)).sum();
        let total_power: f64 = power_spectrum(&image, width, height)
            .iter()
            .map(|&p| f64::from(p))
            .sum();
        let expected = (width * height) as f64 * squared_deviations;
        assert!(
            (total_power - expected).abs() <= 1e-5 * expected,
            "{total_power} vs {expected}"
        );
    }

    #[test]
    fn the_low_band_covers_radii_up_to_the_fraction_of_nyquist() {
        // Radius 8 is inside the quarter-of-Nyquist band of a 64x64 image, radius 9 is not.
        let inside = low_frequency_power(&cosine_image(64, 64, 8, 0), 64, 64, 0.25);
        let outside = low_frequency_power(&cosine_image(64, 64, 9, 0), 64, 64, 0.25);
        assert!(inside > 1.0, "{inside}");
        assert!(outside < 1e-6 * inside, "{outside}");
    }
}
