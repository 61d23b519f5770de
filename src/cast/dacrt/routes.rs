//! The shared top's plan and its routes: the planes chosen on a sample of the
//! triangles' boxes, and the descent that finds the cell (or cells) of each box. Below
//! `top.rs`, which builds the top with them.

use crate::geometry::Aabb;
use glam::Vec3;

/// The shared top's planes, chosen on a sample before any triangle is routed.
pub(super) enum Plan {
    /// Cell number `.0` (numbered depth first, low side first).
    Cell(usize),
    Split {
        axis: usize,
        pos: f32,
        kids: Box<[Plan; 2]>,
    },
}

impl Plan {
    /// Numbers the cells depth first from `next`.
    pub(super) fn number(&mut self, next: &mut usize) {
        match self {
            Plan::Cell(c) => {
                *c = *next;
                *next += 1;
            }
            Plan::Split { kids, .. } => kids.iter_mut().for_each(|k| k.number(next)),
        }
    }
}

/// A numbered [`Plan`] flattened for routing: node 0 is the root; a node is a cell
/// (`axis == CELL`, its number in `kids[0]`) or a plane with its two children. Each
/// cell also keeps the open region its path's planes bound (`regions`, by cell
/// number): a box strictly inside it descends to that cell.
pub(super) struct Routes {
    nodes: Vec<RouteNode>,
    regions: Vec<(Vec3, Vec3)>,
}

#[derive(Clone, Copy)]
struct RouteNode {
    axis: usize,
    pos: f32,
    kids: [usize; 2],
}

/// `RouteNode::axis` of a cell.
const CELL: usize = 3;

impl Routes {
    /// The routes of a plan whose cells are numbered `0..cells`.
    pub(super) fn new(plan: &Plan, cells: usize) -> Routes {
        fn push(plan: &Plan, (lo, hi): (Vec3, Vec3), routes: &mut Routes) -> usize {
            let at = routes.nodes.len();
            routes.nodes.push(RouteNode { axis: CELL, pos: 0.0, kids: [0; 2] });
            routes.nodes[at] = match plan {
                Plan::Cell(c) => {
                    routes.regions[*c] = (lo, hi);
                    RouteNode { axis: CELL, pos: 0.0, kids: [*c, 0] }
                }
                Plan::Split { axis, pos, kids } => {
                    // A box goes low when its max is below the plane, high when its
                    // min is above it (`descend`).
                    let (mut below, mut above) = (hi, lo);
                    below[*axis] = below[*axis].min(*pos);
                    above[*axis] = above[*axis].max(*pos);
                    let l = push(&kids[0], (lo, below), routes);
                    let h = push(&kids[1], (above, hi), routes);
                    RouteNode { axis: *axis, pos: *pos, kids: [l, h] }
                }
            };
            at
        }
        let mut routes = Routes { nodes: Vec::new(), regions: vec![(Vec3::INFINITY, Vec3::NEG_INFINITY); cells] };
        push(plan, (Vec3::NEG_INFINITY, Vec3::INFINITY), &mut routes);
        routes
    }

    /// Whether the box lies strictly inside cell `c`'s region, so that it descends to
    /// `c` (false for NaN bounds and for a box on a plane: those descend as usual).
    #[inline]
    pub(super) fn inside(&self, c: usize, b: &Aabb) -> bool {
        let (lo, hi) = self.regions[c];
        b.min.cmpgt(lo).all() && b.max.cmplt(hi).all()
    }

    /// [`Routes::descend`] from the root, asking first whether the box lies inside
    /// `last` (the cell of the box before it): neighbouring triangles of a mesh mostly
    /// share a cell, and the test has no chain of loads.
    #[inline]
    pub(super) fn descend_near(&self, b: &Aabb, last: Option<usize>) -> Result<usize, usize> {
        match last {
            Some(c) if self.inside(c, b) => Ok(c),
            _ => self.descend(b, 0),
        }
    }

    /// The cell of a box that lies on one side of every plane on its way down, or
    /// `Err(node)` for the first node whose plane it touches (closed half-spaces: such
    /// a box goes to both sides), or `Err(usize::MAX)` for a box with NaN bounds. The
    /// descent picks a child by a comparison, not a branch: most boxes take one path.
    #[inline]
    pub(super) fn descend(&self, b: &Aabb, mut n: usize) -> Result<usize, usize> {
        let (min, max) = (b.min.to_array(), b.max.to_array());
        loop {
            let node = self.nodes[n];
            if node.axis == CELL {
                return Ok(node.kids[0]);
            }
            let (lo, hi) = (min[node.axis] <= node.pos, max[node.axis] >= node.pos);
            if lo == hi {
                return Err(if lo { n } else { usize::MAX });
            }
            n = node.kids[hi as usize];
        }
    }

    /// Calls `f` with every cell whose half-spaces the box overlaps. For boxes inside
    /// the scene's box this is the same as overlapping the cell's region.
    pub(super) fn route_from(&self, b: &Aabb, n: usize, f: &mut impl FnMut(usize)) {
        match self.descend(b, n) {
            Ok(cell) => f(cell),
            Err(usize::MAX) => {}
            Err(split) => {
                let kids = self.nodes[split].kids;
                self.route_from(b, kids[0], f);
                self.route_from(b, kids[1], f);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// Asking the last cell first (`descend_near`) answers as the descent from the root
    /// does, whatever cell is asked: boxes with corners on the planes' coarse grid
    /// touch planes exactly, some boxes have NaN bounds, and the plan is uneven, so
    /// that regions are bounded on some axes and open on others.
    #[test]
    fn asking_the_last_cell_first_finds_the_cells_the_descent_finds() {
        fn plan(rng: &mut Rng, depth: u32) -> Plan {
            if depth >= 6 || rng.uniform() < 0.15 * depth as f32 {
                return Plan::Cell(0);
            }
            let axis = (rng.uniform() * 3.0) as usize % 3;
            let pos = (rng.uniform() * 8.0).round() * 0.25 - 1.0;
            Plan::Split { axis, pos, kids: Box::new([plan(rng, depth + 1), plan(rng, depth + 1)]) }
        }
        let mut rng = Rng::for_sample(7, 0, 0);
        for trial in 0..20 {
            let mut p = plan(&mut rng, 0);
            let mut cells = 0;
            p.number(&mut cells);
            let routes = Routes::new(&p, cells);
            let coarse = trial % 2 == 0;
            let (mut shortcuts, mut touching, mut last) = (0, 0, None);
            for k in 0..2000 {
                let mut corner = || {
                    let v = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - 1.0;
                    if coarse { (v * 4.0).round() * 0.25 } else { v }
                };
                let (a, c) = (corner(), corner());
                // Small boxes near the last one half the time, as a mesh's neighbours.
                let mut b = Aabb::from_points(&[a, if k % 2 == 0 { a + (c - a) * 0.05 } else { c }]);
                if k % 97 == 0 {
                    b.min.y = f32::NAN;
                }
                let asked = if k % 5 == 0 { Some((rng.uniform() * cells as f32) as usize % cells) } else { last };
                let expected = routes.descend(&b, 0);
                assert_eq!(routes.descend_near(&b, asked), expected, "trial {trial}, box {b:?}, asked {asked:?}");
                shortcuts += asked.is_some_and(|c| routes.inside(c, &b)) as u32;
                touching += expected.is_err() as u32;
                last = expected.ok().or(last);
            }
            assert!(shortcuts > 0 && touching > 0, "trial {trial}: {shortcuts} shortcuts, {touching} touching");
        }
    }
}
