//! `gloam raybench`: ray throughput per ray type, and BVH build, refit and TLAS times.
//!
//! A measurement tool over `accel`, outside the frame. One run:
//! 1. load the scene and extract its static BLASes and instances (BLAS build timed);
//! 2. optionally repeat the instances in a grid (`--instances N`) and add a deforming
//!    wavy grid (`--deforming-triangles M`) placed below the scene;
//! 3. make the rays once, by one rule for every scene: size x size primary
//!    rays from the camera; per primary hit, one shadow ray to a uniform point on the
//!    emissive triangles and one cosine-weighted diffuse bounce;
//! 4. time each ray type through gloam's TLAS -> BLAS traversal, and through obvhs's own
//!    flat BVH2 (the baseline) and CWBVH over the same world-space triangles, on one thread
//!    and on `--threads`, `--repeats` times; report medians;
//! 5. time TLAS rebuilds and the deforming grid's refits.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context as _, bail};
use glam::{Affine3A, Mat3A, Vec2, Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::bvh2::builder::{build_bvh2, build_bvh2_from_tris};
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::RayHit;
use obvhs::rt_triangle::RtTriangle;
use obvhs::triangle::Triangle;
use rayon::prelude::*;
use serde_json::{Value, json};

use crate::accel::{
    AccelScene, Blas, BlasKind, Instance, InstanceMask, Kernels, MeshGeometry, Mobility, Opaque,
    Ray, RefitOutcome, Traversal, WideBvh,
};
use crate::frame::render_scene;
use crate::profile::AccelRays;
use crate::render::light::Light;
use crate::scene::files::write_atomically;
use crate::scene::world::{CameraPlacement, Scene};

/// Flattening more world-space triangles than this for the baseline would need gigabytes.
const MAX_FLAT_TRIANGLES: usize = 5_000_000;

#[derive(Debug, clap::Args)]
pub struct Options {
    /// Level or glTF/GLB file (its camera; emissive triangles are the shadow-ray targets).
    pub scene: PathBuf,
    /// Repeat the scene's instances in a grid until there are N.
    #[arg(long, value_parser = crate::headless::values::size())]
    pub instances: Option<usize>,
    /// Add a deforming grid of at least M triangles and time its per-frame refit.
    #[arg(long, default_value_t = 0, value_parser = crate::headless::values::size_or_zero())]
    pub deforming_triangles: usize,
    /// Threads for the multi-threaded measurement (one thread is always measured).
    #[arg(long, default_value_t = crate::headless::bench::default_threads(), value_parser = crate::headless::values::size())]
    pub threads: usize,
    /// Primary rays per side (size x size).
    #[arg(long, default_value_t = 512, value_parser = crate::headless::values::count())]
    pub size: u32,
    /// Timed runs per measurement; medians are reported.
    #[arg(long, default_value_t = 5, value_parser = crate::headless::values::size())]
    pub repeats: usize,
    /// Write the report as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Also build the flat triangles with obvhs's other presets (less or no reinsertion,
    /// a shorter PLOC search; pre-split triangles) and trace each collapsed 8 wide: what
    /// build quality costs at load time against what it saves per ray.
    #[arg(long)]
    pub build_study: bool,
}

/// obvhs presets the build study compares with the medium preset of `wide8_flat` (static
/// BLASes use the slow one).
const STUDY_PRESETS: [(&str, BvhBuildParams); 4] = [
    // PLOC search distance 1, reinsertion of 1% of nodes.
    ("wide8_flat_very_fast", BvhBuildParams::very_fast_build()),
    // Search distance low, 2% reinsertion.
    ("wide8_flat_fast", BvhBuildParams::fast_build()),
    // Search distance high, 20% reinsertion, without splits (as static BLASes build).
    (
        "wide8_flat_slow",
        BvhBuildParams {
            pre_split: false,
            ..BvhBuildParams::slow_build()
        },
    ),
    // The same, large triangles' boxes split first (obvhs's `split_aabbs_preset`, in the
    // spirit of Ernst & Greiner 2007's early split clipping).
    ("wide8_flat_slow_presplit", BvhBuildParams::slow_build()),
];

/// Rays of each type, made once and traced by every layout.
struct RaySet {
    primary: Vec<Ray>,
    shadow: Vec<Ray>,
    diffuse: Vec<Ray>,
}

/// Mrays/s medians for the three ray types.
#[derive(Clone, Copy, Default)]
struct Throughput {
    primary: f64,
    shadow: f64,
    diffuse: f64,
}

impl Throughput {
    fn json(&self) -> Value {
        json!({"primary_mrays_per_s": round(self.primary), "shadow_mrays_per_s": round(self.shadow), "diffuse_mrays_per_s": round(self.diffuse)})
    }
}

fn round(value: f64) -> f64 {
    (value * 1000.0).round() / 1000.0
}

fn milliseconds(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}

pub fn run(options: &Options) -> anyhow::Result<()> {
    let name = options.scene.display().to_string();
    if options.size == 0 || options.repeats == 0 || options.threads == 0 {
        bail!("--size, --repeats and --threads must be at least 1");
    }
    let phase = super::progress::spinner("loading");
    // 1. Load and extract.
    let scene = Scene::load(&options.scene)?;
    let start = Instant::now();
    let render = render_scene(&scene);
    let blas_build_ms = milliseconds(start);
    let emitters = emitters(&render.lights.lights);
    let camera = render.camera.clone();
    let mut accel = render.accel;
    let scene_instances = accel.instances().len();
    if scene_instances == 0 {
        bail!("{name}: the scene places no triangles, so there is nothing to trace");
    }
    let bounds = accel.bounds();

    phase.set_message("building replicas");
    // 2. Replicas and the deforming grid.
    if let Some(wanted) = options.instances {
        replicate_instances(&mut accel, scene_instances, wanted);
    }
    let deforming = if options.deforming_triangles > 0 {
        let grid = crate::scene::kit::stress_grid(options.deforming_triangles)?;
        let geometry = MeshGeometry {
            materials: vec![0; grid.indices.len()],
            positions: grid.positions,
            normals: grid.normals,
            uvs: grid.uvs,
            triangles: grid.indices,
            alpha_tested: Vec::new(),
        };
        let start = Instant::now();
        let blas = Blas::build(geometry, BlasKind::Deforming);
        let build_ms = milliseconds(start);
        accel.blases.push(blas);
        let below = Affine3A::from_translation(Vec3::new(0.0, bounds.min.y - 2.0, 0.0));
        accel.push_instance(Instance::new(
            accel.blases.len() as u32 - 1,
            below,
            InstanceMask::ALL,
            u64::MAX,
        ));
        Some((accel.blases.len() - 1, build_ms))
    } else {
        None
    };
    accel.rebuild_tlas();

    phase.set_message("making rays");
    // 3. Rays.
    let rays = make_rays(&accel, &camera, &emitters, options.size);
    println!(
        "gloam raybench {name}: {} triangles in {} BLASes, {} instances ({} triangles instanced, {} instances in static batches); {} primary, {} shadow, {} diffuse rays; median of {}",
        accel.blases.iter().map(Blas::triangle_count).sum::<usize>(),
        accel.blases.len(),
        accel.instances().len(),
        accel.instanced_triangle_count(),
        accel.batched_instance_count(),
        rays.primary.len(),
        rays.shadow.len(),
        rays.diffuse.len(),
        options.repeats
    );

    phase.set_message("measuring throughput");
    // 4. Throughput. Every layout is built first, then measured in interleaved rounds (each
    //    round times every layout once), so the machine's slow and fast spells fall on all
    //    of them alike and the ratios of medians compare like with like.
    let mut thread_counts = vec![1];
    if options.threads > 1 {
        thread_counts.push(options.threads);
    }
    // gloam's TLAS over BLASes, once per BLAS traversal (copies differ only in that).
    let with_traversal = |traversal: Traversal| {
        let mut copy = AccelScene::new(accel.blases.clone(), accel.instances().to_vec());
        copy.set_traversal(traversal);
        copy
    };
    let portable = with_traversal(Traversal::Wide(Kernels::Portable));
    let bvh2 = with_traversal(Traversal::Bvh2);
    // Every instance traced on its own through the TLAS, as before static batching.
    let unbatched = AccelScene::new(
        accel.blases.clone(),
        accel
            .instances()
            .iter()
            .map(|instance| instance.clone().with_mobility(Mobility::Movable))
            .collect(),
    );
    let flat_count = accel.instanced_triangle_count();
    let mut agreement = None;
    // The flat builds run on one thread (obvhs's builders use rayon where they can), so
    // their times are the one-thread build figures.
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .context("starting a one-thread pool")?;
    let flat = (flat_count <= MAX_FLAT_TRIANGLES).then(|| one_thread.install(|| {
        let world = flat_triangles(&accel);
        // obvhs BVH2, the same build preset as static BLASes: the baseline.
        let start = Instant::now();
        let rt: Vec<RtTriangle> = world
            .iter()
            .map(|t| RtTriangle::new(t.v0, t.v1, t.v2))
            .collect();
        let conversion_ms = milliseconds(start);
        let start = Instant::now();
        let bvh = build_bvh2(&rt, BvhBuildParams::medium_build(), &mut Default::default());
        let bvh_ms = milliseconds(start) + conversion_ms;
        let ordered: Vec<RtTriangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| rt[i as usize])
            .collect();
        // The same preset collapsed 8 wide: gloam's BLAS traversal without the TLAS.
        let (wide_bvh_ms, wide, collapse_ms) =
            wide_over(&world, &rt, BvhBuildParams::medium_build());
        let wide_bvh_ms = wide_bvh_ms + conversion_ms;
        let wide_stats = wide.as_ref().map(|wide| {
            json!({
                "bvh2_build_ms": round(wide_bvh_ms),
                "collapse_ms": round(collapse_ms),
                "nodes": wide.node_count(),
                "blocks": wide.block_count(),
                "lanes_used": round(wide.triangle_count() as f64 / (wide.block_count() * 8).max(1) as f64),
                "depth": wide.depth(),
            })
        });
        // obvhs CWBVH (8-wide compressed nodes).
        let start = Instant::now();
        let cwbvh = build_cwbvh_from_tris(
            &world,
            BvhBuildParams::medium_build(),
            &mut Default::default(),
        );
        let cwbvh_ms = milliseconds(start);
        let cw_ordered: Vec<RtTriangle> = cwbvh
            .primitive_indices
            .iter()
            .map(|&i| rt[i as usize])
            .collect();
        // The build study: each preset's BVH2 collapsed 8 wide, timed one thread.
        let study: Vec<(&'static str, WideBvh, f64, Value)> = if options.build_study {
            STUDY_PRESETS
                .iter()
                .filter_map(|(name, params)| {
                    let (bvh_ms, wide, collapse_ms) = wide_over(&world, &rt, *params);
                    let wide = wide?;
                    let stats = json!({
                        "bvh2_build_ms": round(bvh_ms),
                        "collapse_ms": round(collapse_ms),
                        "sah_cost": round(wide.sah_cost() as f64),
                        "blocks": wide.block_count(),
                        "triangle_references": wide.triangle_count(),
                    });
                    Some((*name, wide, bvh_ms + collapse_ms, stats))
                })
                .collect()
        } else {
            Vec::new()
        };
        let wide_stats = wide_stats.map(|mut stats| {
            if let Some(wide) = &wide {
                stats["sah_cost"] = json!(round(wide.sah_cost() as f64));
            }
            stats
        });
        (
            bvh,
            ordered,
            bvh_ms,
            wide,
            wide_bvh_ms + collapse_ms,
            cwbvh,
            cw_ordered,
            cwbvh_ms,
            wide_stats,
            study,
        )
    }));
    // The renderer's own path first (its figures are the report's top level): camera rays
    // in packets, shadow rays in interleaved streams, bounces one at a time, as
    // render/mod.rs traces them.
    let mut contenders: Vec<Contender> = vec![
        Contender::renderer("gloam_renderer", blas_build_ms, &accel),
        Contender {
            primary: packet_closest(&unbatched),
            ..Contender::one_by_one(
                "gloam_renderer_unbatched",
                blas_build_ms,
                single_closest(&unbatched),
                |ray: &Ray| unbatched.occluded(ray, InstanceMask::ALL, &Opaque),
            )
        },
        // Packets for every ray type, diffuse bounces included (what the renderer does not).
        Contender::packets("gloam_packets", blas_build_ms, &accel),
        Contender::packets("gloam_packets_portable", blas_build_ms, &portable),
    ];
    for (name, scene) in [
        ("gloam_tlas_blas_wide8", &accel),
        ("gloam_tlas_blas_wide8_portable", &portable),
        ("gloam_tlas_blas_bvh2", &bvh2),
    ] {
        contenders.push(Contender::one_by_one(
            name,
            blas_build_ms,
            single_closest(scene),
            move |ray: &Ray| scene.occluded(ray, InstanceMask::ALL, &Opaque),
        ));
    }

    // The largest BLAS traced on its own, no TLAS (when its instance is untransformed): what
    // the two-level walk costs on top of the BLAS walk (and, for closest hits, the
    // barycentrics the renderer needs).
    let largest = accel
        .instances()
        .iter()
        .max_by_key(|instance| {
            accel.blases[instance.blas as usize]
                .geometry
                .triangles
                .len()
        })
        .filter(|instance| instance.world_from_object() == Affine3A::IDENTITY)
        .and_then(|instance| accel.blases[instance.blas as usize].packet_tree());
    // The largest static batch traced on its own: the renderer's path without the TLAS.
    let largest_batch = accel
        .batch_blases()
        .max_by_key(|blas| blas.triangle_count())
        .and_then(Blas::packet_tree);
    for (name, tree) in [
        ("gloam_largest_blas_alone", largest),
        ("gloam_largest_batch_alone", largest_batch),
    ] {
        if let Some((tree, kernels)) = tree {
            contenders.push(Contender::tree_alone(name, blas_build_ms, tree, kernels));
        }
    }

    let mut wide_stats = None;
    let mut study_stats = serde_json::Map::new();
    if let Some((
        bvh,
        ordered,
        bvh_ms,
        wide,
        wide_build_ms,
        cwbvh,
        cw_ordered,
        cwbvh_ms,
        stats,
        study,
    )) = &flat
    {
        wide_stats = stats.clone();
        for (name, wide, build_ms, stats) in study {
            study_stats.insert((*name).into(), stats.clone());
            contenders.push(Contender::one_by_one(
                name,
                *build_ms,
                |ray: &Ray| wide.intersect(&ray.to_obvhs(), Kernels::Best).is_some(),
                |ray: &Ray| wide.occluded(&ray.to_obvhs(), Kernels::Best),
            ));
        }
        contenders.push(Contender::one_by_one(
            "obvhs_bvh2_flat",
            *bvh_ms,
            |ray: &Ray| {
                bvh.ray_traverse(ray.to_obvhs(), &mut RayHit::none(), |r, id| {
                    ordered[id].intersect(r)
                })
            },
            |ray: &Ray| !bvh.ray_traverse_miss(ray.to_obvhs(), |r, id| ordered[id].intersect(r)),
        ));
        if let Some(wide) = wide {
            contenders.push(Contender::one_by_one(
                "wide8_flat",
                *wide_build_ms,
                |ray: &Ray| wide.intersect(&ray.to_obvhs(), Kernels::Best).is_some(),
                |ray: &Ray| wide.occluded(&ray.to_obvhs(), Kernels::Best),
            ));
        }
        contenders.push(Contender::one_by_one(
            "obvhs_cwbvh_flat",
            *cwbvh_ms,
            |ray: &Ray| {
                cwbvh.ray_traverse(ray.to_obvhs(), &mut RayHit::none(), |r, id| {
                    cw_ordered[id].intersect(r)
                })
            },
            |ray: &Ray| {
                !cwbvh.ray_traverse_miss(ray.to_obvhs(), |r, id| cw_ordered[id].intersect(r))
            },
        ));
        agreement = Some(agreement_with_flat(&accel, &rays.diffuse, |ray| {
            let mut hit = RayHit::none();
            bvh.ray_traverse(ray.to_obvhs(), &mut hit, |r, id| ordered[id].intersect(r))
                .then_some(hit.t)
        }));
    } else {
        phase.suspend(|| {
            println!(
                "(baseline skipped: flattening {flat_count} triangles would exceed {MAX_FLAT_TRIANGLES})"
            )
        });
    }
    let mut per_threads = Vec::new();
    for &threads in &thread_counts {
        per_threads.push(measure_interleaved(
            &rays,
            threads,
            options.repeats,
            &contenders,
        )?);
    }
    let layouts: Vec<(&str, Vec<Throughput>, f64)> = contenders
        .iter()
        .enumerate()
        .map(|(index, c)| {
            let measured = per_threads.iter().map(|all| all[index]).collect();
            (c.name, measured, c.build_ms)
        })
        .collect();
    let gloam = layouts[0].1.clone();
    // The contenders borrow `accel`; step 5 changes it.
    drop(contenders);

    phase.set_message("TLAS rebuilds and refits");
    // 5. TLAS rebuilds and deforming refits, on `threads` (as in a frame).
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.threads)
        .build()
        .context("starting the thread pool")?;
    let tlas_build_ms = pool.install(|| {
        median(
            (0..50)
                .map(|_| {
                    let start = Instant::now();
                    accel.rebuild_tlas();
                    milliseconds(start)
                })
                .collect(),
        )
    });
    let deforming_report = deforming.map(|(blas_index, build_ms)| {
        pool.install(|| bench_refit(&mut accel, blas_index, build_ms))
    });

    // Report.
    phase.finish_and_clear();
    print_table(&layouts, &thread_counts);
    println!(
        "builds: scene extraction with static BLASes {blas_build_ms:.1} ms (all meshes, parallel); TLAS rebuild {tlas_build_ms:.3} ms for {} instances ({} threads)",
        accel.instances().len(),
        options.threads
    );
    if let Some(stats) = &wide_stats {
        println!(
            "wide8 over the flat triangles: BVH2 build {} ms + collapse {} ms (one thread); SAH cost {}, {} nodes, {} leaf blocks, {:.0}% of triangle lanes used, {} levels",
            stats["bvh2_build_ms"],
            stats["collapse_ms"],
            stats["sah_cost"],
            stats["nodes"],
            stats["blocks"],
            stats["lanes_used"].as_f64().unwrap_or(0.0) * 100.0,
            stats["depth"]
        );
    }
    for (name, stats) in &study_stats {
        println!(
            "build study {name}: BVH2 {} ms + collapse {} ms (one thread), SAH cost {} ({} leaf blocks, {} triangle references)",
            stats["bvh2_build_ms"],
            stats["collapse_ms"],
            stats["sah_cost"],
            stats["blocks"],
            stats["triangle_references"]
        );
    }
    if let Some(agreement) = agreement {
        println!(
            "agreement with the flat baseline on diffuse rays: {:.4}% same hit distance",
            agreement * 100.0
        );
    }
    if let Some(report) = &deforming_report {
        println!(
            "deforming: {} triangles refit in {:.3} ms (median of {} frames, {} rebuilds; full rebuild {:.1} ms); SAH cost {:.3}x its last build, {:.3}x a fresh build",
            report["triangles"],
            report["refit_ms"],
            report["frames"],
            report["rebuilds"],
            report["rebuild_ms"],
            report["sah_decay"],
            report["sah_vs_fresh_build"]
        );
    }

    if let Some(path) = &options.json {
        let single = |name: &str| layouts.iter().find(|l| l.0 == name).map(|l| l.1[0]);
        let mut layout_json = serde_json::Map::new();
        for (layout, per_threads, build_ms) in &layouts {
            let mut entry = serde_json::Map::new();
            for (threads, throughput) in thread_counts.iter().zip(per_threads) {
                entry.insert(format!("threads_{threads}"), throughput.json());
            }
            entry.insert("build_ms".into(), json!(round(*build_ms)));
            layout_json.insert((*layout).into(), Value::Object(entry));
        }
        let top = gloam[0];
        let report = json!({
            "scene": name,
            "primary_mrays_per_s": round(top.primary),
            "shadow_mrays_per_s": round(top.shadow),
            "diffuse_mrays_per_s": round(top.diffuse),
            "threads": 1,
            "all_threads": {"threads": options.threads, "mrays_per_s": gloam.last().map(Throughput::json)},
            "triangles": accel.instanced_triangle_count(),
            "unique_triangles": accel.blases.iter().map(Blas::triangle_count).sum::<usize>(),
            "instances": accel.instances().len(),
            "rays": {"primary": rays.primary.len(), "shadow": rays.shadow.len(), "diffuse": rays.diffuse.len()},
            "tlas_build_ms": round(tlas_build_ms),
            "blas_build_ms": round(blas_build_ms),
            "blas_refit_ms": deforming_report.as_ref().map(|r| r["refit_ms"].clone()),
            "deforming": deforming_report,
            "baseline_obvhs_bvh2": single("obvhs_bvh2_flat").map(|t| t.json()),
            "agreement_with_baseline": agreement,
            "wide8_flat_build": wide_stats,
            "build_study": (!study_stats.is_empty()).then_some(Value::Object(study_stats.clone())),
            "layouts": layout_json,
        });
        let text = serde_json::to_string_pretty(&report).context("encoding the report")? + "\n";
        write_atomically(path, text.as_bytes())?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Primary rays per side of `AccelAlone`'s rays: 262k camera rays a round.
const ACCEL_ALONE_SIZE: u32 = 512;

/// A level's accel alone with this tool's rays (`make_rays`), timed the renderer's way
/// (`Contender::renderer`) in rounds: `gloam bench` times one between windows of its
/// frames and sets it beside the renderer's own rays per second.
pub struct AccelAlone {
    accel: AccelScene,
    rays: RaySet,
}

impl AccelAlone {
    pub fn new(scene: &Scene) -> AccelAlone {
        // The engine's accel, its TLAS built as a frame leaves it.
        let render = render_scene(scene);
        let rays = make_rays(
            &render.accel,
            &render.camera,
            &emitters(&render.lights.lights),
            ACCEL_ALONE_SIZE,
        );
        AccelAlone {
            accel: render.accel,
            rays,
        }
    }

    /// One timing of each kind of ray, on the thread pool it is called from.
    pub fn round(&self) -> AccelRays {
        let contender = Contender::renderer("gloam_renderer", 0.0, &self.accel);
        AccelRays {
            camera: rate(&self.rays.primary, &*contender.primary),
            shadow: rate(&self.rays.shadow, &*contender.shadow),
            bounce: rate(&self.rays.diffuse, &*contender.diffuse),
        }
    }
}

/// Mrays/s of `trace` over `set` on the thread pool it is called from.
fn rate(set: &[Ray], trace: &(dyn Fn(&[Ray]) -> usize + Sync)) -> f64 {
    if set.is_empty() {
        return 0.0;
    }
    let start = Instant::now();
    // The hit count keeps the work observable to the optimiser. Batches of 1024 rays are
    // four render tiles.
    let hits: usize = set.par_chunks(1024).map(trace).sum();
    std::hint::black_box(hits);
    set.len() as f64 / start.elapsed().as_secs_f64() / 1e6
}

/// The emissive triangles of `lights` (shadow rays aim at them).
fn emitters(lights: &[Light]) -> Vec<[Vec3A; 3]> {
    lights
        .iter()
        .filter_map(|light| match light {
            Light::Triangle { vertices, .. } => Some(*vertices),
            _ => None,
        })
        .collect()
}

/// A way of tracing a batch of rays: how many of them hit.
type Tracer<'a> = Box<dyn Fn(&[Ray]) -> usize + Sync + 'a>;

/// One way of tracing the rays, with what it cost to build: closest hits (primary and
/// diffuse rays) and any hits (shadow rays), each over a batch of rays in tile order.
struct Contender<'a> {
    name: &'static str,
    build_ms: f64,
    primary: Tracer<'a>,
    shadow: Tracer<'a>,
    diffuse: Tracer<'a>,
}

impl<'a> Contender<'a> {
    /// As render/mod.rs traces: camera rays in packets, shadow rays in interleaved
    /// streams, bounces one at a time.
    fn renderer(name: &'static str, build_ms: f64, scene: &'a AccelScene) -> Contender<'a> {
        Contender {
            primary: packet_closest(scene),
            shadow: stream_any(scene),
            ..Contender::one_by_one(name, build_ms, single_closest(scene), |ray: &Ray| {
                scene.occluded(ray, InstanceMask::ALL, &Opaque)
            })
        }
    }

    /// A contender tracing every ray type through `scene` in packets.
    fn packets(name: &'static str, build_ms: f64, scene: &'a AccelScene) -> Contender<'a> {
        Contender {
            name,
            build_ms,
            primary: packet_closest(scene),
            shadow: packet_any(scene),
            diffuse: packet_closest(scene),
        }
    }

    /// One wide tree walked on its own, with no TLAS above it, one ray at a time.
    fn tree_alone(
        name: &'static str,
        build_ms: f64,
        tree: &'a WideBvh,
        kernels: Kernels,
    ) -> Contender<'a> {
        Contender::one_by_one(
            name,
            build_ms,
            move |ray: &Ray| tree.intersect(&ray.to_obvhs(), kernels).is_some(),
            move |ray: &Ray| tree.occluded(&ray.to_obvhs(), kernels),
        )
    }

    /// A contender tracing one ray at a time (the same queries for primary and diffuse).
    fn one_by_one(
        name: &'static str,
        build_ms: f64,
        closest: impl Fn(&Ray) -> bool + Sync + Copy + 'a,
        any: impl Fn(&Ray) -> bool + Sync + 'a,
    ) -> Contender<'a> {
        let each = move |rays: &[Ray]| rays.iter().filter(|r| closest(r)).count();
        Contender {
            name,
            build_ms,
            primary: Box::new(each),
            shadow: Box::new(move |rays: &[Ray]| rays.iter().filter(|r| any(r)).count()),
            diffuse: Box::new(each),
        }
    }
}

/// Builds timed per preset in `wide_over`: the median is reported (one build's time swings
/// by 30% on a shared machine).
const TIMED_BUILDS: usize = 5;

/// The 8-wide tree over `triangles` (`world` as obvhs's `RtTriangle`s) as gloam builds it
/// from obvhs's preset `params` (its BVH2 without obvhs's leaf collapse,
/// `WideBvh::source_params`; pre-split when `params` asks; None if too deep), with the
/// BVH2's build time and the collapse's in ms, medians of `TIMED_BUILDS` builds.
fn wide_over(
    world: &[Triangle],
    triangles: &[RtTriangle],
    params: BvhBuildParams,
) -> (f64, Option<WideBvh>, f64) {
    let (mut bvh_times, mut collapse_times) = (Vec::new(), Vec::new());
    let mut wide = None;
    let params = WideBvh::source_params(params);
    for _ in 0..TIMED_BUILDS {
        let start = Instant::now();
        // `build_bvh2` takes any boxes and does not split; the triangle builder does.
        let bvh = if params.pre_split {
            build_bvh2_from_tris(world, params, &mut Default::default())
        } else {
            build_bvh2(triangles, params, &mut Default::default())
        };
        bvh_times.push(milliseconds(start));
        let ordered: Vec<RtTriangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| triangles[i as usize])
            .collect();
        let start = Instant::now();
        wide = WideBvh::build(&bvh, &ordered).ok();
        collapse_times.push(milliseconds(start));
    }
    (median(bvh_times), wide, median(collapse_times))
}

/// gloam's single-ray closest-hit query.
fn single_closest(scene: &AccelScene) -> impl Fn(&Ray) -> bool + Sync + Copy + '_ {
    move |ray: &Ray| scene.intersect(ray, InstanceMask::ALL, &Opaque).is_some()
}

/// gloam's packet queries over a batch (`AccelScene::intersect_coherent`).
fn packet_closest(scene: &AccelScene) -> Tracer<'_> {
    Box::new(move |rays: &[Ray]| {
        let mut hits = vec![None; rays.len()];
        scene.intersect_coherent(rays, InstanceMask::ALL, &Opaque, &mut hits);
        hits.iter().filter(|h| h.is_some()).count()
    })
}

/// gloam's packet shadow queries over a batch (`AccelScene::occluded_coherent`).
fn packet_any(scene: &AccelScene) -> Tracer<'_> {
    Box::new(move |rays: &[Ray]| {
        let mut occluded = vec![false; rays.len()];
        scene.occluded_coherent(rays, InstanceMask::ALL, &Opaque, &mut occluded);
        occluded.iter().filter(|&&o| o).count()
    })
}

/// gloam's shadow queries over a batch in interleaved streams
/// (`AccelScene::occluded_stream`).
fn stream_any(scene: &AccelScene) -> Tracer<'_> {
    Box::new(move |rays: &[Ray]| {
        let mut occluded = vec![false; rays.len()];
        scene.occluded_stream(rays, InstanceMask::ALL, &Opaque, &mut occluded);
        occluded.iter().filter(|&&o| o).count()
    })
}

/// Times the three ray types of every contender on `threads` threads, `repeats` rounds
/// each timing every contender once; the median Mrays/s per contender and ray type.
fn measure_interleaved(
    rays: &RaySet,
    threads: usize,
    repeats: usize,
    contenders: &[Contender],
) -> anyhow::Result<Vec<Throughput>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the thread pool")?;
    let rate = |set: &[Ray], trace: &(dyn Fn(&[Ray]) -> usize + Sync)| -> f64 {
        pool.install(|| rate(set, trace))
    };
    let mut samples = vec![[Vec::new(), Vec::new(), Vec::new()]; contenders.len()];
    for _ in 0..repeats {
        for (contender, samples) in contenders.iter().zip(&mut samples) {
            samples[0].push(rate(&rays.primary, &*contender.primary));
            samples[1].push(rate(&rays.shadow, &*contender.shadow));
            samples[2].push(rate(&rays.diffuse, &*contender.diffuse));
        }
    }
    Ok(samples
        .into_iter()
        .map(|[primary, shadow, diffuse]| Throughput {
            primary: median(primary),
            shadow: median(shadow),
            diffuse: median(diffuse),
        })
        .collect())
}

fn print_table(layouts: &[(&str, Vec<Throughput>, f64)], thread_counts: &[usize]) {
    println!(
        "{:<24} {:>8} {:>10} {:>9} {:>9}   (Mrays/s)",
        "layout", "threads", "primary", "shadow", "diffuse"
    );
    let baseline = layouts.iter().find(|l| l.0 == "obvhs_bvh2_flat");
    for (layout, per_threads, build_ms) in layouts {
        for (threads, t) in thread_counts.iter().zip(per_threads) {
            println!(
                "{layout:<24} {threads:>8} {:>10.2} {:>9.2} {:>9.2}   build {build_ms:.1} ms",
                t.primary, t.shadow, t.diffuse
            );
        }
    }
    if let (Some(baseline), Some(gloam)) = (baseline, layouts.first()) {
        for (index, threads) in thread_counts.iter().enumerate() {
            let (g, b) = (gloam.1[index], baseline.1[index]);
            println!(
                "{:<24} {threads:>8} {:>9.2}x {:>8.2}x {:>8.2}x",
                "gloam / obvhs flat",
                g.primary / b.primary,
                g.shadow / b.shadow,
                g.diffuse / b.diffuse
            );
        }
    }
}

/// Adds copies of the scene's first `scene_instances` instances, moved along a square grid
/// in X and Z spaced by the scene's size, until there are `wanted` instances in all. Every
/// instance is made `Movable` (the scene's batches dissolve at the next TLAS rebuild): the
/// TLAS is what this measures, so it must hold all `wanted`.
fn replicate_instances(accel: &mut AccelScene, scene_instances: usize, wanted: usize) {
    for instance in accel.instances_mut() {
        instance.mobility = Mobility::Movable;
    }
    let bounds = accel.bounds();
    let step = Vec3::from(bounds.diagonal()) * 1.1;
    let side = (wanted as f64 / scene_instances as f64)
        .sqrt()
        .ceil()
        .max(1.0) as i32;
    let originals: Vec<Instance> = accel.instances()[..scene_instances].to_vec();
    let mut copy = 1;
    while accel.instances().len() < wanted {
        let (column, row) = (copy % side, copy / side);
        let offset = Affine3A::from_translation(Vec3::new(
            column as f32 * step.x,
            0.0,
            -(row as f32) * step.z,
        ));
        for original in &originals {
            if accel.instances().len() >= wanted {
                break;
            }
            let mut instance = original.clone();
            instance.set_transform(offset * original.world_from_object());
            accel.push_instance(instance);
        }
        copy += 1;
    }
}

/// A hash of (stream, index) to a uniform float in [0, 1) (a fixed integer hash so every
/// run makes the same rays; the renderer's samplers come with the Renderer issue).
fn uniform(stream: u32, index: u32) -> f32 {
    let mut x = index.wrapping_mul(0x9e37_79b9) ^ stream.wrapping_mul(0x85eb_ca6b);
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    (x >> 8) as f32 / (1u32 << 24) as f32
}

/// Primary rays through pixel centres (`render::Camera`'s pinhole), then per primary hit one shadow
/// ray to a uniform point on the emitters (chosen by area) and one cosine-weighted bounce.
fn make_rays(
    accel: &AccelScene,
    camera: &CameraPlacement,
    emitters: &[[Vec3A; 3]],
    size: u32,
) -> RaySet {
    let (_, rotation, position) = camera.world_from_camera.to_scale_rotation_translation();
    let rotation = Mat3A::from_quat(rotation);
    let tan_half = (camera.yfov * 0.5).tan();
    // Pixels in the renderer's order: 16 x 16 tiles, row by row within each, so packets of
    // 64 consecutive rays are 16 x 4 strips of a tile, as render/mod.rs forms them.
    const TILE: u32 = 16;
    let tiles_across = size.div_ceil(TILE);
    let pixels: Vec<(u32, u32)> = (0..tiles_across * tiles_across)
        .flat_map(|tile| {
            let (x0, y0) = (tile % tiles_across * TILE, tile / tiles_across * TILE);
            (y0..(y0 + TILE).min(size))
                .flat_map(move |y| (x0..(x0 + TILE).min(size)).map(move |x| (x, y)))
        })
        .collect();
    let primary: Vec<Ray> = pixels
        .iter()
        .map(|&(x, y)| {
            let ndc = Vec2::new(
                2.0 * (x as f32 + 0.5) / size as f32 - 1.0,
                1.0 - 2.0 * (y as f32 + 0.5) / size as f32,
            );
            let direction = rotation * Vec3A::new(ndc.x * tan_half, ndc.y * tan_half, -1.0);
            Ray::new(position.into(), direction.normalize())
        })
        .collect();

    let mut cumulative_area = Vec::with_capacity(emitters.len());
    let mut total = 0.0;
    for [a, b, c] in emitters {
        total += (*b - *a).cross(*c - *a).length() * 0.5;
        cumulative_area.push(total);
    }
    let hits: Vec<Option<(u32, crate::accel::SurfaceHit, Vec3A)>> = primary
        .par_iter()
        .zip(&pixels)
        .map(|(ray, &(x, y))| {
            accel
                .intersect(ray, InstanceMask::ALL, &Opaque)
                .map(|hit| (y * size + x, accel.surface(&hit), ray.direction))
        })
        .collect();
    let mut shadow = Vec::new();
    let mut diffuse = Vec::new();
    for (pixel, surface, incoming) in hits.into_iter().flatten() {
        // The side the ray arrived on.
        let normal = if surface.geometric_normal.dot(incoming) < 0.0 {
            surface.geometric_normal
        } else {
            -surface.geometric_normal
        };
        if total > 0.0 {
            let pick = uniform(1, pixel) * total;
            let index = cumulative_area
                .partition_point(|&c| c < pick)
                .min(emitters.len() - 1);
            let [a, b, c] = emitters[index];
            let root = uniform(2, pixel).sqrt();
            let (b1, b2) = (1.0 - root, uniform(3, pixel) * root);
            let target = a * (1.0 - b1 - b2) + b * b1 + c * b2;
            shadow.push(Ray::spawn_to(surface.position, normal, target));
        }
        // Cosine-weighted direction about the normal (Malley's method) in an orthonormal
        // basis (Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
        let (r1, r2) = (uniform(4, pixel), uniform(5, pixel));
        let (sin_phi, cos_phi) = (std::f32::consts::TAU * r1).sin_cos();
        let radius = r2.sqrt();
        let sign = 1f32.copysign(normal.z);
        let a = -1.0 / (sign + normal.z);
        let b = normal.x * normal.y * a;
        let tangent = Vec3A::new(
            1.0 + sign * normal.x * normal.x * a,
            sign * b,
            -sign * normal.x,
        );
        let bitangent = Vec3A::new(b, sign + normal.y * normal.y * a, -normal.y);
        let direction = tangent * (radius * cos_phi)
            + bitangent * (radius * sin_phi)
            + normal * (1.0 - r2).max(0.0).sqrt();
        diffuse.push(Ray::spawn(surface.position, normal, direction.normalize()));
    }
    RaySet {
        primary,
        shadow,
        diffuse,
    }
}

/// Every instance's triangles in world space, for the flat baselines.
fn flat_triangles(accel: &AccelScene) -> Vec<Triangle> {
    let mut triangles = Vec::with_capacity(accel.instanced_triangle_count());
    for instance in accel.instances() {
        let geometry = &accel.blases[instance.blas as usize].geometry;
        let to_world = instance.world_from_object();
        for triangle in 0..geometry.triangles.len() {
            let [v0, v1, v2] = geometry
                .triangle_vertices(triangle)
                .map(|v| to_world.transform_point3a(v));
            triangles.push(Triangle { v0, v1, v2 });
        }
    }
    triangles
}

/// Fraction of rays where gloam and a flat BVH agree on hit or miss and, for hits, on the
/// distance within 1e-3 relative (the two trace in different spaces, so not bit for bit).
fn agreement_with_flat(
    accel: &AccelScene,
    rays: &[Ray],
    flat: impl Fn(&Ray) -> Option<f32> + Sync,
) -> f64 {
    if rays.is_empty() {
        return 1.0;
    }
    let same: usize = rays
        .par_iter()
        .filter(|ray| {
            match (
                accel
                    .intersect(ray, InstanceMask::ALL, &Opaque)
                    .map(|h| h.t),
                flat(ray),
            ) {
                (None, None) => true,
                (Some(a), Some(b)) => (a - b).abs() <= 1e-3 * (1.0 + a.abs()),
                _ => false,
            }
        })
        .count();
    same as f64 / rays.len() as f64
}

/// Deforms the grid for 30 frames (a travelling wave, computed outside the timing, as the
/// animation step would) and times each refit.
fn bench_refit(accel: &mut AccelScene, blas_index: usize, build_ms: f64) -> Value {
    let rest = accel.blases[blas_index].geometry.positions.clone();
    let frames = 30;
    let mut times = Vec::with_capacity(frames);
    let mut rebuilds = 0;
    let mut moved = rest.clone();
    for frame in 0..frames {
        let phase = frame as f32 * 0.2;
        for (target, p) in moved.iter_mut().zip(&rest) {
            *target = *p + Vec3::Y * (0.3 * (1.1 * p.x + phase).sin() * (0.7 * p.z - phase).cos());
        }
        let start = Instant::now();
        if accel.blases[blas_index].refit(&moved, None) == RefitOutcome::Rebuilt {
            rebuilds += 1;
        }
        times.push(milliseconds(start));
    }
    let blas = &accel.blases[blas_index];
    let fresh = Blas::build(blas.geometry.clone(), BlasKind::Deforming);
    json!({
        "triangles": blas.triangle_count(),
        "frames": frames,
        "refit_ms": round(median(times)),
        "rebuilds": rebuilds,
        "rebuild_ms": round(build_ms),
        "sah_decay": round(blas.quality_decay() as f64),
        "sah_vs_fresh_build": round((blas.sah_cost() / fresh.sah_cost()) as f64),
    })
}
