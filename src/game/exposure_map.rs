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
//!
//! To draw it, the route visits the targets in turn (the next is the one the darkest way
//! reaches, nearest first on a tie; the exit last), each leg the shortest way among those
//! no brighter than the leg's minimax distance. Where the drawn way crosses cells brighter
//! than the threshold, no way round is darker: those lit crossings are the level's
//! chokepoints.

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
    /// The floor's height (metres) in each cell the player reaches.
    pub floor: Vec<Option<f32>>,
}

/// The best way from the spawn through every shard to the exit.
#[derive(Clone, Debug, PartialEq)]
pub struct Route {
    /// The gem's highest value along the darkest way (None: no walkable way at all).
    pub max_exposure: Option<f32>,
    /// A way exists that keeps the gem at or below the threshold.
    pub exists: bool,
    /// That way, cell by cell (feet positions), from the spawn through every shard to the
    /// exit; empty when there is none.
    pub path: Vec<Vec3>,
    /// Where the way has to cross light above the threshold, no way round being darker:
    /// the brightest cell of each such crossing.
    pub chokepoints: Vec<Vec3>,
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
            path: Vec::new(),
            chokepoints: Vec::new(),
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
                    floor: vec![None; cells],
                });
            }
            let (standing, crouching) = values[at];
            map.storeys[storey].standing[column] = Some(standing);
            map.storeys[storey].crouching[column] = Some(crouching);
            map.storeys[storey].floor[column] = Some(grid.position(reached[at]).y);
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
        let best = within_reach(&grid, &reached, target, radius)
            .map(|node| minimax[grid.index(node)])
            .fold(f32::INFINITY, f32::min);
        if best.is_finite() {
            worst = worst.max(best);
        } else {
            walkable = false;
        }
    }
    let path = if walkable {
        drawn_route(&grid, &reached, start, &cost, waypoints)
    } else {
        Vec::new()
    };
    let chokepoints = lit_crossings(&path, |node| cost[grid.index(node)], threshold)
        .into_iter()
        .map(|node| grid.position(node))
        .collect();
    map.route = Route {
        max_exposure: walkable.then_some(worst),
        exists: walkable && worst <= threshold,
        path: path.iter().map(|&node| grid.position(node)).collect(),
        chokepoints,
    };
    map
}

/// The reached nodes from which a body reaches `target` (within `radius` across the
/// ground, the target between the feet and the head).
fn within_reach<'a>(
    grid: &'a NavGrid,
    reached: &'a [Node],
    target: Vec3,
    radius: f32,
) -> impl Iterator<Item = Node> + 'a {
    reached.iter().copied().filter(move |&node| {
        let feet = grid.position(node);
        let across = glam::Vec2::new(feet.x - target.x, feet.z - target.z).length();
        across <= radius.max(grid.cell * 0.5)
            && target.y >= feet.y - 0.5
            && target.y <= feet.y + STANDING_HEIGHT
    })
}

/// The route drawn: from the spawn to each shard in turn and then the exit, each leg the
/// shortest way among the darkest (see the module doc).
fn drawn_route(
    grid: &NavGrid,
    reached: &[Node],
    start: Node,
    cost: &[f32],
    waypoints: &Waypoints,
) -> Vec<Node> {
    let mut path = vec![start];
    let mut at = start;
    let mut shards: Vec<(Vec3, f32)> = waypoints.shards.clone();
    loop {
        let minimax = bottleneck_from(grid, at, cost);
        let goals = |target: Vec3, radius: f32| -> Vec<Node> {
            within_reach(grid, reached, target, radius).collect()
        };
        let darkest = |nodes: &[Node]| {
            nodes
                .iter()
                .map(|&n| minimax[grid.index(n)])
                .fold(f32::INFINITY, f32::min)
        };
        // The next shard: the darkest to reach from here, the nearest on a tie.
        let next = shards
            .iter()
            .enumerate()
            .map(|(index, &(target, radius))| {
                let nodes = goals(target, radius);
                let distance = grid.position(at).distance(target);
                (darkest(&nodes), distance, index, nodes)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let (nodes, last) = match next {
            Some((_, _, index, nodes)) => {
                shards.remove(index);
                (nodes, false)
            }
            None => match waypoints.exit {
                Some((target, radius)) => (goals(target, radius), true),
                None => return path,
            },
        };
        let limit = darkest(&nodes);
        let Some(leg) = shortest_within(grid, at, &nodes, cost, limit) else {
            return path;
        };
        at = *leg.last().unwrap_or(&at);
        path.extend(leg.into_iter().skip(1));
        if last {
            return path;
        }
    }
}

/// The shortest way from `from` to any of `goals` through cells costing at most `limit`
/// (Dijkstra over the grid's step lengths), `from` first; None when there is none.
fn shortest_within(
    grid: &NavGrid,
    from: Node,
    goals: &[Node],
    cost: &[f32],
    limit: f32,
) -> Option<Vec<Node>> {
    let mut distance = vec![f32::INFINITY; grid.index_bound()];
    let mut previous: Vec<Option<Node>> = vec![None; grid.index_bound()];
    let mut is_goal = vec![false; grid.index_bound()];
    for &goal in goals {
        is_goal[grid.index(goal)] = true;
    }
    let mut open = BinaryHeap::new();
    distance[grid.index(from)] = 0.0;
    open.push(Open {
        key: 0.0,
        node: from,
    });
    while let Some(Open { key, node }) = open.pop() {
        if key > distance[grid.index(node)] {
            continue;
        }
        if is_goal[grid.index(node)] {
            let mut way = vec![node];
            let mut at = node;
            while let Some(before) = previous[grid.index(at)] {
                way.push(before);
                at = before;
            }
            way.reverse();
            return Some(way);
        }
        for (neighbour, length) in grid.neighbours(node) {
            let index = grid.index(neighbour);
            if cost[index] > limit {
                continue;
            }
            let through = key + length;
            if through < distance[index] {
                distance[index] = through;
                previous[index] = Some(node);
                open.push(Open {
                    key: through,
                    node: neighbour,
                });
            }
        }
    }
    None
}

/// The brightest cell of each run of cells along `path` whose cost is above `threshold`.
fn lit_crossings<T: Copy>(path: &[T], cost: impl Fn(T) -> f32, threshold: f32) -> Vec<T> {
    let mut crossings = Vec::new();
    let mut brightest: Option<(f32, T)> = None;
    for &cell in path {
        let value = cost(cell);
        if value > threshold {
            if brightest.is_none_or(|(b, _)| value > b) {
                brightest = Some((value, cell));
            }
        } else if let Some((_, cell)) = brightest.take() {
            crossings.push(cell);
        }
    }
    crossings.extend(brightest.map(|(_, cell)| cell));
    crossings
}

/// Every node a body walks to from `start`.
pub fn flood(grid: &NavGrid, start: Node) -> Vec<Node> {
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

#[cfg(test)]
mod tests {
    use super::lit_crossings;

    #[test]
    fn each_lit_run_along_the_way_is_one_chokepoint_at_its_brightest() {
        let costs = [0.1, 0.6, 0.9, 0.7, 0.2, 0.3, 0.8, 0.1, 0.55];
        let path: Vec<usize> = (0..costs.len()).collect();
        assert_eq!(lit_crossings(&path, |i| costs[i], 0.5), [2, 6, 8]);
        assert!(lit_crossings(&path, |i| costs[i], 0.95).is_empty());
    }
}
