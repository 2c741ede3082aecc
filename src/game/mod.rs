//! The game: ECS components, resources, systems and the schedules that run them.
//!
//! One displayed frame, headless (the window shell drives the same `Engine`):
//! 1. `Engine::advance(dt)`: the simulation clock accumulates real time and runs the
//!    fixed-step schedule at 60 Hz as many times as it owes: `fly_camera` (input), then
//!    gameplay systems as the game grows, and last `propagate_transforms`;
//! 2. the frame schedule, chained: `extract_instances` (moved entities -> accel instance
//!    transforms) -> `update_acceleration` (TLAS rebuild when anything moved) ->
//!    `render_frame` (one frame of samples) -> film accumulation: while nothing moves,
//!    frames add up into a converging image; any change starts it again.
//!
//! Render and accel never see this module: the `RenderScene` sits in a resource and the
//! systems here call into them with plain data.

pub mod input;
pub mod transform;

use bevy_ecs::prelude::*;
use glam::Vec3;

pub use input::{Action, Input, fly_camera};
pub use transform::{GlobalTransform, Transform, propagate_transforms};

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
                let mut spawned =
                    world.spawn((transform, GlobalTransform::default(), ChildOf(parent)));
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
                ViewCamera { yfov: camera.yfov },
            ));
        }
        let pixels = (settings.width * settings.height) as usize;
        world.insert_resource(Input::default());
        world.insert_resource(RenderState {
            scene: render,
            tlas_stale: false,
        });
        world.insert_resource(Accumulation {
            settings,
            sum: vec![Vec3::ZERO; pixels],
            frames: 0,
            reset: true,
        });

        let mut fixed_step = Schedule::default();
        fixed_step.add_systems((fly_camera, propagate_transforms).chain());
        let mut frame = Schedule::default();
        frame.add_systems((extract_instances, update_acceleration, render_frame).chain());
        let mut engine = Engine {
            world,
            fixed_step,
            frame,
            owed: 0.0,
            steps: 0,
        };
        // Settle the hierarchy once so the first frame sees world transforms.
        engine.fixed_step.run(&mut engine.world);
        engine
    }

    /// Simulates `seconds` of real time in fixed 1/60 s steps (the remainder carries
    /// over), then renders and accumulates one frame.
    pub fn advance(&mut self, seconds: f64) {
        self.owed += seconds.max(0.0);
        let step = 1.0 / SIMULATION_HZ;
        while self.owed >= step {
            self.fixed_step.run(&mut self.world);
            self.owed -= step;
            self.steps += 1;
        }
        self.frame.run(&mut self.world);
    }

    /// The accumulated image so far.
    pub fn image(&self) -> Film {
        self.world.resource::<Accumulation>().image()
    }
}

/// Extract: copies moved entities' world transforms into their accel instances.
pub fn extract_instances(
    moved: Query<(&RenderInstance, &GlobalTransform), Changed<GlobalTransform>>,
    moved_views: Query<(), (With<ViewCamera>, Changed<GlobalTransform>)>,
    mut state: ResMut<RenderState>,
    mut accumulation: ResMut<Accumulation>,
) {
    for (instance, global) in &moved {
        state.scene.accel.instances_mut()[instance.0 as usize].set_transform(global.0);
        state.tlas_stale = true;
    }
    if state.tlas_stale || !moved_views.is_empty() {
        accumulation.reset = true;
    }
}

/// Accel: rebuilds the TLAS when any instance moved.
pub fn update_acceleration(mut state: ResMut<RenderState>) {
    if state.tlas_stale {
        state.scene.accel.rebuild_tlas();
        state.tlas_stale = false;
    }
}

/// Render and film: one frame of samples from the view, added to the running sum (or
/// starting it again after a change).
pub fn render_frame(
    state: Res<RenderState>,
    views: Query<(&GlobalTransform, &ViewCamera)>,
    mut accumulation: ResMut<Accumulation>,
) {
    let Some((global, view)) = views.iter().next() else {
        return;
    };
    let placement = crate::scene::world::CameraPlacement {
        name: String::new(),
        yfov: view.yfov,
        znear: 0.01,
        world_from_camera: glam::Mat4::from(global.0),
    };
    let accumulation = &mut *accumulation;
    if accumulation.reset {
        accumulation.sum.iter_mut().for_each(|p| *p = Vec3::ZERO);
        accumulation.frames = 0;
        accumulation.reset = false;
    }
    let mut settings = accumulation.settings.clone();
    settings.frame = accumulation.frames;
    let camera = Camera::new(&placement, settings.width, settings.height);
    let output = render(&state.scene, &camera, &settings, &|_| {});
    for (sum, pixel) in accumulation.sum.iter_mut().zip(&output.film.pixels) {
        *sum += *pixel;
    }
    accumulation.frames += 1;
}
