//! Measurement tools, as library code: what `gloam bench` ([`frames`]), `raybench`,
//! `flythrough`, `convergence` and `exposure` ([`exposure_map`]) measure. Each module's
//! `Options` is its command's flags (the command line parses them and calls `run`; `gloam
//! <command> --help` lists them with their defaults); each `run` prints its table and
//! writes its reports. Outside the frame: these drive the engine's own steps and time
//! them. This page is what their tables mean and the schema of every JSON report they
//! write.
//!
//! # `gloam bench`: the frame-time profile
//!
//! The level's frames, headless, as they are played: seen through the player's eyes in a
//! play-through of the level (`--replay FILE`, else the level's won recording in
//! `tests/recordings/`, else the bot's run), each frame simulating the fixed steps its
//! predecessor's time owes (as in play, at least one: the game's vsync holds frames to 60
//! Hz) and presenting its image as the window does (tone mapping into a frame buffer, the
//! HUD laid out and tessellated; the GPU's upload is not timed), to the end of the inputs
//! unless `--frames` stops it sooner. A glTF, a level without a player start, or `--view
//! camera` is seen through the level's camera instead, along a fixed path with exactly one
//! 60 Hz step a frame, so every such run does the same work. Without `--render-scale` the
//! frames are rendered by the game's rule for the size shown (`film::render_scale_for`:
//! native up to 640 x 360's pixels, fewer and upscaled past it).
//! It prints mean, p50, p95, p99 and max per stage (`input`, `gameplay`, `animation`,
//! `transforms`, `audio`, `extract`, `blas_refit`, `tlas_build`, `render`, `film`,
//! `present`: [`crate::profile::Stage`]) and per frame, and Mrays/s. Three stages are
//! followed by their parts, which add up to them:
//!
//! - `gameplay`: `.world` (the simulation's copy of the level brought up to date),
//!   `.exposure` (the light gem's shadow rays), `.sight` (the wardens' sight rays and
//!   minds), `.rest` (the player's body, the goal and the wardens' feet);
//! - `render`: `.primary` (camera rays and their hits), `.shade` (the first vertex's
//!   materials and samples), `.shadow` (the first vertex's shadow rays), `.bounces` (the
//!   rest of every path): the render's wall time shared out by each phase's CPU time over
//!   the threads;
//! - `film`: `.temporal` (demodulation, reprojection and blending), `.spatial` (the
//!   a-trous passes, remodulating in the last), `.remodulate` (where no a-trous pass runs,
//!   `--filter temporal`), `.upscale` (the temporal upscaling; zero when rendering at the
//!   size shown), wall-clock; under the full chain `.temporal` and `.spatial` run as one
//!   chain of bands and share its wall time as their bands' CPU time was. Then the film's
//!   share of the frames' time, split between the filters and the upscaler.
//!
//! After every 30 measured frames (and after the last) it times a round of `raybench`'s
//! rays for the level traced the renderer's way (camera rays in packets, shadow rays in
//! streams, bounces one at a time; 512 x 512 camera rays, on the same threads), and prints
//! the renderer's rays per second (rays traced / render time) beside that accel-alone
//! figure's harmonic mean over camera, shadow and bounce rays, and their ratio: how much of
//! what its rays can do the renderer keeps. The ratio is the median over the rounds of each
//! window of frames' rate against its own round, so a machine whose load changes during the
//! run moves both sides of each pair together. It counts rays, not work: work saved with
//! the rays it would have cast (a path the radiance cache ends at its second vertex skips
//! its shading and its rays alike) does not raise it, however far the `render` row falls.
//! So a `tracing` line gives the render's own mix of rays (camera, shadow and bounce rays
//! a frame) and how long the accel alone takes to trace that mix, each kind at its own rate
//! from the round beside the frames, in milliseconds and as a share of the render's time:
//! the rest of the render is shading the paths. `--churn-instances N --churn-lights M`
//! splits extract + accel by spawning, despawning and quiet frames instead.
//!
//! `--json FILE`:
//!
//! ```text
//! {"scene", "frames", "width", "height", "render_width", "render_height", "threads",
//!  "simd": "native" | "portable",
//!  "view": "player" | "camera",
//!  "replay": the play-through's recording, or "autoplay" (the bot's run; player view only),
//!  "steps": fixed simulation steps the measured frames ran,
//!  "stages": {"<stage>": {"mean_ms", "p50_ms", "p95_ms", "p99_ms", "max_ms"}},
//!  "frame": {the same five}, "mrays_per_s",
//!  "gameplay_phases", "render_phases", "film_phases": {"<phase>": {the same five}},
//!  "rays_per_frame": [per frame],
//!  "cache_ended_share": the share of paths the radiance cache ended at their second vertex,
//!  "cache_learn_ms": {the same five: the cache learning each frame's samples, on a pool
//!                     thread while the next frame ran},
//!  "film_share": {"film", "upscale"}: fractions of the frames' time,
//!  "accel_mrays_per_s": {"camera", "shadow", "bounce", "harmonic_mean"},
//!  "renderer_vs_accel",
//!  "tracing": {"camera_rays", "shadow_rays", "bounce_rays", "ms", "share_of_render"},
//!  "accel_rounds": [{"after_frames", "camera", "shadow", "bounce", "harmonic_mean",
//!                    "renderer_mrays_per_s"}]}
//! ```
//!
//! `film_share` is there when a film step ran, and the accel fields when a round did. The
//! other reports, `--csv`, `--trace` (a Chrome trace) and `--chart` (a PNG), are
//! [`crate::profile`]'s.
//!
//! # `gloam raybench`: ray throughput
//!
//! Mrays/s per ray type, on one thread and on all cores, median of `--repeats` runs, by one
//! rule for every scene ([`raybench`]): through gloam's TLAS -> BLAS traversal as the
//! renderer traces (`gloam_renderer`: camera rays in packets, shadow rays in interleaved
//! streams, bounces one at a time, static instances batched), the same with every instance
//! traced on its own (`gloam_renderer_unbatched`), the largest BLAS or static batch walked
//! with no TLAS above it (`gloam_largest_blas_alone`, `gloam_largest_batch_alone`), every
//! ray type in packets (`gloam_packets`) and the single-ray layouts with AVX2 and portable
//! kernels; and through obvhs's own flat BVH2 (the baseline), the 8-wide tree gloam builds
//! from the same preset (`wide8_flat`) and obvhs's CWBVH, timed in interleaved rounds so
//! machine noise falls on all alike. The gap from `gloam_largest_blas_alone` to
//! `gloam_renderer_unbatched` is what the two-level walk costs, the gap to
//! `gloam_renderer` what is left of it once static instances are batched (on
//! dream-apartment, mostly working out the closest hit's triangle and barycentrics). The
//! benchmark apartment is in the shared test data, beside the clone:
//!
//! ```sh
//! cargo run --release -- raybench ../shared/scenes/dream-apartment.glb \
//!     --deforming-triangles 100000 --json raybench.json
//! ```
//!
//! `--json FILE`:
//!
//! ```text
//! {"scene", "primary_mrays_per_s", "shadow_mrays_per_s", "diffuse_mrays_per_s" (gloam,
//!  one thread), "threads", "all_threads": {"threads", "mrays_per_s"},
//!  "triangles" (instanced), "unique_triangles", "instances",
//!  "rays": {"primary", "shadow", "diffuse"}, "tlas_build_ms", "blas_build_ms",
//!  "blas_refit_ms", "deforming": {"triangles", "frames", "refit_ms", "rebuilds",
//!  "rebuild_ms", "sah_decay", "sah_vs_fresh_build"} (with --deforming-triangles),
//!  "baseline_obvhs_bvh2", "agreement_with_baseline" (the share of rays on which gloam and
//!  the baseline find the same hit), "wide8_flat_build", "build_study" (with
//!  --build-study), "layouts" (every layout at each thread count, with its build time)}
//! ```
//!
//! # `gloam flythrough`: image quality of the real-time film
//!
//! What [`flythrough`] compares, and how: along the level's camera path with a warden
//! patrolling across it (`--view camera`, the default), or through the player's eyes in a
//! play-through of the level, as `bench` plays it (`--view player`, from `--from` seconds
//! in, two steps a frame; no mover, so the trail figures are NaN and `moving_lamp_pool`
//! null). `--json FILE` has every figure: `level`, `view`, `width`,
//! `height`, `frames`, `render_scale`, `player_render_size`, `reference_spp`, the median
//! RMSE of each image (`median_rmse_display`, `median_rmse_linear`, `median_trail_rmse`),
//! `ratio_full_to_raw`, `ratio_temporal_to_raw`, `ratio_player_to_full`,
//! `ratio_player_to_resized`, `moving_lamp_pool` (`pixels`, `luminance_kept`,
//! `rmse_display`), `median_ms` (`render`, `temporal`, `full`, `player_render`,
//! `player_film`) and `compared`, each compared frame's errors. `--out DIR` writes the last
//! compared frame's images (raw, temporal, full, resized, player, reference) as PNGs.
//!
//! # `gloam exposure`: the exposure map
//!
//! [`exposure_map`] writes `MAP.json`:
//!
//! ```text
//! {"origin": [x, z] (metres, the minimum corner of cell [0][0]), "cell_size",
//!  "width", "depth" (cells along +x and +z),
//!  "standing", "crouching": depth rows of width values, null where the player cannot
//!      stand; row r is at z = origin.z + (r + 0.5) cell_size, value c of a row at
//!      x = origin.x + (c + 0.5) cell_size,
//!  "route": {"exists": max_exposure <= threshold,
//!            "max_exposure": the lowest peak gem of any walkable route, null when none
//!                reaches every shard and the exit,
//!            "threshold",
//!            "path": that route cell by cell as feet positions [x, y, z], from the spawn
//!                through every shard (the darkest to reach next first) to the exit, each
//!                leg the shortest of the darkest ways,
//!            "chokepoints": the brightest cell [x, y, z] of each stretch of the path above
//!                the threshold (lit, and no way round is darker)},
//!  "floors": [{"storey": 1, "standing", "crouching"}, ...] (only where a column is
//!      reached on more than one floor: the floors above the lowest)}
//! ```
//!
//! `MAP.png` is the ground storey standing, 8 pixels a cell, +x right and +z down: black
//! where no one stands, dark blue hidden, warming to yellow as the gem rises, red above the
//! threshold; the spawn white, shards cyan, the exit green. Level 1's map takes about
//! 0.2 s.

pub mod convergence;
pub mod exposure_map;
pub mod flythrough;
pub mod frames;
pub mod progress;
pub mod raybench;

/// Worker threads when a command is not told: every core.
pub fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}
