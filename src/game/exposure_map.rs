//! Before play (`gloam exposure`): where on a level the player would be seen. For each
//! floor cell a body can reach from the spawn, the light gem a player standing or crouching
//! there would settle at (`exposure::settled_gem`: the game's own body points, lights and
//! shadow rays), and whether a walkable way leads from the spawn through every shard to the
//! exit with the gem never above a threshold.
//!
//! The floor is the level's `NavGrid` at the map's cell size, flooded from the spawn's cell
//! (cells nothing walkable joins, such as a crate's top, are left out). A column reached on
//! more than one floor (a bridge over a passage) puts each floor in its own storey, the
//! lowest first.
//!
//! The route: crouching is always open to the player, so a cell costs the lower of its two
//! values, and a way's exposure is its brightest cell. A shard or the exit is reached
//! anywhere within its radius, as the game takes or wins it. The least such maximum between two
//! cells is the bottleneck (minimax) distance, found by Dijkstra's algorithm with `max` in
//! place of `+`. Minimax distances form an ultrametric (any leg between two places is no
//! worse than the worse of reaching each from the spawn), so visiting every target in any
//! order costs exactly the worst of the spawn's minimax distances to them: one search
//! answers the whole route.

use std::collections::BinaryHeap;

use glam::Vec3;
use rayon::prelude::*;

use super::exposure::settled_gem;
use super::nav::{NavGrid, Node, Open};
use super::player::tuning::{CROUCHED_HEIGHT, STANDING_HEIGHT};
use super::world_query::WorldQuery;

/// One storey of the map: per cell (row-major, `width` a row), the settled gem standing
/// and crouching, or None where no reachable floor of this storey is.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Storey {
    pub standing: Vec<Option<f32>>,
    pub crouching: Vec<Option<f32>>,
}

/// The best way from the spawn through every shard to the exit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Route {
    /// The gem's highest value along the darkest way (None: no walkable way at all).
    pub max_exposure: Option<f32>,
    /// A way exists that keeps the gem at or below the threshold.
    pub exists: bool,
}

/// The map (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct ExposureMap {
    /// The minimum corner (x, z) of cell (0, 0), metres.
    pub origin: (f32, f32),
    pub cell_size: f32,
    /// Cells along +x and +z.
    pub width: usize,
    pub depth: usize,
    /// The lowest reachable floor of every column first, then any above.
    pub storeys: Vec<Storey>,
    pub route: Route,
}

/// The places the route must visit: the spawn, then each shard and the exit, each reached
/// anywhere within its radius (where the game takes the shard or wins).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Waypoints {
    pub spawn: Vec3,
    /// (position, pickup radius).
    pub shards: Vec<(Vec3, f32)>,
    /// (position, radius).
    pub exit: Option<(Vec3, f32)>,
}

/// The map of `world` within `bounds` at `cell`-metre cells, with the route through
/// `waypoints` judged against `threshold`.
pub fn exposure_map(
    world: &dyn WorldQuery,
    bounds: (Vec3, Vec3),
    cell: f32,
    waypoints: &Waypoints,
    threshold: f32,
) -> ExposureMap {
    let grid = NavGrid::build(world, bounds, cell);
    let cells = grid.width * grid.depth;
    let mut map = ExposureMap {
        origin: grid.origin,
        cell_size: grid.cell,
        width: grid.width,
        depth: grid.depth,
        storeys: Vec::new(),
        route: Route {
            max_exposure: None,
            exists: false,
        },
    };
    let Some(start) = grid.node_near(waypoints.spawn) else {
        return map;
    };
    // The floor the spawn reaches, and each cell's values (in parallel: every cell is
    // sixteen body points' worth of shadow rays).
    let reached = flood(&grid, start);
    let values: Vec<(f32, f32)> = reached
        .par_iter()
        .map(|&node| {
            let feet = grid.position(node);
            (
                settled_gem(world, feet, STANDING_HEIGHT),
                settled_gem(world, feet, CROUCHED_HEIGHT),
            )
        })
        .collect();
    // Crouching is always open to the player: a cell costs the lower of its two values.
    let mut cost = vec![f32::INFINITY; grid.index_bound()];
    let mut by_column: Vec<Vec<(f32, usize)>> = vec![Vec::new(); cells];
    for (at, (&node, &(standing, crouching))) in reached.iter().zip(&values).enumerate() {
        cost[grid.index(node)] = standing.min(crouching);
        by_column[node.column].push((grid.position(node).y, at));
    }
    // Storeys: the lowest reachable floor of each column in storey 0, and so on up.
    for (column, floors) in by_column.iter_mut().enumerate() {
        floors.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (storey, &(_, at)) in floors.iter().enumerate() {
            if map.storeys.len() <= storey {
                map.storeys.push(Storey {
                    standing: vec![None; cells],
                    crouching: vec![None; cells],
                });
            }
            let (standing, crouching) = values[at];
            map.storeys[storey].standing[column] = Some(standing);
            map.storeys[storey].crouching[column] = Some(crouching);
        }
    }
    // The route: the worst of the spawn's minimax distances to every target.
    let minimax = bottleneck_from(&grid, start, &cost);
    let targets = waypoints.shards.iter().chain(&waypoints.exit);
    let mut worst = cost[grid.index(start)];
    let mut walkable = true;
    for &(target, radius) in targets {
        // The darkest way to anywhere the target is within reach of the body, as the game
        // measures it (across the ground, the feet below it and the head above).
        let best = reached
            .iter()
            .filter(|&&node| {
                let feet = grid.position(node);
                let across = glam::Vec2::new(feet.x - target.x, feet.z - target.z).length();
                across <= radius.max(grid.cell * 0.5)
                    && target.y >= feet.y - 0.5
                    && target.y <= feet.y + STANDING_HEIGHT
            })
            .map(|&node| minimax[grid.index(node)])
            .fold(f32::INFINITY, f32::min);
        if best.is_finite() {
            worst = worst.max(best);
        } else {
            walkable = false;
        }
    }
    map.route = Route {
        max_exposure: walkable.then_some(worst),
        exists: walkable && worst <= threshold,
    };
    map
}

/// Every node a body walks to from `start`.
fn flood(grid: &NavGrid, start: Node) -> Vec<Node> {
    let mut seen = vec![false; grid.index_bound()];
    let mut reached = vec![start];
    seen[grid.index(start)] = true;
    let mut next = 0;
    while next < reached.len() {
        let node = reached[next];
        next += 1;
        for (neighbour, _) in grid.neighbours(node) {
            if !seen[grid.index(neighbour)] {
                seen[grid.index(neighbour)] = true;
                reached.push(neighbour);
            }
        }
    }
    reached
}

/// For every node, the least possible brightest cost along a way from `start` (infinite
/// where no way leads).
fn bottleneck_from(grid: &NavGrid, start: Node, cost: &[f32]) -> Vec<f32> {
    let mut best = vec![f32::INFINITY; grid.index_bound()];
    let mut open = BinaryHeap::new();
    best[grid.index(start)] = cost[grid.index(start)];
    open.push(Open {
        key: cost[grid.index(start)],
        node: start,
    });
    while let Some(Open { key: value, node }) = open.pop() {
        if value > best[grid.index(node)] {
            continue; // reached more cheaply since
        }
        for (neighbour, _) in grid.neighbours(node) {
            let through = value.max(cost[grid.index(neighbour)]);
            if through < best[grid.index(neighbour)] {
                best[grid.index(neighbour)] = through;
                open.push(Open {
                    key: through,
                    node: neighbour,
                });
            }
        }
    }
    best
}
