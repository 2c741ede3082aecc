//! The game: ECS components, resources, systems and the schedules that run them.
//!
//! One displayed frame, headless (the window shell drives the same `Engine`):
//! 1. `Engine::advance(dt)`: the simulation clock accumulates real time and runs the
//!    fixed-step schedule at 60 Hz as many times as it owes: `fly_camera` (input), then
//!    gameplay systems as the game grows, then animation (`advance_animations` and `apply_animations` sample glTF clips into node transforms
//!    and morph weights), and last `propagate_transforms`;
//! 2. the prepare schedule, chained: `extract_instances` (moved entities -> accel instance
//!    transforms, interpolated between the last two simulation steps by how far real time
//!    has run into the next one) -> `deform_meshes` (skinning, morph targets and deformers
//!    for meshes whose pose changed, then their BLAS refits) -> `update_acceleration`
//!    (emitters follow, TLAS rebuild when anything moved or deformed);
//! 3. the frame schedule: `render_frame` (one frame of samples) -> film: with the filter
//!    off, frames add up into a converging image while nothing moves and any change starts
//!    it again; with it on (the window and `bench`), the frame is rendered with its guides
//!    and goes through `render::denoise` (temporal reprojection, then a-trous).
//!
//! Each stage's time lands in the `StageTimes` resource (the profiler issue builds on it).
//!
//! Render and accel never see this module: the `RenderScene` sits in a resource and the
//! systems here call into them with plain data.

pub mod animation;
pub mod deform;
pub mod input;
pub mod transform;

use std::collections::HashMap;
use std::sync::Arc;

use bevy_ecs::prelude::*;
use glam::Vec3;

pub use animation::{
    AnimationLibrary, Animator, Deformer, MorphWeights, advance_animations, apply_animations,
};
pub use deform::{DeformSource, DeformStats, DeformedMesh, SkinBinding, deform_meshes};

pub use input::{Action, Input, fly_camera};
pub use transform::{
    GlobalTransform, PreviousGlobalTransform, Transform, interpolate, propagate_transforms,
    remember_transforms,
};

use crate::accel::BlasKind;
use crate::extract::{instance_user_id, refresh_triangle_lights, render_scene};
use crate::render::denoise::{FilterMode, FrameFilter};
use crate::render::{
    Camera, Film, RenderOutput, RenderScene, RenderSettings, render, render_guided,
    render_guided_reusing,
};
use crate::scene::model::NodeTransform;
use crate::scene::world::{CameraPlacement, Scene};

/// Simulation steps per second (DESIGN.md: fixed timestep, 60 Hz).
pub const SIMULATION_HZ: f64 = 60.0;

/// A renderable entity: its index among the accel instances.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderInstance(pub u32);

/// The entity whose `GlobalTransform` is the view (looks down its -Z).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct ViewCamera {
    /// Vertical field of view in radians.
    pub yfov: f32,
}

/// Which level entity (index in the level file) an ECS entity came from.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct LevelEntity(pub usize);

/// The scene as the renderer reads it, and what changed in it this frame.
#[derive(Resource)]
pub struct RenderState {
    pub scene: RenderScene,
    pub tlas_stale: bool,
    /// Per accel instance: moved or deformed this frame (its emissive triangles follow).
    pub moved: Vec<bool>,
}

/// The film: frames accumulated since the last change, as a running sum of per-frame
/// means, or (filter on) the last filtered frame.
#[derive(Resource)]
pub struct Accumulation {
    pub settings: RenderSettings,
    sum: Vec<Vec3>,
    pub frames: u32,
    /// The real-time filter chain (`FilterMode::Off` unless the shell turns it on).
    pub filter: FrameFilter,
    /// The last frame through the filter.
    filtered: Option<Film>,
    /// The last filtered frame's render, whose buffers the next one reuses.
    rendered: Option<RenderOutput>,
    /// Set by extract when anything visible moved: the next frame starts a new sum.
    pub reset: bool,
    /// The view the sum was rendered from.
    view: Option<glam::Affine3A>,
}

/// How far real time has run past the last simulation step, in steps (0..1): rendering
/// interpolates between the previous and the current step by this much.
#[derive(Resource, Default, Clone, Copy, Debug)]
pub struct SimulationClock {
    pub alpha: f32,
}

/// Milliseconds each stage of the last frame took (`profile::STAGES` names them; the fixed
/// steps' stages sum over every step the frame ran), and the rays it traced.
#[derive(Resource, Default, Clone, Copy, Debug)]
pub struct StageTimes {
    /// Input actions applied (the fly camera), and last step's transforms remembered.
    pub input: f64,
    /// Gameplay systems (none yet: the game proper adds them here).
    pub gameplay: f64,
    /// Clip sampling in the fixed steps, plus deforming meshes (skinning, morph targets,
    /// procedural deformers) in the frame.
    pub animation: f64,
    /// Transform propagation down the hierarchy.
    pub transforms: f64,
    pub extract: f64,
    /// Refitting (or rebuilding) the deformed meshes' BLASes.
    pub blas_refit: f64,
    /// Rebuilding the TLAS and moving emissive triangles with their instances.
    pub tlas_build: f64,
    pub render: f64,
    /// The render's wall time split over its phases (`render::PhaseTimes::NAMES`) in
    /// proportion to the CPU time each took on the tiles' threads.
    pub render_phases: [f64; 4],
    /// The film's wall time split over its steps (`render::FilmPhaseTimes::NAMES`).
    pub film_phases: [f64; 3],
    /// The film step: filtering the frame (real-time view), or adding it into the
    /// accumulated image (still view).
    pub film: f64,
    /// Rays the render traced (camera, bounce and shadow).
    pub rays: u64,
}

impl StageTimes {
    /// This frame as a profile sample, with the shell's own `present` and whole-frame times.
    pub fn sample(&self, present_ms: f64, frame_ms: f64) -> crate::profile::FrameSample {
        crate::profile::FrameSample {
            stages: [
                self.input,
                self.gameplay,
                self.animation,
                self.transforms,
                self.extract,
                self.blas_refit,
                self.tlas_build,
                self.render,
                self.film,
                present_ms,
            ],
            render_phases: self.render_phases,
            film_phases: self.film_phases,
            frame_ms,
            rays: self.rays,
        }
    }
}

pub(crate) fn since(start: std::time::Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

impl Accumulation {
    /// Renders at `width` x `height` from the next frame on, starting the image and the
    /// filter's history again.
    pub fn set_resolution(&mut self, width: u32, height: u32) {
        let (width, height) = (width.max(1), height.max(1));
        if (width, height) == (self.settings.width, self.settings.height) {
            return;
        }
        self.settings.width = width;
        self.settings.height = height;
        self.sum = vec![Vec3::ZERO; (width * height) as usize];
        self.frames = 0;
        self.reset = true;
        self.filter.reset();
        self.filtered = None;
        self.rendered = None;
    }

    /// The image to show: the filtered frame with the filter on, else the mean of the
    /// accumulated frames.
    pub fn image(&self) -> Film {
        if self.filter.mode != FilterMode::Off
            && let Some(filtered) = &self.filtered
        {
            return filtered.clone();
        }
        let scale = 1.0 / self.frames.max(1) as f32;
        Film {
            width: self.settings.width,
            height: self.settings.height,
            pixels: self.sum.iter().map(|p| *p * scale).collect(),
        }
    }
}

/// The ECS world and its schedules.
pub struct Engine {
    pub world: World,
    /// One 1/60 s simulation step, as its timed stages: input, gameplay, animation,
    /// transforms.
    fixed_step: [Schedule; 4],
    /// Animation applied and transforms propagated, without moving any clock (posing).
    pose: Schedule,
    /// Extract, deform and refit, TLAS: the scene made ready to trace.
    prepare: Schedule,
    /// One frame of samples into the film.
    frame: Schedule,
    /// Real time not yet simulated, in seconds.
    owed: f64,
    /// Fixed steps run so far.
    pub steps: u64,
}

impl Engine {
    /// Spawns `scene` into a new world: one entity per level entity, with the glTF node
    /// hierarchy of its asset as children; mesh nodes get their `RenderInstance`, and
    /// meshes that change shape their `DeformedMesh` (with `MorphWeights`, a `Deformer`,
    /// and the skin's joints as entities). Entities with a clip get an `Animator`. The
    /// scene is posed at time 0 before this returns.
    pub fn new(scene: &Scene, settings: RenderSettings) -> Engine {
        let mut world = World::new();
        let render = render_scene(scene);
        // Map (level entity, node) -> accel instance.
        let instance_of: HashMap<u64, u32> = render
            .accel
            .instances()
            .iter()
            .enumerate()
            .map(|(i, instance)| (instance.user_id, i as u32))
            .collect();
        let mut library = AnimationLibrary::default();
        let mut clip_of: HashMap<(usize, usize), usize> = HashMap::new();
        let mut sources: HashMap<(usize, usize), Arc<DeformSource>> = HashMap::new();
        for (index, entity) in scene.level.entities.iter().enumerate() {
            let root = world
                .spawn((
                    LevelEntity(index),
                    Transform {
                        translation: entity.transform.translation,
                        rotation: entity.transform.rotation_quat(),
                        scale: entity.transform.scale,
                    },
                    GlobalTransform::default(),
                    PreviousGlobalTransform::default(),
                ))
                .id();
            if let Some(level_camera) = &entity.camera {
                world.entity_mut(root).insert(ViewCamera {
                    yfov: level_camera.yfov_degrees.to_radians(),
                });
            }
            let Some(asset_index) = scene.entity_assets[index] else {
                continue;
            };
            let asset = &scene.assets[asset_index];
            // The asset's nodes, parents before children. A skinned mesh's node hangs
            // straight off the root with no transform of its own: glTF places skinned
            // vertices by their joints alone.
            let mut node_entities = vec![Entity::PLACEHOLDER; asset.nodes.len()];
            let mut parent_node = vec![None; asset.nodes.len()];
            let mut stack: Vec<(usize, Entity)> =
                asset.roots.iter().rev().map(|&node| (node, root)).collect();
            while let Some((node, parent)) = stack.pop() {
                let skinned_mesh =
                    asset.nodes[node].skin.is_some() && asset.nodes[node].mesh.is_some();
                let transform = match asset.nodes[node].transform {
                    _ if skinned_mesh => Transform::default(),
                    NodeTransform::Trs {
                        translation,
                        rotation,
                        scale,
                    } => Transform {
                        translation,
                        rotation,
                        scale,
                    },
                    NodeTransform::Matrix(matrix) => Transform::from_matrix(matrix),
                };
                let mut spawned = world.spawn((
                    transform,
                    GlobalTransform::default(),
                    PreviousGlobalTransform::default(),
                    ChildOf(if skinned_mesh { root } else { parent }),
                ));
                if let Some(&instance) = instance_of.get(&instance_user_id(index, node)) {
                    spawned.insert(RenderInstance(instance));
                }
                let id = spawned.id();
                node_entities[node] = id;
                for &child in &asset.nodes[node].children {
                    parent_node[child] = Some(node);
                }
                stack.extend(
                    asset.nodes[node]
                        .children
                        .iter()
                        .rev()
                        .map(|&child| (child, id)),
                );
            }

            // Deforming meshes: their own BLAS, their source data, what drives them.
            for (node_index, node) in asset.nodes.iter().enumerate() {
                let (Some(mesh), Some(&instance)) = (
                    node.mesh,
                    instance_of.get(&instance_user_id(index, node_index)),
                ) else {
                    continue;
                };
                let blas = render.accel.instances()[instance as usize].blas;
                if render.accel.blases[blas as usize].kind != BlasKind::Deforming {
                    continue;
                }
                let source = sources
                    .entry((asset_index, mesh))
                    .or_insert_with(|| Arc::new(DeformSource::from_mesh(asset, mesh)))
                    .clone();
                let skin = node.skin.map(|skin| {
                    let skin = &asset.skins[skin];
                    // Joints and their ancestors below the root: what moves the pose.
                    let mut watched = Vec::new();
                    for &joint in &skin.joints {
                        let mut current = Some(joint);
                        while let Some(n) = current {
                            if !watched.contains(&node_entities[n]) {
                                watched.push(node_entities[n]);
                            }
                            current = parent_node[n];
                        }
                    }
                    SkinBinding {
                        root,
                        joints: skin.joints.iter().map(|&j| node_entities[j]).collect(),
                        inverse_bind_matrices: skin.inverse_bind_matrices.clone(),
                        watched,
                    }
                });
                let mut entity_mut = world.entity_mut(node_entities[node_index]);
                let targets = source.morph_positions.len();
                if targets > 0 {
                    let weights = node
                        .morph_weights
                        .clone()
                        .or_else(|| {
                            let defaults = &asset.meshes[mesh].morph_weights;
                            (!defaults.is_empty()).then(|| defaults.clone())
                        })
                        .unwrap_or_else(|| vec![0.0; targets]);
                    entity_mut.insert(MorphWeights(weights));
                }
                if let Some(kind) = &entity.deformer {
                    entity_mut.insert(Deformer {
                        kind: kind.clone(),
                        time: 0.0,
                    });
                }
                entity_mut.insert(DeformedMesh::new(blas, instance, source, skin));
            }

            if let Some(animation) = &entity.animation
                && let Some(clip) = asset.animation_by_name(&animation.clip)
            {
                let clip = *clip_of.entry((asset_index, clip)).or_insert_with(|| {
                    library.clips.push(asset.animations[clip].clone());
                    library.clips.len() - 1
                });
                world.entity_mut(root).insert(Animator {
                    clip,
                    elapsed: animation.start as f64,
                    start: animation.start as f64,
                    speed: animation.speed,
                    playback: animation.playback,
                    nodes: node_entities,
                });
            }
        }
        let pixels = (settings.width * settings.height) as usize;
        let instances = render.accel.instances().len();
        world.insert_resource(Input::default());
        world.insert_resource(SimulationClock::default());
        world.insert_resource(StageTimes::default());
        world.insert_resource(DeformStats::default());
        world.insert_resource(library);
        world.insert_resource(RenderState {
            scene: render,
            tlas_stale: false,
            moved: vec![false; instances],
        });
        world.insert_resource(Accumulation {
            view: None,
            settings,
            sum: vec![Vec3::ZERO; pixels],
            frames: 0,
            filter: FrameFilter::new(FilterMode::Off),
            filtered: None,
            rendered: None,
            reset: true,
        });

        let mut input = Schedule::default();
        input.add_systems((remember_transforms, fly_camera).chain());
        // Gameplay systems (player, shards, wardens) join this schedule with the game.
        let gameplay = Schedule::default();
        let mut animation = Schedule::default();
        animation.add_systems((advance_animations, apply_animations).chain());
        let mut transforms = Schedule::default();
        transforms.add_systems(propagate_transforms);
        let fixed_step = [input, gameplay, animation, transforms];
        let mut pose = Schedule::default();
        pose.add_systems((apply_animations, propagate_transforms).chain());
        let mut prepare = Schedule::default();
        prepare.add_systems((extract_instances, deform_meshes, update_acceleration).chain());
        let mut frame = Schedule::default();
        frame.add_systems(render_frame);
        let mut engine = Engine {
            world,
            fixed_step,
            pose,
            prepare,
            frame,
            owed: 0.0,
            steps: 0,
        };
        engine.settle();
        // The view: the level's camera entity if it has one, else an asset's camera, else
        // a view framing the posed scene (a skinned file's rest vertices may lie anywhere).
        let mut views = engine.world.query_filtered::<Entity, With<ViewCamera>>();
        if views.iter(&engine.world).next().is_none() {
            let mut state = engine.world.resource_mut::<RenderState>();
            if scene.camera().is_none() {
                let bounds = state.scene.accel.bounds();
                state.scene.camera = CameraPlacement::framing(bounds.min.into(), bounds.max.into());
            }
            let camera = state.scene.camera.clone();
            let placed = Transform::from_matrix(camera.world_from_camera);
            engine.world.spawn((
                placed,
                GlobalTransform(placed.affine()),
                PreviousGlobalTransform(placed.affine()),
                ViewCamera { yfov: camera.yfov },
            ));
        }
        engine
    }

    /// Poses the world as it stands (clips at their clocks, transforms propagated) with
    /// nothing to interpolate from, and makes the scene ready to trace.
    fn settle(&mut self) {
        self.pose.run(&mut self.world);
        let mut settle = self
            .world
            .query::<(&GlobalTransform, &mut PreviousGlobalTransform)>();
        for (global, mut previous) in settle.iter_mut(&mut self.world) {
            previous.0 = global.0;
        }
        self.prepare.run(&mut self.world);
    }

    /// Sets every clip and deformer clock to `seconds` after level start and poses the
    /// scene there (for `gloam render --time` and tests); no simulation step runs.
    pub fn pose_at(&mut self, seconds: f64) {
        let mut animators = self.world.query::<&mut Animator>();
        for mut animator in animators.iter_mut(&mut self.world) {
            animator.elapsed = animator.start + seconds * animator.speed as f64;
        }
        let mut deformers = self.world.query::<&mut Deformer>();
        for mut deformer in deformers.iter_mut(&mut self.world) {
            deformer.time = seconds;
        }
        self.settle();
    }

    /// The scene as the renderer sees it now.
    pub fn render_scene(&self) -> &RenderScene {
        &self.world.resource::<RenderState>().scene
    }

    /// Deformation counts of the last prepared frame.
    pub fn deform_stats(&self) -> DeformStats {
        *self.world.resource::<DeformStats>()
    }

    /// Simulates `seconds` of real time in fixed 1/60 s steps (the remainder carries
    /// over), then renders and accumulates one frame.
    pub fn advance(&mut self, seconds: f64) {
        // A live profiler's frame boundary (the previous frame's present ends before it).
        profiling::finish_frame!();
        self.simulate(seconds);
        self.frame.run(&mut self.world);
    }

    /// `advance` without the frame: the steps owed, then extract, deform and TLAS, so the
    /// scene is ready to trace from `view_camera` (for tools that render it themselves).
    pub fn simulate(&mut self, seconds: f64) {
        self.owed += seconds.max(0.0);
        let step = 1.0 / SIMULATION_HZ;
        let mut times = StageTimes::default();
        while self.owed >= step {
            profiling::scope!("fixed step");
            let [input, gameplay, animation, transforms] = &mut self.fixed_step;
            for (_name, schedule, slot) in [
                ("input", input, &mut times.input),
                ("gameplay", gameplay, &mut times.gameplay),
                ("animation", animation, &mut times.animation),
                ("transforms", transforms, &mut times.transforms),
            ] {
                let start = std::time::Instant::now();
                profiling::scope!(_name);
                schedule.run(&mut self.world);
                *slot += since(start);
            }
            self.owed -= step;
            self.steps += 1;
        }
        self.world.insert_resource(times);
        self.world.resource_mut::<SimulationClock>().alpha = (self.owed / step) as f32;
        self.prepare.run(&mut self.world);
    }

    /// The camera the next frame renders from, at `width` x `height`.
    pub fn view_camera(&mut self, width: u32, height: u32) -> Option<Camera> {
        let alpha = self.world.resource::<SimulationClock>().alpha;
        let mut views = self
            .world
            .query::<(&GlobalTransform, &PreviousGlobalTransform, &ViewCamera)>();
        let (global, previous, view) = views.iter(&self.world).next()?;
        Some(Camera::new(
            &view_placement(global, previous, view, alpha).1,
            width,
            height,
        ))
    }

    /// The accumulated image so far.
    pub fn image(&self) -> Film {
        self.world.resource::<Accumulation>().image()
    }
}

/// Extract: gives each instance its entity's world transform, interpolated between the
/// last two simulation steps; only instances whose transform changes are touched.
pub fn extract_instances(
    instances: Query<(&RenderInstance, &GlobalTransform, &PreviousGlobalTransform)>,
    clock: Res<SimulationClock>,
    mut state: ResMut<RenderState>,
    mut times: ResMut<StageTimes>,
) {
    let start = std::time::Instant::now();
    profiling::scope!("extract");
    let state = &mut *state;
    for (instance, global, previous) in &instances {
        let shown = if previous.0 == global.0 {
            global.0
        } else {
            interpolate(previous.0, global.0, clock.alpha)
        };
        let target = &mut state.scene.accel.instances_mut()[instance.0 as usize];
        if target.world_from_object() != shown {
            target.set_transform(shown);
            state.tlas_stale = true;
            state.moved[instance.0 as usize] = true;
        }
    }
    times.extract = since(start);
}

/// Accel: when any instance moved or deformed, its emissive triangles follow it and the
/// TLAS is rebuilt over the new instance boxes; the accumulated image starts again.
pub fn update_acceleration(
    mut state: ResMut<RenderState>,
    mut accumulation: ResMut<Accumulation>,
    mut times: ResMut<StageTimes>,
) {
    let start = std::time::Instant::now();
    profiling::scope!("tlas_build");
    let state = &mut *state;
    if state.tlas_stale {
        state.scene.accel.rebuild_tlas();
        state.tlas_stale = false;
        accumulation.reset = true;
        if state.moved.contains(&true) {
            refresh_triangle_lights(&mut state.scene, &state.moved);
            state.moved.fill(false);
        }
    }
    times.tlas_build = since(start);
}

/// The view's transform interpolated `alpha` of the way from the last step to this one,
/// and the camera placed there.
fn view_placement(
    global: &GlobalTransform,
    previous: &PreviousGlobalTransform,
    view: &ViewCamera,
    alpha: f32,
) -> (glam::Affine3A, CameraPlacement) {
    let shown = if previous.0 == global.0 {
        global.0
    } else {
        interpolate(previous.0, global.0, alpha)
    };
    let placement = CameraPlacement {
        name: String::new(),
        yfov: view.yfov,
        znear: 0.01,
        world_from_camera: glam::Mat4::from(shown),
    };
    (shown, placement)
}

/// Render and film: one frame of samples from the view, added to the running sum (or
/// starting it again after a change).
pub fn render_frame(
    state: Res<RenderState>,
    views: Query<(&GlobalTransform, &PreviousGlobalTransform, &ViewCamera)>,
    clock: Res<SimulationClock>,
    mut accumulation: ResMut<Accumulation>,
    mut times: ResMut<StageTimes>,
) {
    let Some((global, previous, view)) = views.iter().next() else {
        return;
    };
    let (shown, placement) = view_placement(global, previous, view, clock.alpha);
    let accumulation = &mut *accumulation;
    if accumulation.view != Some(shown) {
        accumulation.view = Some(shown);
        accumulation.reset = true;
    }
    if accumulation.reset {
        accumulation.sum.iter_mut().for_each(|p| *p = Vec3::ZERO);
        accumulation.frames = 0;
        accumulation.reset = false;
    }
    let mut settings = accumulation.settings.clone();
    settings.frame = accumulation.frames;
    let camera = Camera::new(&placement, settings.width, settings.height);
    let filtering = accumulation.filter.mode != FilterMode::Off;
    let start = std::time::Instant::now();
    let output = {
        profiling::scope!("render");
        if filtering {
            match accumulation.rendered.take() {
                Some(earlier) => render_guided_reusing(&state.scene, &camera, &settings, earlier),
                None => render_guided(&state.scene, &camera, &settings),
            }
        } else {
            render(&state.scene, &camera, &settings, &|_| {})
        }
    };
    times.render = since(start);
    times.render_phases = output.phases.share_of(times.render);
    times.rays = output.rays.total();
    let start = std::time::Instant::now();
    profiling::scope!("film");
    if let Some(guides) = &output.guides {
        let instances: Vec<glam::Affine3A> = state
            .scene
            .accel
            .instances()
            .iter()
            .map(|instance| instance.world_from_object())
            .collect();
        // Last frame's image is overwritten (a fresh buffer a frame costs page faults).
        let mut image = accumulation
            .filtered
            .take()
            .unwrap_or_else(|| Film::new(0, 0));
        accumulation
            .filter
            .apply_into(&output.film, guides, &camera, &instances, &mut image);
        accumulation.filtered = Some(image);
        accumulation.rendered = Some(output);
        accumulation.frames += 1;
        times.film = since(start);
        // The steps' own times, with the little around them (the instances' transforms
        // gathered) shared out so they add up to the stage.
        let steps = accumulation.filter.last_times.as_array();
        let timed: f64 = steps.iter().sum();
        times.film_phases = if timed > 0.0 {
            steps.map(|step| times.film * step / timed)
        } else {
            [0.0; 3]
        };
        return;
    }
    for (sum, pixel) in accumulation.sum.iter_mut().zip(&output.film.pixels) {
        *sum += *pixel;
    }
    accumulation.frames += 1;
    times.film = since(start);
    times.film_phases = [0.0; 3];
}
