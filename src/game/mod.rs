//! The game: ECS components, resources, systems and the schedules that run them.
//!
//! One displayed frame, headless (the window shell drives the same `Engine`):
//! 1. `Engine::advance(dt)`: the simulation clock accumulates real time and runs the
//!    fixed-step schedule at 60 Hz as many times as it owes: `fly_camera` (input), then
//!    gameplay systems as the game grows, and last `propagate_transforms`;
//! 2. the frame schedule, chained: `extract_instances` (moved entities -> accel instance
//!    transforms, interpolated between the last two simulation steps by how far real time
//!    has run into the next one) -> `update_acceleration` (TLAS rebuild when anything
//!    moved) -> `render_frame` (one frame of samples) -> film accumulation: while nothing
//!    moves, frames add up into a converging image; any change starts it again.
//!
//! Each stage's time lands in the `StageTimes` resource (the profiler issue builds on it).
//!
//! Render and accel never see this module: the `RenderScene` sits in a resource and the
//! systems here call into them with plain data.

pub mod input;
pub mod transform;

use bevy_ecs::prelude::*;
use glam::Vec3;

pub use input::{Action, Input, fly_camera};
pub use transform::{
    GlobalTransform, PreviousGlobalTransform, Transform, interpolate, propagate_transforms,
    remember_transforms,
};

use crate::extract::{instance_user_id, render_scene};
use crate::render::{Camera, Film, RenderScene, RenderSettings, render};
use crate::scene::model::NodeTransform;
use crate::scene::world::Scene;

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

/// The scene as the renderer reads it, and whether the TLAS is stale.
#[derive(Resource)]
pub struct RenderState {
    pub scene: RenderScene,
    pub tlas_stale: bool,
}

/// Frames accumulated since the last change, as a running sum of per-frame means.
#[derive(Resource)]
pub struct Accumulation {
    pub settings: RenderSettings,
    sum: Vec<Vec3>,
    pub frames: u32,
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

/// Milliseconds each stage of the last frame took.
#[derive(Resource, Default, Clone, Copy, Debug)]
pub struct StageTimes {
    /// All fixed steps run for this frame (input, gameplay, transforms).
    pub simulate: f64,
    pub extract: f64,
    /// TLAS rebuild (and BLAS refits, with deforming meshes).
    pub accel: f64,
    pub render: f64,
    /// Adding the frame into the accumulated image.
    pub film: f64,
}

fn since(start: std::time::Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

impl Accumulation {
    /// The converging image: mean of the accumulated frames.
    pub fn image(&self) -> Film {
        let scale = 1.0 / self.frames.max(1) as f32;
        Film {
            width: self.settings.width,
            height: self.settings.height,
            pixels: self.sum.iter().map(|p| *p * scale).collect(),
        }
    }
}

/// The ECS world and its two schedules.
pub struct Engine {
    pub world: World,
    fixed_step: Schedule,
    frame: Schedule,
    /// Real time not yet simulated, in seconds.
    owed: f64,
    /// Fixed steps run so far.
    pub steps: u64,
}

impl Engine {
    /// Spawns `scene` into a new world: one entity per level entity, with the glTF node
    /// hierarchy of its asset as children; mesh nodes get their `RenderInstance`.
    pub fn new(scene: &Scene, settings: RenderSettings) -> Engine {
        let mut world = World::new();
        let render = render_scene(scene);
        // Map (level entity, node) -> accel instance.
        let instance_of: std::collections::HashMap<u64, u32> = render
            .accel
            .instances()
            .iter()
            .enumerate()
            .map(|(i, instance)| (instance.user_id, i as u32))
            .collect();
        let camera = render.camera.clone();
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
            let Some(asset) = scene.entity_assets[index].map(|a| &scene.assets[a]) else {
                continue;
            };
            // The asset's nodes, parents before children.
            let mut stack: Vec<(usize, Entity)> =
                asset.roots.iter().rev().map(|&node| (node, root)).collect();
            while let Some((node, parent)) = stack.pop() {
                let transform = match asset.nodes[node].transform {
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
                    ChildOf(parent),
                ));
                if let Some(&instance) = instance_of.get(&instance_user_id(index, node)) {
                    spawned.insert(RenderInstance(instance));
                }
                let id = spawned.id();
                stack.extend(
                    asset.nodes[node]
                        .children
                        .iter()
                        .rev()
                        .map(|&child| (child, id)),
                );
            }
        }
        // The view: the level's camera entity if it has one, else a camera entity placed
        // where extract's choice (an asset camera or a framing view) puts it.
        let mut views = world.query_filtered::<Entity, With<ViewCamera>>();
        if views.iter(&world).next().is_none() {
            world.spawn((
                Transform::from_matrix(camera.world_from_camera),
                GlobalTransform::default(),
                PreviousGlobalTransform::default(),
                ViewCamera { yfov: camera.yfov },
            ));
        }
        let pixels = (settings.width * settings.height) as usize;
        world.insert_resource(Input::default());
        world.insert_resource(SimulationClock::default());
        world.insert_resource(StageTimes::default());
        world.insert_resource(RenderState {
            scene: render,
            tlas_stale: false,
        });
        world.insert_resource(Accumulation {
            view: None,
            settings,
            sum: vec![Vec3::ZERO; pixels],
            frames: 0,
            reset: true,
        });

        let mut fixed_step = Schedule::default();
        fixed_step.add_systems((remember_transforms, fly_camera, propagate_transforms).chain());
        let mut frame = Schedule::default();
        frame.add_systems((extract_instances, update_acceleration, render_frame).chain());
        let mut engine = Engine {
            world,
            fixed_step,
            frame,
            owed: 0.0,
            steps: 0,
        };
        // Settle the hierarchy once so the first frame sees world transforms, with nothing
        // to interpolate from.
        engine.fixed_step.run(&mut engine.world);
        let mut settle = engine
            .world
            .query::<(&GlobalTransform, &mut PreviousGlobalTransform)>();
        for (global, mut previous) in settle.iter_mut(&mut engine.world) {
            previous.0 = global.0;
        }
        engine
    }

    /// Simulates `seconds` of real time in fixed 1/60 s steps (the remainder carries
    /// over), then renders and accumulates one frame.
    pub fn advance(&mut self, seconds: f64) {
        let start = std::time::Instant::now();
        self.owed += seconds.max(0.0);
        let step = 1.0 / SIMULATION_HZ;
        while self.owed >= step {
            self.fixed_step.run(&mut self.world);
            self.owed -= step;
            self.steps += 1;
        }
        self.world.resource_mut::<StageTimes>().simulate = since(start);
        self.world.resource_mut::<SimulationClock>().alpha = (self.owed / step) as f32;
        self.frame.run(&mut self.world);
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
    mut accumulation: ResMut<Accumulation>,
    mut times: ResMut<StageTimes>,
) {
    let start = std::time::Instant::now();
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
        }
    }
    if state.tlas_stale {
        accumulation.reset = true;
    }
    times.extract = since(start);
}

/// Accel: rebuilds the TLAS when any instance moved.
pub fn update_acceleration(mut state: ResMut<RenderState>, mut times: ResMut<StageTimes>) {
    let start = std::time::Instant::now();
    if state.tlas_stale {
        state.scene.accel.rebuild_tlas();
        state.tlas_stale = false;
    }
    times.accel = since(start);
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
    let shown = if previous.0 == global.0 {
        global.0
    } else {
        interpolate(previous.0, global.0, clock.alpha)
    };
    let placement = crate::scene::world::CameraPlacement {
        name: String::new(),
        yfov: view.yfov,
        znear: 0.01,
        world_from_camera: glam::Mat4::from(shown),
    };
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
    let start = std::time::Instant::now();
    let output = render(&state.scene, &camera, &settings, &|_| {});
    times.render = since(start);
    let start = std::time::Instant::now();
    for (sum, pixel) in accumulation.sum.iter_mut().zip(&output.film.pixels) {
        *sum += *pixel;
    }
    accumulation.frames += 1;
    times.film = since(start);
}
