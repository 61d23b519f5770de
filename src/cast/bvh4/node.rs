//! The 4-wide BVH's floor: what the builder writes and the traversal reads — nodes,
//! leaves, the child codes that name them, and the bounds on leaf size and depth.

use crate::geometry::lanes::{Boxes4, Triangles4};
use glam::Vec3;

/// Triangles a leaf may hold (one 4-lane block).
pub(super) const LEAF_SIZE: usize = 4;
/// Levels built by SAH; deeper spans are halved by count.
pub(super) const SAH_DEPTH: usize = 40;
/// The deepest a tree can be: SAH levels, then at most 32 levels of halving (each
/// level at least halves the largest child, and a span holds fewer than 2^32).
pub(super) const MAX_DEPTH: usize = SAH_DEPTH + 33;

/// A node: its children's boxes on four lanes and their codes (a node index, or a
/// leaf: [`leaf_code`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Node {
    pub boxes: Boxes4,
    pub child: [u32; 4],
    /// Children in use (2 to 4), in lanes `0..children`.
    pub children: u32,
}

/// A leaf: up to four triangles on SIMD lanes, with their scene ids.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Leaf {
    pub tris: Triangles4,
    pub ids: [u32; 4],
}

impl Leaf {
    /// The leaf of the listed triangles (one to four).
    pub fn new(tris: &[[Vec3; 3]], ids: &[u32]) -> Leaf {
        let mut corners = [[Vec3::ZERO; 3]; 4];
        let mut all = [u32::MAX; 4];
        for (k, &id) in ids.iter().enumerate() {
            (corners[k], all[k]) = (tris[id as usize], id);
        }
        Leaf { tris: Triangles4::new(&corners[..ids.len()]), ids: all }
    }
}

/// Marks a child code as a leaf.
pub(super) const LEAF: u32 = 1 << 31;

/// The code of leaf `leaf` holding `len` triangles (1 to 4).
pub(super) fn leaf_code(leaf: usize, len: usize) -> u32 {
    assert!(leaf < (1 << 29), "bvh4: more than 2^29 leaves");
    LEAF | (leaf as u32) << 2 | (len as u32 - 1)
}

/// The leaf and triangle count a leaf code names.
#[inline]
pub(super) fn leaf_of(code: u32) -> (usize, usize) {
    (((code & !LEAF) >> 2) as usize, (code & 3) as usize + 1)
}

/// Levels of inner nodes on the longest path down from `root` (an inner node's code).
pub(super) fn depth(nodes: &[Node], root: u32) -> usize {
    let mut deepest = 0;
    let mut pending = vec![(root, 1usize)];
    while let Some((code, level)) = pending.pop() {
        if code & LEAF != 0 {
            continue;
        }
        deepest = deepest.max(level);
        let node = &nodes[code as usize];
        pending.extend(node.child[..node.children as usize].iter().map(|&c| (c, level + 1)));
    }
    deepest
}
