//! `gloam convergence`: how fast each sampler and integrator approaches the converged image.
//!
//! A measurement tool over `render`, outside the frame. Renders a converged image (path
//! integrator, blue noise, `--reference-spp`), then prints the RMSE against it of:
//! 1. the path integrator at 1, 4 and 16 spp with the white, stratified and blue samplers;
//! 2. path (16 spp, stratified and blue) against reference (white) given the same
//!    wall-clock time, the reference's sample count calibrated from a timed trial;
//! 3. how blue the blue sampler's error is over whole paths: the power of the 1-spp
//!    luminance error below 1/8 of the image size (radii to a quarter of Nyquist,
//!    `spectrum::low_frequency_power`), blue against white, over the seeds.

use std::path::PathBuf;

use crate::render::light::luminance;
use crate::render::spectrum::low_frequency_power;
use crate::render::{
    Camera, HdrImage, IntegratorKind, RenderScene, RenderSettings, SamplerKind, render,
};
use crate::scene::world::Scene;

#[derive(Debug, clap::Args)]
pub struct Options {
    /// Level or glTF/GLB file.
    pub scene: PathBuf,
    /// The render width, in pixels.
    #[arg(long, default_value_t = 128, value_parser = crate::headless::values::count())]
    pub width: u32,
    /// The render height, in pixels.
    #[arg(long, default_value_t = 128, value_parser = crate::headless::values::count())]
    pub height: u32,
    /// Samples per pixel of the converged image.
    #[arg(long, default_value_t = 4096, value_parser = crate::headless::values::count())]
    pub reference_spp: u32,
    /// Seeds each RMSE is averaged over.
    #[arg(long, default_value_t = 8, value_parser = crate::headless::values::count())]
    pub seeds: u32,
    /// Bounces at most (0: emitters only, 1: direct lighting, ...).
    #[arg(long, default_value_t = 8, value_parser = crate::headless::values::count_or_zero())]
    pub max_depth: u32,
}

/// Root of the mean over seeds 1..=seeds of each render's squared RMSE.
fn mean_rmse(seeds: u32, rmse_of_seed: impl Fn(u32) -> f32) -> f32 {
    let seeds = seeds.max(1);
    ((1..=seeds)
        .map(|seed| rmse_of_seed(seed).powi(2) as f64)
        .sum::<f64>()
        / seeds as f64)
        .sqrt() as f32
}

/// Renders, timed; `bar` counts the samples per pixel rendered.
fn timed(
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    bar: &indicatif::ProgressBar,
) -> (HdrImage, f64, f64) {
    let output = render(scene, camera, settings, &|_| {});
    bar.inc(u64::from(settings.spp));
    let mrays = output.mrays_per_second();
    (output.image, output.seconds, mrays)
}

pub fn run(options: &Options) -> anyhow::Result<()> {
    if options.width == 0 || options.height == 0 || options.reference_spp == 0 {
        anyhow::bail!("--width, --height and --reference-spp must be at least 1");
    }
    let scene = Scene::load(&options.scene)?;
    let render_scene = crate::frame::render_scene(&scene);
    let camera = Camera::new(&render_scene.camera, options.width, options.height);
    let settings =
        |spp: u32, integrator: IntegratorKind, sampler: SamplerKind, seed: u32| RenderSettings {
            width: options.width,
            height: options.height,
            spp,
            seed,
            frame: 0,
            integrator,
            sampler,
            max_depth: options.max_depth,
        };
    // Samples per pixel of every render below (the equal-time references are added when
    // their counts are known).
    let planned = options.reference_spp
        + 3 * 21 * options.seeds
        + 16
        + 2 * 16 * (1 + options.seeds)
        + 2 * options.seeds;
    let bar = super::progress::bar(u64::from(planned), "spp rendered");
    let (converged, seconds, _) = timed(
        &render_scene,
        &camera,
        &settings(
            options.reference_spp,
            IntegratorKind::Path,
            SamplerKind::BlueNoise,
            1000,
        ),
        &bar,
    );
    println!(
        "gloam convergence {}: {}x{}, max depth {}; converged image: path, blue, {} spp ({seconds:.1} s)",
        options.scene.display(),
        options.width,
        options.height,
        options.max_depth,
        options.reference_spp
    );
    println!(
        "RMSE against it (path integrator), over {} seeds:",
        options.seeds
    );
    println!(
        "{:<12} {:>10} {:>10} {:>10}",
        "sampler", "1 spp", "4 spp", "16 spp"
    );
    for sampler in [
        SamplerKind::White,
        SamplerKind::Stratified,
        SamplerKind::BlueNoise,
    ] {
        let row: Vec<String> = [1, 4, 16]
            .iter()
            .map(|&spp| {
                format!(
                    "{:>10.5}",
                    mean_rmse(options.seeds, |seed| timed(
                        &render_scene,
                        &camera,
                        &settings(spp, IntegratorKind::Path, sampler, seed),
                        &bar
                    )
                    .0
                    .rmse(&converged))
                )
            })
            .collect();
        println!("{:<12} {}", sampler.name(), row.join(" "));
    }

    // Equal time: path with each structured sampler against the reference integrator with
    // white noise, its sample count calibrated to the path render's time from a trial.
    let (_, trial_seconds, _) = timed(
        &render_scene,
        &camera,
        &settings(16, IntegratorKind::Reference, SamplerKind::White, 1),
        &bar,
    );
    println!("equal time (path at 16 spp against the reference given the same seconds):");
    for sampler in [SamplerKind::Stratified, SamplerKind::BlueNoise] {
        let (_, path_seconds, path_mrays) = timed(
            &render_scene,
            &camera,
            &settings(16, IntegratorKind::Path, sampler, 1),
            &bar,
        );
        let reference_spp = ((16.0 * path_seconds / trial_seconds.max(1e-9)).round() as u32).max(1);
        bar.inc_length(u64::from(reference_spp * (1 + options.seeds)));
        let (_, reference_seconds, reference_mrays) = timed(
            &render_scene,
            &camera,
            &settings(
                reference_spp,
                IntegratorKind::Reference,
                SamplerKind::White,
                1,
            ),
            &bar,
        );
        let path_rmse = mean_rmse(options.seeds, |seed| {
            timed(
                &render_scene,
                &camera,
                &settings(16, IntegratorKind::Path, sampler, seed),
                &bar,
            )
            .0
            .rmse(&converged)
        });
        let reference_rmse = mean_rmse(options.seeds, |seed| {
            timed(
                &render_scene,
                &camera,
                &settings(
                    reference_spp,
                    IntegratorKind::Reference,
                    SamplerKind::White,
                    seed,
                ),
                &bar,
            )
            .0
            .rmse(&converged)
        });
        println!(
            "  path 16 spp ({:<10}) {path_seconds:6.2} s {path_mrays:6.2} Mrays/s RMSE {path_rmse:.5} | reference {reference_spp:4} spp (white) {reference_seconds:6.2} s {reference_mrays:6.2} Mrays/s RMSE {reference_rmse:.5} | ratio {:.3}",
            sampler.name(),
            path_rmse / reference_rmse.max(1e-12)
        );
    }

    // Whole paths at 1 spp: the low band of each seed's luminance error, blue over white.
    let low_band = |sampler: SamplerKind| -> f64 {
        (1..=options.seeds)
            .map(|seed| {
                let (film, _, _) = timed(
                    &render_scene,
                    &camera,
                    &settings(1, IntegratorKind::Path, sampler, seed),
                    &bar,
                );
                f64::from(low_band_error_power(&film, &converged))
            })
            .sum::<f64>()
            / f64::from(options.seeds.max(1))
    };
    let (blue, white) = (
        low_band(SamplerKind::BlueNoise),
        low_band(SamplerKind::White),
    );
    bar.finish_and_clear();
    println!(
        "blue noise over whole paths (1 spp, {} seeds): power of the luminance error below 1/8 of the image size, blue {blue:.3e} / white {white:.3e} = {:.3}",
        options.seeds,
        blue / white.max(1e-30)
    );
    Ok(())
}

/// The mean power of `film`'s luminance error against `converged` over the radii below
/// 1/8 of the image size (a quarter of Nyquist).
fn low_band_error_power(film: &HdrImage, converged: &HdrImage) -> f32 {
    let error: Vec<f32> = film
        .pixels
        .iter()
        .zip(&converged.pixels)
        .map(|(value, truth)| luminance(*value - *truth))
        .collect();
    low_frequency_power(&error, film.width as usize, film.height as usize, 0.25)
}
