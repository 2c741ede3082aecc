//! The frame driver: runs one displayed frame down the frame line, left to right, and
//! times every stage under its `Stage`.
//!
//! Per frame, `Engine::advance` runs five steps, each a method of the same name:
//! 1. `simulate`: the clock accumulates real time and runs the game's fixed 60 Hz step as
//!    many times as it owes: first the simulation's copy of the level is brought up to
//!    date (`extract::step_world`, timed under `Gameplay`: the geometry the step's queries
//!    see), then `Stage::Input`, `Gameplay`, `Animation`, `Transforms`
//!    (`game::fixed_step_schedules`); then, when something listens (`Engine::hearing`),
//!    what the player's ears hear of the step (`Stage::Audio`, `audio::Hearing`: the
//!    mixer's commands, which the window sends to the device and headless replays mix);
//! 2. `extract` (`extract::extract_schedule`): the ECS made into the `RenderScene`
//!    (`Stage::Extract`), and the meshes that changed shape deformed (`Animation`);
//! 3. `accel` (`extract::accel_schedule`): the deformed BLASes refit (`BlasRefit`), the
//!    TLAS rebuilt (`TlasBuild`); the film hears what the frame changed;
//! 4. `render` (`Stage::Render`): the frame the film orders (`film::Accumulation::
//!    order_frame`: the view, the sample index, plain or for the filters), rendered;
//! 5. `film` (`Stage::Film`, `film::Accumulation::develop`): with the filter off, frames
//!    add up into a converging image while nothing changes; with it on (the window and
//!    `bench`), the frame goes through temporal reprojection, the a-trous filter and, below
//!    the shown resolution, the upscaler.
//!
//! Then present: the window shell (`app`) tone maps the film's image into its pixel
//! buffer and presents it, timed as `Stage::Present`; headless tools
//! (`bench`, `render`, `flythrough`, tests) drive the same `Engine`. At construction a
//! level with wardens gets its navigation grid, built from the simulation's copy of its
//! geometry (`game::NavGrid`). Each fixed step can record its input (`Engine::recording`) or take
//! it from a recording (`Engine::playback`).

use bevy_ecs::prelude::*;

use crate::extract::step_world::{StepWorld, step_world_schedule};
use crate::extract::{DeformStats, RenderState, accel_schedule, extract_schedule};
use crate::film::{Accumulation, FrameKind, FrameOrder};
use crate::game::replay::{Recorder, StepInput};
use crate::game::{
    Animator, Deformer, GlobalTransform, LevelEntity, MeshNode, PreviousGlobalTransform,
    SIMULATION_HZ, SimulationClock, Transform, ViewCamera, WorldGeometry, fixed_step_schedules,
    pose_schedule, spawn_level,
};
use crate::profile::{RayMix, Stage, StageTimes, TileSpan, since};
use crate::render::{Camera, RenderOutput, RenderScene, RenderSettings};
use crate::scene::world::{CameraPlacement, Scene};

/// The ECS world, its schedules and the film: one running level.
pub struct Engine {
    pub world: World,
    /// One 1/60 s simulation step, a schedule per stage.
    fixed_step: Vec<(Stage, Schedule)>,
    /// Animation applied and transforms propagated, without moving any clock (posing).
    pose: Schedule,
    /// Extract: the ECS made into the render scene, deformed meshes reshaped.
    extract_schedule: Schedule,
    /// Accel: deformed BLASes refit, the TLAS rebuilt.
    accel_schedule: Schedule,
    /// The simulation's copy of the level brought up to date, before each fixed step.
    step_world: Schedule,
    /// The film the frames go into.
    pub film: Accumulation,
    /// Real time not yet simulated, in seconds.
    owed: f64,
    /// Fixed steps run so far.
    pub steps: u64,
    /// While recording, each fixed step's input, as the step found it, and the state
    /// every `game::replay::TRAIL_EVERY` steps.
    pub recording: Option<Recorder>,
    /// While watching a recording, the inputs still to play, one per fixed step (they
    /// replace what devices give; once they run out the player stands still).
    pub playback: Option<std::collections::VecDeque<StepInput>>,
    /// The player's ears, after each fixed step (none: nothing listens).
    pub hearing: Option<crate::audio::Hearing>,
    /// The last render's tiles: which thread traced each, and when.
    tile_spans: Vec<TileSpan>,
}

impl Engine {
    /// Spawns `scene` into a new world (`game::spawn_level`), poses it at time 0 and makes
    /// the scene ready to trace. A level with no camera of its own or in its assets is
    /// viewed from a camera that frames its posed bounds.
    pub fn new(scene: &Scene, settings: RenderSettings) -> Engine {
        let mut world = World::new();
        world.init_resource::<StageTimes>();
        world.init_resource::<DeformStats>();
        world.init_resource::<RenderState>();
        world.insert_resource(WorldGeometry(Box::new(StepWorld::default())));
        spawn_level(&mut world, scene);
        let mut engine = Engine {
            world,
            fixed_step: fixed_step_schedules(),
            pose: pose_schedule(),
            extract_schedule: extract_schedule(),
            accel_schedule: accel_schedule(),
            step_world: step_world_schedule(),
            film: Accumulation::new(settings),
            owed: 0.0,
            steps: 0,
            recording: None,
            playback: None,
            hearing: None,
            tile_spans: Vec::new(),
        };
        engine.settle();
        // Where wardens can walk: the level's geometry as the first step will see it (only
        // a level with wardens needs it; `render` and the benchmarks of big scenes do not).
        let mut wardens = engine.world.query::<&crate::game::Warden>();
        if wardens.iter(&engine.world).next().is_some() {
            engine.step_world.run(&mut engine.world);
            let geometry = &engine.world.resource::<WorldGeometry>().0;
            let grid = geometry.bounds().map_or_else(Default::default, |bounds| {
                crate::game::NavGrid::build(geometry.as_ref(), bounds, crate::game::nav::CELL)
            });
            engine.world.insert_resource(grid);
        }
        let mut views = engine.world.query_filtered::<(), With<ViewCamera>>();
        if views.iter(&engine.world).next().is_none() {
            // A skinned file's rest vertices may lie anywhere: frame the posed scene.
            let bounds = engine.render_scene().accel.bounds();
            let camera = CameraPlacement::framing(bounds.min.into(), bounds.max.into());
            let placed = Transform::from_matrix(camera.world_from_camera);
            engine.world.spawn((
                Name::new(camera.name),
                placed,
                GlobalTransform(placed.affine()),
                PreviousGlobalTransform(placed.affine()),
                ViewCamera {
                    yfov: camera.yfov,
                    znear: camera.znear,
                },
            ));
            // Extract again for the view; the deformation counts stay the first pass's
            // (this pass finds everything already posed).
            let posed = engine.deform_stats();
            engine.extract();
            engine.accel();
            engine.world.insert_resource(posed);
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
        self.extract();
        self.accel();
        self.film.reset = true;
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

    /// The render scene and its caches (to re-form batches, find an entity's instance).
    pub fn render_state_mut(&mut self) -> Mut<'_, RenderState> {
        self.world.resource_mut::<RenderState>()
    }

    /// The accel instances drawing level entity `level_entity` (its index in the level
    /// file), as (glTF node, instance), in node order.
    pub fn level_entity_instances(&mut self, level_entity: usize) -> Vec<(usize, u32)> {
        let mut meshes = self.world.query::<(Entity, &MeshNode)>();
        let mut found: Vec<(usize, Entity)> = meshes
            .iter(&self.world)
            .filter(|(_, node)| {
                self.world
                    .get::<LevelEntity>(node.root)
                    .is_some_and(|e| e.0 == level_entity)
            })
            .map(|(entity, node)| (node.node, entity))
            .collect();
        found.sort_by_key(|&(node, _)| node);
        let state = self.world.resource::<RenderState>();
        found
            .into_iter()
            .filter_map(|(node, entity)| Some((node, state.instance_of(entity)?)))
            .collect()
    }

    /// The accel instance drawing glTF node `node` of level entity `level_entity`.
    pub fn node_instance(&mut self, level_entity: usize, node: usize) -> Option<u32> {
        self.level_entity_instances(level_entity)
            .into_iter()
            .find(|&(n, _)| n == node)
            .map(|(_, instance)| instance)
    }

    /// Deformation counts of the last prepared frame.
    pub fn deform_stats(&self) -> DeformStats {
        *self.world.resource::<DeformStats>()
    }

    /// What each stage of the last frame cost.
    pub fn stage_times(&self) -> StageTimes {
        *self.world.resource::<StageTimes>()
    }

    /// One displayed frame: `seconds` of real time simulated in fixed 1/60 s steps (the
    /// remainder carries over), then the frame line's steps in order.
    pub fn advance(&mut self, seconds: f64) {
        // A live profiler's frame boundary (the previous frame's present ends before it).
        profiling::finish_frame!();
        self.simulate(seconds);
        self.extract();
        self.accel();
        let (order, output) = self.render();
        self.film(&order, output);
    }

    /// `advance` without render and film: the steps owed, then extract and accel, so the
    /// scene is ready to trace from `view_camera` (for tools that render it themselves).
    pub fn prepare(&mut self, seconds: f64) {
        self.simulate(seconds);
        self.extract();
        self.accel();
    }

    /// Step 1, simulate: the fixed steps `seconds` of real time owe, and how far real time
    /// has run into the next one (what extract interpolates by). Starts the frame's times.
    pub fn simulate(&mut self, seconds: f64) {
        self.world.insert_resource(StageTimes::default());
        self.owed += seconds.max(0.0);
        let step = 1.0 / SIMULATION_HZ;
        while self.owed >= step {
            self.step();
            self.owed -= step;
            self.world.resource_mut::<StageTimes>().steps += 1;
        }
        self.world.resource_mut::<SimulationClock>().alpha = (self.owed / step) as f32;
    }

    /// Step 2, extract: the ECS made into the render scene, deforming meshes reshaped.
    fn extract(&mut self) {
        self.extract_schedule.run(&mut self.world);
    }

    /// Step 3, accel: the deformed BLASes refit and the TLAS rebuilt; then the film hears
    /// what this pass changed (every pass, so that instances renumbered between two
    /// rendered frames still reach the filter's history).
    fn accel(&mut self) {
        self.accel_schedule.run(&mut self.world);
        let state = self.world.resource::<RenderState>();
        self.film.scene_changed(&state.changes);
    }

    /// Step 4, render: the frame the film orders, rendered from the scene as it stands.
    fn render(&mut self) -> (FrameOrder, RenderOutput) {
        let scene = &self.world.resource::<RenderState>().scene;
        let mut times = *self.world.resource::<StageTimes>();
        let mut order = self.film.order_frame(scene, &mut times);
        let start = std::time::Instant::now();
        let mut output = {
            profiling::scope!("render");
            let (camera, settings) = (&order.camera, &order.settings);
            match &mut order.kind {
                FrameKind::Summed => crate::render::render(scene, camera, settings, &|_| {}),
                FrameKind::Filtered { earlier } => {
                    let cache = Some(self.film.cache_for_render());
                    match earlier.take() {
                        Some(earlier) => crate::render::render_guided_reusing(
                            scene, camera, settings, earlier, cache,
                        ),
                        None => crate::render::render_guided(scene, camera, settings, cache),
                    }
                }
            }
        };
        let render_ms = since(start);
        times.add(Stage::Render, render_ms);
        times.render_phases = output.phases.share_of(render_ms);
        times.rays = RayMix {
            camera: output.rays.camera,
            shadow: output.rays.shadow,
            bounce: output.rays.bounce,
        };
        times.cache_ended = output.rays.cache_ended;
        self.tile_spans = std::mem::take(&mut output.tiles);
        self.world.insert_resource(times);
        (order, output)
    }

    /// Step 5, film: the render's output developed into the image to show.
    fn film(&mut self, order: &FrameOrder, output: RenderOutput) {
        let scene = &self.world.resource::<RenderState>().scene;
        let mut times = *self.world.resource::<StageTimes>();
        self.film.develop(order, output, scene, &mut times);
        self.world.insert_resource(times);
    }

    /// One fixed step of the simulation and nothing else (no extract, no frame): the
    /// geometry its queries see brought up to date, then its stages in order. Replays run
    /// the simulation this way.
    pub fn step(&mut self) {
        profiling::scope!("fixed step");
        if let Some(playback) = &mut self.playback {
            let input = playback.pop_front().unwrap_or_default();
            input.apply(&mut self.world.resource_mut::<crate::game::Input>());
        }
        if let Some(recording) = &mut self.recording {
            recording
                .steps
                .push(StepInput::of(self.world.resource::<crate::game::Input>()));
        }
        // The geometry the step's queries see: the world as the last step left it.
        self.step_world.run(&mut self.world);
        for (stage, schedule) in &mut self.fixed_step {
            let start = std::time::Instant::now();
            profiling::scope!(stage.name());
            schedule.run(&mut self.world);
            self.world
                .resource_mut::<StageTimes>()
                .add(*stage, since(start));
        }
        if let Some(hearing) = &mut self.hearing {
            let start = std::time::Instant::now();
            profiling::scope!(Stage::Audio.name());
            hearing.step(&mut self.world);
            self.world
                .resource_mut::<StageTimes>()
                .add(Stage::Audio, since(start));
        }
        self.steps += 1;
        if let Some(recording) = &mut self.recording {
            recording.after_step(&mut self.world);
        }
    }

    /// Brings the simulation's copy of the level up to date with the world as it stands
    /// (a step does this at its start), for tools that ask it questions between steps.
    pub fn update_step_world(&mut self) {
        self.step_world.run(&mut self.world);
    }

    /// The camera the next frame renders from, at `width` x `height`.
    pub fn view_camera(&self, width: u32, height: u32) -> Camera {
        Camera::new(&self.render_scene().camera, width, height)
    }

    /// The last render's tiles: the thread that traced each, and when.
    pub fn tile_spans(&self) -> &[TileSpan] {
        &self.tile_spans
    }

    /// The image to show: the film's.
    pub fn image(&self) -> crate::render::HdrImage {
        self.film.image().into_owned()
    }
}

/// The `RenderScene` of `scene` posed at level start, as the game would show its first
/// frame (for tools and tests that render a level without playing it).
pub fn render_scene(scene: &Scene) -> RenderScene {
    let mut engine = Engine::new(scene, RenderSettings::real_time(1, 1));
    engine
        .world
        .remove_resource::<RenderState>()
        .map(|state| state.scene)
        .expect("the engine keeps its render state")
}
