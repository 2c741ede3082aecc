//! The bot's plan: a way through space and time on which no warden sees it.
//!
//! What the bot knows is what a player watching the level knows: its floor, the wardens'
//! routes and where they are, the light. It learns where the wardens will be and how the
//! light will fall by watching a copy of the level run on without it (the `foresight`
//! engine: the real simulation, with a body no warden can see standing in for the player's).
//! While the bot stays unseen and silent the real wardens walk exactly those steps: the
//! simulation is deterministic and their beats never read a player they have not noticed.
//!
//! The search (`sweep`) is over (floor cell, shards taken, moment): the moments are
//! slices of `SLICE_STEPS` fixed steps, the cells the nodes of a navigation grid over every
//! place a body can stand at some time (`Map`: the wardens' grid, joined with grids built
//! while moving geometry such as a gate stood elsewhere). From a cell the bot may wait a
//! slice, move to a neighbouring cell crouched (0.9 m/s) or walking (1.4 m/s; not near
//! anything it would knock over; on stairs only walking), or nudge towards a shard on a
//! table and back, taking the slices that move needs. It never sprints or jumps: both make
//! noise. At every slice a move spans, the most any warden could see of it is
//!
//!   vis = max(view(a), view(b)) x lit(max(gem(a), gem(b))),
//!
//! with `view` the share of the body's points in a warden's cones and in its line of sight
//! times the distance falloff (`sight::look`, the wardens' own function, mirrors included),
//! `gem` the light gem the body settles at there (`exposure::settled_gem`: the game's own
//! body points, lights and shadow rays) and `lit` the wardens' reading of it. Taking the
//! brighter end's gem stands for the gem's smoothing, which carries light from one cell
//! into the next. The wardens' suspicion then moves by `FILL_RATE` x vis - `DRAIN` a
//! second, as theirs does; the search carries an upper bound on the most suspicious
//! warden's (a move keeps it as a function of the suspicion it left with, so one move
//! serves every set of shards) and drops every move that would take it past
//! `SUSPICION_LIMIT`, half of noticing. No cell within `KEEP_AWAY` of a warden is taken.
//! The slices advance in order, as the foresight engine runs, so the search is a
//! breadth-first sweep through time: the first slice at which the way out is reached with
//! every shard is the earliest unseen finish, and waiting in the dark for a lamp to pass is
//! simply the move that gets there first.
//!
//! A sweep that takes no new shard in `LEG_SECONDS` has no unseen route: the cells along
//! the shortest walkable way to what it still lacks that it never reached, and found
//! watched and lit, are its chokepoints.

use glam::Vec3;
use rayon::prelude::*;

use crate::frame::Engine;
use crate::game::exposure::settled_gem;
use crate::game::exposure_map::flood;
use crate::game::nav::{CELL, NavGrid, Node, stands_clear};
use crate::game::player::tuning::{CROUCH, CROUCHED_HEIGHT, RADIUS, STANDING_HEIGHT, WALK};
use crate::game::sight::{self, tuning::FAR_RANGE};
use crate::game::warden::tuning::{DRAIN, FILL_RATE, NOTICE};
use crate::game::world_query::{WorldGeometry, WorldQuery};
use crate::game::{Knockable, SIMULATION_HZ, Transform, Warden};

/// Fixed steps in one slice of the search (a fifteenth of a second): a warden's cone
/// sweeps at most 12 degrees in one, and a body inside it for less than a slice raises no
/// warden's suspicion to noticing (0.067 s x (2 - 0.2) a second = 0.12, under 0.25).
pub const SLICE_STEPS: u64 = 6;

/// A view this dim needs no light gem to judge: counted as fully lit it still drains
/// suspicion (which grows only above a visibility of 0.1).
pub const SAFE_VISIBILITY: f32 = 0.095;

/// No cell nearer a warden than this (metres across the ground) is taken: within touch a
/// warden senses the body from behind, and its lamp is there.
pub const KEEP_AWAY: f32 = 1.6;

/// How long the sweep may go without taking another shard (or, with all taken, reaching
/// the way out) before the level is judged to have no unseen route (seconds): longer than
/// any beat's round.
pub const LEG_SECONDS: f64 = 150.0;

/// How far apart in time the grids of moving geometry are built, and for how long.
const MAP_SAMPLE_SECONDS: f64 = 1.0;
const MAP_SAMPLES: usize = 24;

/// How the bot carries itself on a move.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stance {
    Crouch = 0,
    Stand = 1,
}

impl Stance {
    pub fn height(self) -> f32 {
        match self {
            Stance::Crouch => CROUCHED_HEIGHT,
            Stance::Stand => STANDING_HEIGHT,
        }
    }

    pub fn speed(self) -> f32 {
        match self {
            Stance::Crouch => CROUCH,
            Stance::Stand => WALK,
        }
    }

    /// Slices a move of `length` metres takes: the time at this speed, with 5 cm to spare
    /// for a body a little off a cell's centre.
    fn slices(self, length: f32) -> u32 {
        let steps = (length + 0.05) / self.speed() * SIMULATION_HZ as f32;
        (steps / SLICE_STEPS as f32).ceil().max(1.0) as u32
    }
}

/// Where a body can stand, at some time, and how it may carry itself there.
pub struct Map {
    pub grid: NavGrid,
    /// Per node index: a floor only at some times (geometry moves over it), so each slice
    /// asks whether the body fits there.
    dynamic: Vec<bool>,
    /// Per node index: nothing to knock over within reach of a standing body.
    stand_ok: Vec<bool>,
    /// Per node index: a crouched body keeps its footing here. On a flight of stairs it
    /// does not: its shorter capsule catches the steps and it drops from one to the next
    /// hard enough to be heard (measured on the keep's stairs), so there the bot walks.
    crouch_ok: Vec<bool>,
}

impl Map {
    /// The map of the level `engine` runs (at its first step; it is stepped on to see
    /// moving geometry elsewhere, so give it an engine of its own).
    pub fn build(engine: &mut Engine) -> Option<Map> {
        engine.update_step_world();
        let bounds = engine.world.resource::<WorldGeometry>().0.bounds()?;
        let mut grids = Vec::with_capacity(MAP_SAMPLES);
        for sample in 0..MAP_SAMPLES {
            if sample > 0 {
                for _ in 0..(MAP_SAMPLE_SECONDS * SIMULATION_HZ) as u64 {
                    engine.step();
                }
                engine.update_step_world();
            }
            let geometry = &engine.world.resource::<WorldGeometry>().0;
            grids.push(NavGrid::build(geometry.as_ref(), bounds, CELL));
        }
        let mut grid = grids[0].clone();
        for other in &grids[1..] {
            grid.union(other);
        }
        let mut dynamic = vec![false; grid.index_bound()];
        for node in grid.nodes() {
            let at = grid.position(node);
            dynamic[grid.index(node)] = !grids.iter().all(|g| g.has_floor_at(at));
        }
        // Things to knock over: a standing body within reach topples them (noise).
        let knockables: Vec<(Vec3, f32)> = engine
            .world
            .query::<(&Knockable, &Transform)>()
            .iter(&engine.world)
            .map(|(thing, placed)| (placed.translation, thing.radius))
            .collect();
        let mut stand_ok = vec![true; grid.index_bound()];
        for node in grid.nodes() {
            let at = grid.position(node);
            stand_ok[grid.index(node)] = knockables.iter().all(|&(thing, radius)| {
                let across = glam::Vec2::new(thing.x - at.x, thing.z - at.z).length();
                across > radius + RADIUS + 0.35 || (thing.y - at.y).abs() > STANDING_HEIGHT
            });
        }
        let mut crouch_ok = vec![true; grid.index_bound()];
        for node in grid.nodes() {
            let height = grid.position(node).y;
            crouch_ok[grid.index(node)] = grid
                .neighbours(node)
                .all(|(next, _)| (grid.position(next).y - height).abs() <= 0.05);
        }
        Some(Map {
            grid,
            dynamic,
            stand_ok,
            crouch_ok,
        })
    }
}

impl Map {
    /// How the bot waits at node `index`: crouched, but on stairs standing.
    pub fn rest_stance(&self, index: usize) -> Stance {
        if self.crouch_ok[index] || !self.stand_ok[index] {
            Stance::Crouch
        } else {
            Stance::Stand
        }
    }
}

/// A warden where the foresight engine has it at one slice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WardenPose {
    pub at: Vec3,
    pub yaw: f32,
}

/// The wardens of `engine`'s world, in name order.
pub fn warden_poses(engine: &mut Engine) -> Vec<WardenPose> {
    let mut found: Vec<(String, WardenPose)> = engine
        .world
        .query::<(&bevy_ecs::name::Name, &Transform, &Warden)>()
        .iter(&engine.world)
        .map(|(name, placed, warden)| {
            (
                name.as_str().to_owned(),
                WardenPose {
                    at: placed.translation,
                    yaw: warden.yaw,
                },
            )
        })
        .collect();
    found.sort_by(|a, b| a.0.cmp(&b.0));
    found.into_iter().map(|(_, pose)| pose).collect()
}

/// One move of the plan: to node `to`, leaving at slice `depart` and arriving at slice
/// `arrive` of the sweep; a nudge moves towards shard `nudge` from `to` and back.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanMove {
    pub to: Node,
    pub depart: u32,
    pub arrive: u32,
    pub stance: Stance,
    pub nudge: Option<usize>,
}

/// A lit place with no way round.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chokepoint {
    pub at: Vec3,
    /// Seconds into the run when the bot found it watched and lit.
    pub time: f64,
    /// The light gem a body settles at there then.
    pub exposure: f32,
}

/// How the sweep ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Sweep {
    /// Every shard taken and the way out reached: the moves there, in order.
    Won { moves: Vec<PlanMove> },
    /// No walkable way leads to `what` at all.
    Unreachable { what: String },
    /// Walkable, but no unseen way to `what` within `LEG_SECONDS` of the last shard taken:
    /// the lit crossings on the way.
    Watched {
        what: String,
        chokepoints: Vec<Chokepoint>,
    },
    /// The run's time ran out first.
    OutOfTime,
}

/// A move under way, for every set of shards taken it carries (bit m of `masks`: the
/// shards of mask m taken). What the wardens' suspicion does over the slices it has run
/// is kept as a function of the suspicion it left with, s -> max(`floor`, s + `rise`),
/// with the most each part reached (`floor_peak`, `rise_peak`), so one move serves every
/// set (each left with its own suspicion).
#[derive(Clone, Copy)]
struct Pending {
    from: u32,
    to: u32,
    depart: u32,
    arrive: u32,
    stance: Stance,
    /// The shard a nudge takes.
    nudge: Option<u8>,
    masks: u64,
    /// The least suspicion any of its sets left with.
    least: f32,
    floor: f32,
    rise: f32,
    floor_peak: f32,
    rise_peak: f32,
}

/// How a node looks at one slice, per stance: its view factor (share x falloff, infinite
/// where the body cannot be) and light gem (NaN until asked).
#[derive(Clone, Copy)]
struct Seen {
    view: [f32; 2],
    gem: [f32; 2],
}

const UNKNOWN: Seen = Seen {
    view: [f32::NAN; 2],
    gem: [f32::NAN; 2],
};

/// What the sweep knows of the slice it is at. Its tables live across slices: `touched`
/// says which entries to clear when the next slice begins.
struct Slice<'a> {
    map: &'a Map,
    seen: Vec<Seen>,
    touched: Vec<u32>,
    /// Per node index and stance, the slice that last asked for its view or gem (so each
    /// is listed once without sorting: a slice asks for hundreds of thousands).
    asked_view: Vec<[u32; 2]>,
    asked_gem: Vec<[u32; 2]>,
    slice: u32,
}

impl<'a> Slice<'a> {
    fn new(map: &'a Map) -> Slice<'a> {
        let bound = map.grid.index_bound();
        Slice {
            map,
            seen: vec![UNKNOWN; bound],
            touched: Vec::new(),
            asked_view: vec![[u32::MAX; 2]; bound],
            asked_gem: vec![[u32::MAX; 2]; bound],
            slice: 0,
        }
    }

    /// Forgets the last slice's answers.
    fn begin(&mut self, slice: u32) {
        for &index in &self.touched {
            self.seen[index as usize] = UNKNOWN;
        }
        self.touched.clear();
        self.slice = slice;
    }

    /// The view factor of a body at node `index` in `stance` (see the module doc).
    fn view(
        map: &Map,
        world: &dyn WorldQuery,
        wardens: &[WardenPose],
        index: usize,
        stance: Stance,
    ) -> f32 {
        let grid = &map.grid;
        let at = grid.position(grid.node_of_index(index));
        if map.dynamic[index] && !stands_clear(world, at, &mut Vec::new()) {
            return f32::INFINITY;
        }
        let points = crate::game::exposure::body_points(at, 0.0, stance.height());
        let mirrors = !world.mirrors().is_empty();
        let mut worst = 0.0f32;
        for warden in wardens {
            let across = glam::Vec2::new(warden.at.x - at.x, warden.at.z - at.z).length();
            if across < KEEP_AWAY && (warden.at.y - at.y).abs() < STANDING_HEIGHT {
                return f32::INFINITY;
            }
            let forward = Vec3::new(warden.yaw.sin(), 0.0, warden.yaw.cos());
            let eye = sight::eye(warden.at, forward);
            if !mirrors && (at + Vec3::Y).distance(eye) > FAR_RANGE + 1.0 {
                continue;
            }
            let seen = sight::look(world, eye, forward, &points, 1.0);
            worst = worst.max(seen.visibility);
        }
        worst
    }

    fn ensure_views(
        &mut self,
        world: &dyn WorldQuery,
        wardens: &[WardenPose],
        wanted: impl Iterator<Item = (usize, Stance)>,
    ) {
        let mut missing = Vec::new();
        for (index, stance) in wanted {
            let asked = &mut self.asked_view[index][stance as usize];
            if *asked != self.slice {
                *asked = self.slice;
                missing.push((index, stance));
            }
        }
        let map = self.map;
        let views: Vec<f32> = missing
            .par_iter()
            .map(|&(index, stance)| Slice::view(map, world, wardens, index, stance))
            .collect();
        for (&(index, stance), view) in missing.iter().zip(views) {
            if self.seen[index].view[0].is_nan() && self.seen[index].view[1].is_nan() {
                self.touched.push(index as u32);
            }
            self.seen[index].view[stance as usize] = view;
        }
    }

    fn ensure_gems(&mut self, world: &dyn WorldQuery, moves: &[(usize, usize, Stance)]) {
        let mut missing = Vec::new();
        for &(a, b, stance) in moves {
            let s = stance as usize;
            let view = self.seen[a].view[s].max(self.seen[b].view[s]);
            if !(view.is_finite() && view > SAFE_VISIBILITY) {
                continue;
            }
            for index in [a, b] {
                let asked = &mut self.asked_gem[index][s];
                if *asked != self.slice {
                    *asked = self.slice;
                    missing.push((index, stance));
                }
            }
        }
        let grid = &self.map.grid;
        let gems: Vec<f32> = missing
            .par_iter()
            .map(|&(index, stance)| {
                let at = grid.position(grid.node_of_index(index));
                settled_gem(world, at, stance.height())
            })
            .collect();
        for (&(index, stance), gem) in missing.iter().zip(gems) {
            self.seen[index].gem[stance as usize] = gem;
        }
    }

    /// How fast the suspicion of the warden that sees most of a body moving between `a`
    /// and `b` in `stance` grows at this slice (a second; negative: it drains), at most;
    /// infinite where the body cannot be. Views and (where a view is open) gems must have
    /// been ensured.
    fn growth(&self, a: usize, b: usize, stance: Stance) -> f32 {
        let s = stance as usize;
        let view = self.seen[a].view[s].max(self.seen[b].view[s]);
        if view.is_infinite() {
            return f32::INFINITY;
        }
        // A dim view needs no gem: counted as fully lit, it still drains.
        let lit = if view <= SAFE_VISIBILITY {
            1.0
        } else {
            sight::lit(self.seen[a].gem[s].max(self.seen[b].gem[s]))
        };
        FILL_RATE * view * lit - DRAIN
    }

    /// Each of `moves`' growth at this slice: ensures what they need, then answers.
    fn check(
        &mut self,
        world: &dyn WorldQuery,
        wardens: &[WardenPose],
        moves: &[(usize, usize, Stance)],
    ) -> Vec<f32> {
        self.ensure_views(
            world,
            wardens,
            moves.iter().flat_map(|&(a, b, s)| [(a, s), (b, s)]),
        );
        self.ensure_gems(world, moves);
        moves
            .iter()
            .map(|&(a, b, stance)| self.growth(a, b, stance))
            .collect()
    }
}

/// The search's memory of one node, for chokepoints.
#[derive(Clone, Copy)]
struct Watched {
    /// The first slice (of the run) it was found watched and lit, and the gem then.
    first: Option<(u64, f32)>,
    reached: bool,
}

/// The most shards the sweep carries as sets of taken shards (a u64 holds 2^6 sets).
pub const MAX_SHARDS: usize = 6;

/// What the bot must reach: each shard (its name, place and pickup radius) and the way
/// out (its place and radius).
pub struct Targets {
    pub shards: Vec<(String, Vec3, f32)>,
    pub exit: (Vec3, f32),
}

/// Per node, what a body standing there does to the shards: takes (bit i: shard i is
/// within reach of the cell's centre, with room for a body a little off it), or may nudge
/// towards (bit i: within its radius and a cell).
struct Reach {
    takes: Vec<u8>,
    nudges: Vec<u8>,
    exit: Vec<bool>,
}

impl Reach {
    fn new(grid: &NavGrid, targets: &Targets) -> Reach {
        let bound = grid.index_bound();
        let mut reach = Reach {
            takes: vec![0; bound],
            nudges: vec![0; bound],
            exit: vec![false; bound],
        };
        for node in grid.nodes() {
            let feet = grid.position(node);
            let index = grid.index(node);
            let across = |at: Vec3| glam::Vec2::new(feet.x - at.x, feet.z - at.z).length();
            for (i, (_, at, radius)) in targets.shards.iter().enumerate() {
                // The game takes a shard between half a metre under the feet and the head.
                if at.y < feet.y - 0.5 || at.y > feet.y + STANDING_HEIGHT {
                    continue;
                }
                if across(*at) <= radius * 0.75 {
                    reach.takes[index] |= 1 << i;
                } else if across(*at) <= radius + CELL {
                    reach.nudges[index] |= 1 << i;
                }
            }
            let (exit, radius) = targets.exit;
            reach.exit[index] =
                across(exit) <= radius * 0.75 && (exit.y - feet.y).abs() < STANDING_HEIGHT;
        }
        reach
    }
}

/// Slices a move may take at most (a crouched diagonal, a nudge), and one more: the
/// sweep keeps this many slices of suspicions to read a move's start from.
const RING: usize = 12;

/// Sweeps from `start`, with the shards of `taken` already taken and the wardens'
/// suspicion at most `suspicion`, at the foresight engine's present (its `steps`) until
/// every shard is taken and the way out reached unseen (see the module doc), for at most
/// `max_slices` slices. `poses` gets the wardens' poses at every slice swept.
#[allow(clippy::too_many_arguments)]
pub fn sweep(
    map: &Map,
    foresight: &mut Engine,
    start: Node,
    targets: &Targets,
    taken: u8,
    suspicion: f32,
    max_slices: u32,
    poses: &mut Vec<Vec<WardenPose>>,
) -> Sweep {
    let grid = &map.grid;
    let shards = targets.shards.len();
    debug_assert!(
        shards <= MAX_SHARDS,
        "a u64 holds the sets of at most 6 shards"
    );
    let sets = 1usize << shards;
    let all = (sets - 1) as u8;
    let reach = Reach::new(grid, targets);
    let run_step = foresight.steps;
    let dt = (SLICE_STEPS as f64 / SIMULATION_HZ) as f32;
    // Walkable at all?
    let walkable = flood(grid, start);
    let name = |i: usize| targets.shards[i].0.clone();
    for i in 0..shards {
        if taken & (1 << i) == 0
            && !walkable.iter().any(|&n| {
                (reach.takes[grid.index(n)] | reach.nudges[grid.index(n)]) & (1 << i) != 0
            })
        {
            return Sweep::Unreachable { what: name(i) };
        }
    }
    if !walkable.iter().any(|&n| reach.exit[grid.index(n)]) {
        return Sweep::Unreachable {
            what: "the way out".into(),
        };
    }
    let bound = grid.index_bound();
    let stall_slices = ((LEG_SECONDS * SIMULATION_HZ) as u64 / SLICE_STEPS) as u32;
    let mut watched = vec![
        Watched {
            first: None,
            reached: false,
        };
        bound
    ];
    // Per slice, the arrivals that were not a wait: (node, mask, from, from mask, depart,
    // stance, nudge); the last for a (node, mask) is the one that stood. Every other
    // (node, mask) of a slice waited there since the slice before.
    let mut arrivals: Vec<Vec<Arrival>> = Vec::new();
    // The least suspicion each (node, set) is reached with, for the last `RING` slices
    // (infinite: not reached).
    let mut tables = vec![vec![f32::INFINITY; bound * sets]; RING];
    let mut active: Vec<u32>;
    let mut pending: Vec<Pending> = Vec::new();
    let start_index = grid.index(start);
    let mut view = Slice::new(map);
    // The most shards any set reached holds, and when that last grew.
    let (mut best, mut best_slice) = (taken.count_ones(), 0u32);
    let mut out_of_time = false;
    for slice in 0..=max_slices {
        if slice > 0 {
            for _ in 0..SLICE_STEPS {
                foresight.step();
            }
        }
        foresight.update_step_world();
        let wardens = warden_poses(foresight);
        let geometry = &foresight.world.resource::<WorldGeometry>().0;
        let world = geometry.as_ref();
        view.begin(slice);
        poses.push(wardens.clone());
        let now = slice as usize % RING;
        // The slot is reused: clear what it held `RING` slices ago.
        tables[now].fill(f32::INFINITY);
        // 1. Moves under way: what the wardens' suspicion does over this slice.
        let under_way: Vec<(usize, usize, Stance)> = pending
            .iter()
            .map(|p| (p.from as usize, p.to as usize, p.stance))
            .collect();
        let growths = view.check(world, &wardens, &under_way);
        let mut reached_now: Vec<u32> = Vec::new();
        let mut recorded: Vec<Arrival> = Vec::new();
        if slice == 0 {
            let growth = view.check(
                world,
                &wardens,
                &[(start_index, start_index, Stance::Crouch)],
            )[0];
            if growth.is_finite() {
                let mask = (taken | reach.takes[start_index]) as usize;
                tables[now][start_index * sets + mask] = suspicion.max(0.0);
                reached_now.push(start_index as u32);
            }
        }
        let mut kept = Vec::with_capacity(pending.len());
        // Waits first: a set that could stay keeps no record.
        let is_wait = |p: &Pending| p.from == p.to && p.nudge.is_none();
        let waits = (0..pending.len()).filter(|&i| is_wait(&pending[i]));
        let others = (0..pending.len()).filter(|&i| !is_wait(&pending[i]));
        for i in waits.chain(others) {
            let mut p = pending[i];
            let growth = growths[i];
            if !growth.is_finite() {
                continue;
            }
            p.floor = (p.floor + growth * dt).max(0.0);
            p.rise += growth * dt;
            p.floor_peak = p.floor_peak.max(p.floor);
            p.rise_peak = p.rise_peak.max(p.rise);
            if p.floor_peak > SUSPICION_LIMIT || p.least + p.rise_peak > SUSPICION_LIMIT {
                continue;
            }
            if p.arrive != slice {
                kept.push(p);
                continue;
            }
            let takes = reach.takes[p.to as usize] | p.nudge.map_or(0, |i| 1 << i);
            let from_table = &tables[p.depart as usize % RING];
            let mut arrived = Vec::new();
            let mut rest = p.masks;
            while rest != 0 {
                let mask = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let left = from_table[p.from as usize * sets + mask];
                if left + p.rise_peak > SUSPICION_LIMIT {
                    continue;
                }
                arrived.push((mask, p.floor.max(left + p.rise)));
            }
            let table = &mut tables[now];
            let is_wait = p.from == p.to && p.nudge.is_none();
            for (mask, level) in arrived {
                let into = mask | takes as usize;
                let slot = &mut table[p.to as usize * sets + into];
                if level < *slot {
                    if slot.is_infinite() {
                        reached_now.push(p.to);
                    }
                    *slot = level;
                    if !is_wait {
                        recorded.push((
                            p.to, into as u8, p.from, mask as u8, p.depart, p.stance, p.nudge,
                        ));
                    }
                }
            }
        }
        pending = kept;
        reached_now.sort_unstable();
        reached_now.dedup();
        active = reached_now;
        let table = &tables[now];
        for &node in &active {
            watched[node as usize].reached = true;
            let row = &table[node as usize * sets..][..sets];
            let most = (0..sets)
                .filter(|&m| row[m].is_finite())
                .map(|m| m.count_ones())
                .max()
                .unwrap_or(0);
            if most > best {
                (best, best_slice) = (most, slice);
            }
        }
        arrivals.push(recorded);
        // Record what was found watched and lit among the cells checked, for chokepoints.
        for &index in &view.touched {
            let index = index as usize;
            let seen = view.seen[index];
            let s = Stance::Crouch as usize;
            if seen.view[s].is_finite()
                && seen.view[s] > SAFE_VISIBILITY
                && !seen.gem[s].is_nan()
                && FILL_RATE * seen.view[s] * sight::lit(seen.gem[s]) > DRAIN
                && watched[index].first.is_none()
            {
                watched[index].first = Some((run_step + slice as u64 * SLICE_STEPS, seen.gem[s]));
            }
        }
        // Won: the way out with every shard.
        if let Some(&node) = active.iter().find(|&&n| {
            reach.exit[n as usize] && table[n as usize * sets + all as usize].is_finite()
        }) {
            return Sweep::Won {
                moves: trace_back(grid, &arrivals, node, all, slice),
            };
        }
        if slice == max_slices {
            out_of_time = true;
            break;
        }
        if slice - best_slice > stall_slices {
            break;
        }
        // 2. Moves from here: wait, or step to a neighbour crouched or walking, or nudge
        // towards a shard within reach. Each carries every set reached here.
        for &node in &active {
            let a = node as usize;
            let row = &table[a * sets..][..sets];
            let masks = (0..sets)
                .filter(|&m| row[m].is_finite())
                .fold(0u64, |bits, m| bits | 1 << m);
            let least = row.iter().copied().fold(f32::INFINITY, f32::min);
            let mut go = |to: usize, stance: Stance, slices: u32, nudge: Option<u8>| {
                pending.push(Pending {
                    from: node,
                    to: to as u32,
                    depart: slice,
                    arrive: slice + slices,
                    stance,
                    nudge,
                    masks,
                    least,
                    floor: 0.0,
                    rise: 0.0,
                    floor_peak: 0.0,
                    rise_peak: 0.0,
                })
            };
            go(a, map.rest_stance(a), 1, None);
            for (next, length) in grid.neighbours(grid.node_of_index(a)) {
                let b = grid.index(next);
                let stand = map.stand_ok[a] && map.stand_ok[b];
                if !stand || (map.crouch_ok[a] && map.crouch_ok[b]) {
                    go(b, Stance::Crouch, Stance::Crouch.slices(length), None);
                }
                if stand {
                    go(b, Stance::Stand, Stance::Stand.slices(length), None);
                }
            }
            let nudges = reach.nudges[a];
            for i in 0..shards as u8 {
                if nudges & (1 << i) != 0 {
                    go(a, Stance::Crouch, NUDGE_SLICES, Some(i));
                }
            }
        }
        if pending.is_empty() {
            break; // nowhere left that is unseen
        }
    }
    if out_of_time {
        return Sweep::OutOfTime;
    }
    // The first target the best sets reached lack: where the way is watched.
    let last = &tables[arrivals.len().saturating_sub(1) % RING];
    let best_mask = (0..bound)
        .flat_map(|i| (0..sets).filter(move |&m| last[i * sets + m].is_finite()))
        .max_by_key(|m| m.count_ones())
        .map_or(taken, |m| m as u8);
    let (what, goal): (String, Vec<bool>) = match (0..shards).find(|&i| best_mask & (1 << i) == 0) {
        Some(i) => (
            name(i),
            (0..bound)
                .map(|n| (reach.takes[n] | reach.nudges[n]) & (1 << i) != 0)
                .collect(),
        ),
        None => ("the way out".into(), reach.exit.clone()),
    };
    Sweep::Watched {
        what,
        chokepoints: chokepoints(grid, start, &goal, &watched),
    }
}

/// An arrival that was not a wait: (node, mask, from, from mask, depart, stance, nudge).
type Arrival = (u32, u8, u32, u8, u32, Stance, Option<u8>);

/// The most the planner lets any warden's suspicion rise (a warden notices at `NOTICE`):
/// brushes with a warden's view leave it well short.
pub const SUSPICION_LIMIT: f32 = NOTICE * 0.5;

/// Slices a nudge towards a shard takes.
pub const NUDGE_SLICES: u32 = 8;

/// The moves that reached `node` with the shards of `mask` at `slice`, back to the start,
/// in order (waits left out: the body stays where it is).
fn trace_back(
    grid: &NavGrid,
    arrivals: &[Vec<Arrival>],
    node: u32,
    mask: u8,
    slice: u32,
) -> Vec<PlanMove> {
    let mut moves = Vec::new();
    let (mut node, mut mask, mut slice) = (node, mask, slice);
    while slice > 0 {
        match arrivals[slice as usize]
            .iter()
            .rev()
            .find(|&&(n, m, ..)| n == node && m == mask)
        {
            Some(&(_, _, from, from_mask, depart, stance, nudge)) => {
                moves.push(PlanMove {
                    to: grid.node_of_index(node as usize),
                    depart,
                    arrive: slice,
                    stance,
                    nudge: nudge.map(usize::from),
                });
                (node, mask, slice) = (from, from_mask, depart);
            }
            // A wait: the same cell and shards the slice before.
            None => slice -= 1,
        }
    }
    moves.reverse();
    moves
}

/// The lit crossings of a leg that found no unseen way: along the shortest walkable way
/// from `start` to the goal, the first run of cells the sweep never reached that it found
/// watched and lit, at its brightest.
fn chokepoints(grid: &NavGrid, start: Node, goal: &[bool], watched: &[Watched]) -> Vec<Chokepoint> {
    let from = grid.position(start);
    // The goal node nearest the start by the grid's way.
    let Some(way) = grid
        .nodes()
        .filter(|&n| goal[grid.index(n)])
        .filter_map(|n| grid.path(from, grid.position(n)))
        .min_by(|a, b| way_length(from, a).total_cmp(&way_length(from, b)))
    else {
        return Vec::new();
    };
    // The way as cells, densely (the path's corners are straight walks apart).
    let mut cells = Vec::new();
    let mut at = from;
    for &corner in &way {
        let steps = (at.distance(corner) / (CELL * 0.5)).ceil().max(1.0) as usize;
        for i in 1..=steps {
            let point = at.lerp(corner, i as f32 / steps as f32);
            if let Some(node) = grid.node_near(point) {
                cells.push(node);
            }
        }
        at = corner;
    }
    let mut run: Option<(f32, Vec3, u64)> = None;
    for node in cells {
        let memory = watched[grid.index(node)];
        if memory.reached {
            if run.is_some() {
                break;
            }
            continue;
        }
        match memory.first {
            Some((step, gem)) => {
                if run.is_none_or(|(g, ..)| gem > g) {
                    run = Some((gem, grid.position(node), step));
                }
            }
            None if run.is_some() => break,
            None => {}
        }
    }
    run.map(|(gem, at, step)| Chokepoint {
        at,
        time: step as f64 / SIMULATION_HZ,
        exposure: gem,
    })
    .into_iter()
    .collect()
}

fn way_length(from: Vec3, way: &[Vec3]) -> f32 {
    let mut length = 0.0;
    let mut at = from;
    for &point in way {
        length += at.distance(point);
        at = point;
    }
    length
}
