//! Game, at level load: where a warden can walk, and the way from one place to another.
//!
//! `NavGrid::build` lays a grid of square cells (`CELL` metres for the wardens) over the
//! level's geometry (asked
//! through `WorldQuery`, as of the first step) and finds, in each cell's column, every
//! surface a body can stand on: a ray cast down from above the level stops at each
//! surface, and a surface counts when it faces up as a floor does and a standing capsule of the player's radius and height
//! centred on the cell touches nothing but it. A column may hold several floors (a bridge
//! over a passage), each its own node. Two nodes in neighbouring cells are joined when
//! their floors differ by no more than a step (`STEP_HEIGHT`); diagonals only where both
//! sides are open, so no path cuts a corner.
//!
//! `NavGrid::path` is A* over those nodes (Hart, Nilsson and Raphael 1968) with the octile
//! distance as its heuristic, and the path is straightened by dropping every corner the
//! grid can walk past in a straight line (string pulling), so a warden walks lines, not
//! stairs of cells. Rigid geometry is what the grid sees: wardens' bodies and the player
//! are not obstacles in it, and a door that moves will need the grid rebuilt around it.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use bevy_ecs::prelude::*;
use glam::Vec3;

use super::player::tuning::{FLOOR_COSINE, RADIUS, STANDING_HEIGHT, STEP_HEIGHT};
use super::world_query::{Contact, WorldQuery};

/// The side of the wardens' cells in metres: small enough that a 1 m doorway keeps a cell
/// of the capsule-inflated free space, large enough that a 20 m level is 6,400 columns.
pub const CELL: f32 = 0.25;

/// The most floors one column holds.
const MAX_FLOORS: usize = 4;

/// Two floors of one column closer than this are one floor (metres).
const SAME_FLOOR: f32 = 0.05;

/// Where bodies can walk, built once at load.
#[derive(Resource, Clone, Debug, Default)]
pub struct NavGrid {
    /// The minimum corner (x, z) of cell (0, 0).
    pub origin: (f32, f32),
    /// The side of a cell in metres.
    pub cell: f32,
    /// Cells along +x and along +z.
    pub width: usize,
    pub depth: usize,
    /// Per column (row-major, x fastest), the floors' heights from the highest down.
    floors: Vec<Vec<f32>>,
}

/// A node of the grid: one floor in one column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Node {
    /// The column, row-major (`row * width + column`).
    pub column: usize,
    /// Which of the column's floors, highest first.
    pub floor: usize,
}

impl NavGrid {
    /// The grid of `cell`-metre cells over `world`'s geometry within `bounds` (min, max
    /// corners).
    pub fn build(world: &dyn WorldQuery, bounds: (Vec3, Vec3), cell: f32) -> NavGrid {
        let (min, max) = bounds;
        if !(min.is_finite() && max.is_finite() && cell.is_finite() && cell > 0.0)
            || min.x > max.x
            || min.z > max.z
        {
            return NavGrid::default();
        }
        // No more than 2048 cells a side: the build is linear in the cells.
        let width = (((max.x - min.x) / cell).ceil() as usize).clamp(1, 2048);
        let depth = (((max.z - min.z) / cell).ceil() as usize).clamp(1, 2048);
        let mut grid = NavGrid {
            origin: (min.x, min.z),
            cell,
            width,
            depth,
            floors: vec![Vec::new(); width * depth],
        };
        let mut contacts = Vec::new();
        let top = max.y + 1.0;
        for row in 0..depth {
            for column in 0..width {
                let (x, z) = grid.centre(column, row);
                let mut from = top;
                let mut floors = Vec::new();
                // Every surface down the column, top first.
                while floors.len() < MAX_FLOORS {
                    let origin = Vec3::new(x, from, z);
                    let Some(hit) = world.raycast(origin, Vec3::NEG_Y, from - min.y + 1.0) else {
                        break;
                    };
                    let floor = from - hit.distance;
                    // Only a surface facing up is a floor (not a slab's underside).
                    if hit.normal.y >= FLOOR_COSINE
                        && stands_clear(world, Vec3::new(x, floor, z), &mut contacts)
                    {
                        floors.push(floor);
                    }
                    from = floor - 0.05;
                }
                grid.floors[row * width + column] = floors;
            }
        }
        grid
    }

    /// This grid with every floor of `other` (a grid over the same cells, built when moving
    /// geometry stood elsewhere) added to its columns: where a body can stand at some time.
    /// Floors within `SAME_FLOOR` of one already there are the same floor. Each column keeps
    /// its `MAX_FLOORS` highest.
    pub fn union(&mut self, other: &NavGrid) {
        if (self.width, self.depth) != (other.width, other.depth) {
            return;
        }
        for (mine, theirs) in self.floors.iter_mut().zip(&other.floors) {
            for &floor in theirs {
                if !mine.iter().any(|&f| (f - floor).abs() <= SAME_FLOOR) {
                    mine.push(floor);
                }
            }
            mine.sort_by(|a, b| b.total_cmp(a));
            mine.truncate(MAX_FLOORS);
        }
    }

    /// Whether this grid has a floor at `position` (its column, within `SAME_FLOOR`).
    pub fn has_floor_at(&self, position: Vec3) -> bool {
        self.cell_of(position.x, position.z).is_some_and(|column| {
            self.floors[column]
                .iter()
                .any(|&f| (f - position.y).abs() <= SAME_FLOOR)
        })
    }

    /// The centre (x, z) of cell (`column`, `row`).
    pub fn centre(&self, column: usize, row: usize) -> (f32, f32) {
        (
            self.origin.0 + (column as f32 + 0.5) * self.cell,
            self.origin.1 + (row as f32 + 0.5) * self.cell,
        )
    }

    /// The floors a body can stand on in the column at (`x`, `z`), highest first.
    pub fn floors_at(&self, x: f32, z: f32) -> &[f32] {
        self.cell_of(x, z)
            .map_or(&[], |column| self.floors[column].as_slice())
    }

    /// Every node, column by column.
    pub fn nodes(&self) -> impl Iterator<Item = Node> + '_ {
        self.floors
            .iter()
            .enumerate()
            .flat_map(|(column, floors)| (0..floors.len()).map(move |floor| Node { column, floor }))
    }

    /// A dense index for `node` (below `index_bound`), for per-node tables.
    pub fn index(&self, node: Node) -> usize {
        node.column * MAX_FLOORS + node.floor
    }

    /// The node whose `index` is `index` (it may name no floor: check `floor_count`).
    pub fn node_of_index(&self, index: usize) -> Node {
        Node {
            column: index / MAX_FLOORS,
            floor: index % MAX_FLOORS,
        }
    }

    /// Whether `node` names a floor of this grid.
    pub fn holds(&self, node: Node) -> bool {
        self.floors
            .get(node.column)
            .is_some_and(|floors| node.floor < floors.len())
    }

    /// One more than the largest `index`.
    pub fn index_bound(&self) -> usize {
        self.floors.len() * MAX_FLOORS
    }

    /// How many nodes (floor cells) the grid holds.
    pub fn walkable_cells(&self) -> usize {
        self.floors.iter().map(Vec::len).sum()
    }

    fn cell_of(&self, x: f32, z: f32) -> Option<usize> {
        let column = ((x - self.origin.0) / self.cell).floor();
        let row = ((z - self.origin.1) / self.cell).floor();
        if column < 0.0 || row < 0.0 || column >= self.width as f32 || row >= self.depth as f32 {
            return None;
        }
        Some(row as usize * self.width + column as usize)
    }

    /// Where a body stands on `node`: its cell's centre, on its floor.
    pub fn position(&self, node: Node) -> Vec3 {
        let (x, z) = self.centre(node.column % self.width, node.column / self.width);
        Vec3::new(x, self.floors[node.column][node.floor], z)
    }

    /// The node nearest `at` (its own cell's floor nearest its feet, else the closest
    /// walkable cell within a metre).
    pub fn node_near(&self, at: Vec3) -> Option<Node> {
        let reach = (1.0 / self.cell).ceil() as i64;
        let column = ((at.x - self.origin.0) / self.cell).floor() as i64;
        let row = ((at.z - self.origin.1) / self.cell).floor() as i64;
        let mut best: Option<(f32, Node)> = None;
        for dz in -reach..=reach {
            for dx in -reach..=reach {
                let (c, r) = (column + dx, row + dz);
                if c < 0 || r < 0 || c >= self.width as i64 || r >= self.depth as i64 {
                    continue;
                }
                let index = r as usize * self.width + c as usize;
                for floor in 0..self.floors[index].len() {
                    let node = Node {
                        column: index,
                        floor,
                    };
                    let position = self.position(node);
                    // A floor far above the feet is another storey, not this one.
                    if position.y > at.y + STEP_HEIGHT + 0.2 {
                        continue;
                    }
                    let distance = position.distance_squared(at);
                    if best.is_none_or(|(d, _)| distance < d) {
                        best = Some((distance, node));
                    }
                }
            }
        }
        best.map(|(_, node)| node)
    }

    /// The node in column `column` whose floor is within a step of `height`.
    fn node_in(&self, column: usize, height: f32) -> Option<Node> {
        self.floors[column]
            .iter()
            .position(|&floor| (floor - height).abs() <= STEP_HEIGHT)
            .map(|floor| Node { column, floor })
    }

    /// The way from `from` to `to` as points to walk through (the last is `to`'s node),
    /// or `None` when no walkable way joins them.
    pub fn path(&self, from: Vec3, to: Vec3) -> Option<Vec<Vec3>> {
        let start = self.node_near(from)?;
        let goal = self.node_near(to)?;
        let index = |node: Node| self.index(node);
        let mut cost = vec![f32::INFINITY; self.index_bound()];
        let mut came_from: Vec<Option<Node>> = vec![None; self.index_bound()];
        let mut open = BinaryHeap::new();
        cost[index(start)] = 0.0;
        open.push(Open {
            key: self.heuristic(start, goal),
            node: start,
        });
        while let Some(Open {
            node,
            key: estimate,
        }) = open.pop()
        {
            if node == goal {
                break;
            }
            let here = cost[index(node)];
            if estimate > here + self.heuristic(node, goal) + 1e-4 {
                continue; // a stale entry: the node was reached more cheaply since
            }
            for (next, step) in self.neighbours(node) {
                let through = here + step;
                if through < cost[index(next)] {
                    cost[index(next)] = through;
                    came_from[index(next)] = Some(node);
                    open.push(Open {
                        key: through + self.heuristic(next, goal),
                        node: next,
                    });
                }
            }
        }
        if !cost[index(goal)].is_finite() {
            return None;
        }
        let mut nodes = vec![goal];
        while let Some(previous) = came_from[index(*nodes.last()?)] {
            nodes.push(previous);
        }
        nodes.reverse();
        let mut points: Vec<Vec3> = nodes.iter().map(|&node| self.position(node)).collect();
        // Start the walk where the body stands when it stands on the grid.
        if self.walkable_line(from, points[0]) {
            points[0] = from;
        }
        Some(self.straighten(&points))
    }

    /// Octile distance between two nodes' cells, in metres.
    fn heuristic(&self, a: Node, b: Node) -> f32 {
        let (ax, az) = (a.column % self.width, a.column / self.width);
        let (bx, bz) = (b.column % self.width, b.column / self.width);
        let dx = ax.abs_diff(bx) as f32;
        let dz = az.abs_diff(bz) as f32;
        self.cell * (dx.max(dz) + (std::f32::consts::SQRT_2 - 1.0) * dx.min(dz))
    }

    /// The nodes a body at `node` can step to, with the distance.
    pub fn neighbours(&self, node: Node) -> impl Iterator<Item = (Node, f32)> + '_ {
        let (x, z) = (
            (node.column % self.width) as i64,
            (node.column / self.width) as i64,
        );
        let height = self.floors[node.column][node.floor];
        let open = move |dx: i64, dz: i64| -> Option<Node> {
            let (c, r) = (x + dx, z + dz);
            if c < 0 || r < 0 || c >= self.width as i64 || r >= self.depth as i64 {
                return None;
            }
            self.node_in(r as usize * self.width + c as usize, height)
        };
        const STEPS: [(i64, i64); 8] = [
            (1, 0),
            (-1, 0),
            (0, 1),
            (0, -1),
            (1, 1),
            (1, -1),
            (-1, 1),
            (-1, -1),
        ];
        STEPS.into_iter().filter_map(move |(dx, dz)| {
            let next = open(dx, dz)?;
            if dx != 0 && dz != 0 {
                // Diagonal: both sides open, or the path would clip the corner between.
                open(dx, 0)?;
                open(0, dz)?;
                return Some((next, self.cell * std::f32::consts::SQRT_2));
            }
            Some((next, self.cell))
        })
    }

    /// The points after the first, with every corner dropped that a straight walk can
    /// skip.
    fn straighten(&self, points: &[Vec3]) -> Vec<Vec3> {
        let mut kept = Vec::new();
        let mut at = 0;
        while at + 1 < points.len() {
            let mut reach = at + 1;
            while reach + 1 < points.len() && self.walkable_line(points[at], points[reach + 1]) {
                reach += 1;
            }
            kept.push(points[reach]);
            at = reach;
        }
        if kept.is_empty() {
            kept.extend(points.first());
        }
        kept
    }

    /// Whether a body walks straight from `from` to `to` over walkable cells, a step at most
    /// between each and the next.
    pub fn walkable_line(&self, from: Vec3, to: Vec3) -> bool {
        let along = Vec3::new(to.x - from.x, 0.0, to.z - from.z);
        let samples = (along.length() / (self.cell * 0.25)).ceil().max(1.0) as usize;
        let mut height = from.y;
        for sample in 1..=samples {
            let at = from + along * (sample as f32 / samples as f32);
            let Some(column) = self.cell_of(at.x, at.z) else {
                return false;
            };
            match self.node_in(column, height) {
                Some(node) => height = self.floors[column][node.floor],
                None => return false,
            }
        }
        true
    }
}

/// Whether a standing body's capsule at `feet` touches nothing but the floor under it.
pub fn stands_clear(world: &dyn WorldQuery, feet: Vec3, contacts: &mut Vec<Contact>) -> bool {
    // Spheres of the capsule's radius from a step above the floor to the head: what is
    // lower than a step (a kerb, the next stair) the body steps up onto, as the player's
    // controller does, so it does not block the cell. (Half a step blocked every cell of a
    // 0.2 m x 0.33 m flight of stairs: each was within reach of the next riser.)
    let lowest = RADIUS + STEP_HEIGHT;
    let highest = STANDING_HEIGHT - RADIUS;
    let spheres = ((highest - lowest) / RADIUS).ceil() as usize + 1;
    (0..spheres).all(|i| {
        let y = lowest + (highest - lowest) * i as f32 / (spheres - 1).max(1) as f32;
        contacts.clear();
        world.sphere_contacts(feet + Vec3::Y * y, RADIUS, contacts);
        contacts.is_empty()
    })
}

/// A node waiting in a search's open set (A* here, the exposure map's minimax search),
/// the least key first: a `BinaryHeap` of these pops the least.
#[derive(Clone, Copy, Debug)]
pub struct Open {
    pub key: f32,
    pub node: Node,
}

impl PartialEq for Open {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Open {}

impl PartialOrd for Open {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Open {
    fn cmp(&self, other: &Self) -> Ordering {
        // Reversed for a min-heap; ties broken by node so the order is the same everywhere.
        other
            .key
            .total_cmp(&self.key)
            .then_with(|| other.node.column.cmp(&self.node.column))
            .then_with(|| other.node.floor.cmp(&self.node.floor))
    }
}
