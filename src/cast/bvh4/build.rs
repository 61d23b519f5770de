//! The 4-wide BVH's builder: binned SAH (16 bins on each axis, Wald 2007), four
//! children per node made the way Embree's BVH4 builders make them — split the child
//! of largest surface area until there are four or none can be split — and leaves of
//! at most four triangles, one 4-lane block each.
//!
//! Large spans bin in parallel; the children of a node are built in parallel. Node
//! and leaf slots are reserved from atomic counters, so the tree's shape depends only
//! on the triangles while its memory order depends on the threads: hits never do (the
//! traversal's answer is the smallest `(t, id)`, whatever the order of visits).
//!
//! Two guards keep any input within `O(n log n)`: a span whose centroids cannot be
//! told apart by the bins (coincident or degenerate triangles) is halved by count, and
//! past `SAH_DEPTH` levels every split halves by count, so the tree is at most
//! `MAX_DEPTH` levels deep whatever the geometry (`node.rs`).

use super::node::{LEAF, LEAF_SIZE, Leaf, Node, SAH_DEPTH, leaf_code, leaf_of};
use crate::geometry::Aabb;
use crate::geometry::lanes::Boxes4;
use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// Bins per axis for spans of at least [`FEW`] triangles; smaller spans use
/// [`BINS_FEW`] (a sweep over 16 bins costs more than binning a dozen triangles).
const BINS: usize = 16;
const BINS_FEW: usize = 8;
const FEW: usize = 64;
/// Spans at least this long bin their triangles in parallel.
const PARALLEL_BINNING: usize = 1 << 15;
/// Spans at least this long build their children in parallel.
const PARALLEL_CHILDREN: usize = 1 << 11;

/// What the builder made: nodes (the root first when there is one), leaves, and the
/// root's child code.
pub(super) struct Built {
    pub nodes: Vec<Node>,
    pub leaves: Vec<Leaf>,
    pub root: u32,
}

/// A box on SIMD lanes (the builder's working form of [`Aabb`]).
#[derive(Clone, Copy, Debug)]
struct Box3 {
    min: Vec3A,
    max: Vec3A,
}

impl Box3 {
    const EMPTY: Box3 = Box3 { min: Vec3A::splat(f32::INFINITY), max: Vec3A::splat(f32::NEG_INFINITY) };

    #[inline]
    fn union(self, o: Box3) -> Box3 {
        Box3 { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    #[inline]
    fn grow(self, p: Vec3A) -> Box3 {
        Box3 { min: self.min.min(p), max: self.max.max(p) }
    }

    fn area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3A::ZERO);
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    fn aabb(&self) -> Aabb {
        Aabb { min: self.min.into(), max: self.max.into() }
    }
}

/// A contiguous part of the reference list with its triangles' box and the box of
/// their centroids (each centroid kept doubled, `min + max`, which orders as the
/// centroid does and costs no multiply).
#[derive(Clone, Copy, Debug)]
struct Span {
    start: usize,
    end: usize,
    bounds: Box3,
    centroids: Box3,
}

impl Span {
    fn len(&self) -> usize {
        self.end - self.start
    }
}

/// Boxes and centroids accumulated over a set of triangles.
#[derive(Clone, Copy, Debug)]
struct Extent {
    bounds: Box3,
    centroids: Box3,
    count: usize,
}

impl Extent {
    const EMPTY: Extent = Extent { bounds: Box3::EMPTY, centroids: Box3::EMPTY, count: 0 };

    #[inline]
    fn add(&mut self, b: &Box3) {
        self.bounds = self.bounds.union(*b);
        self.centroids = self.centroids.grow(b.min + b.max);
        self.count += 1;
    }

    fn merge(self, o: Extent) -> Extent {
        Extent {
            bounds: self.bounds.union(o.bounds),
            centroids: self.centroids.union(o.centroids),
            count: self.count + o.count,
        }
    }

    fn span(&self, start: usize) -> Span {
        Span { start, end: start + self.count, bounds: self.bounds, centroids: self.centroids }
    }
}

/// One bin: the box of its triangles and their count.
#[derive(Clone, Copy, Debug)]
struct Bin {
    bounds: Box3,
    count: usize,
}

impl Bin {
    const EMPTY: Bin = Bin { bounds: Box3::EMPTY, count: 0 };

    fn merge(self, o: Bin) -> Bin {
        Bin { bounds: self.bounds.union(o.bounds), count: self.count + o.count }
    }
}

/// Slots written once each from any thread, reserved by an atomic counter.
struct Slots<T> {
    ptr: *mut T,
    capacity: usize,
    next: AtomicUsize,
    vec: Vec<T>,
}

// SAFETY: a slot is written only by the thread that reserved it (`reserve` hands out
// each index once), and nothing reads the slots before `into_vec`, which takes `self`.
unsafe impl<T: Send> Sync for Slots<T> {}

impl<T> Slots<T> {
    fn with_capacity(capacity: usize) -> Slots<T> {
        let mut vec = Vec::with_capacity(capacity);
        Slots { ptr: vec.as_mut_ptr(), capacity, next: AtomicUsize::new(0), vec }
    }

    /// Reserves `k` consecutive slots; returns the first.
    fn reserve(&self, k: usize) -> usize {
        let i = self.next.fetch_add(k, Relaxed);
        assert!(i + k <= self.capacity, "bvh4: more slots than the bound of {}", self.capacity);
        i
    }

    fn write(&self, i: usize, value: T) {
        assert!(i < self.capacity);
        // SAFETY: `i` was reserved (so it is within the capacity) and is written once.
        unsafe { self.ptr.add(i).write(value) }
    }

    fn into_vec(mut self) -> Vec<T> {
        // SAFETY: every reserved slot below `next` has been written (the builder writes
        // each node and leaf it reserves before returning).
        unsafe { self.vec.set_len(*self.next.get_mut()) };
        self.vec
    }
}

/// A triangle as the builder moves it: its box and scene id, side by side so that
/// binning and partitions stream through memory.
#[derive(Clone, Copy, Debug)]
struct PrimRef {
    bounds: Box3,
    id: u32,
}

impl PrimRef {
    /// The centroid, doubled.
    #[inline]
    fn centroid(&self) -> Vec3A {
        self.bounds.min + self.bounds.max
    }
}

/// The builder's inputs and outputs.
struct Builder<'a> {
    tris: &'a [[Vec3; 3]],
    nodes: Slots<Node>,
    leaves: Slots<Leaf>,
}

/// Builds the tree over the listed scene triangles (at least one, all finite).
pub(super) fn build(tris: &[[Vec3; 3]], ids: &[u32]) -> Built {
    debug_assert!(!ids.is_empty());
    let n = ids.len();
    let mut refs: Vec<PrimRef> = ids
        .par_iter()
        .with_min_len(1 << 12)
        .map(|&id| {
            let [a, b, c] = tris[id as usize].map(Vec3A::from);
            PrimRef { bounds: Box3 { min: a.min(b).min(c), max: a.max(b).max(c) }, id }
        })
        .collect();
    // A tree with leaves of at least one triangle and at least two children per node
    // has fewer nodes than leaves.
    let b = Builder { tris, nodes: Slots::with_capacity(n.max(1)), leaves: Slots::with_capacity(n) };
    let whole = b.extent(&refs).span(0);
    let root = b.subtree(&mut refs, whole, 0);
    Built { nodes: b.nodes.into_vec(), leaves: b.leaves.into_vec(), root }
}

impl Builder<'_> {
    /// The extent of the listed references, in parallel when there are many.
    fn extent(&self, refs: &[PrimRef]) -> Extent {
        let fold = |mut e: Extent, r: &PrimRef| {
            e.add(&r.bounds);
            e
        };
        if refs.len() >= PARALLEL_BINNING {
            refs.par_chunks(PARALLEL_BINNING / 4)
                .map(|c| c.iter().fold(Extent::EMPTY, fold))
                .reduce(|| Extent::EMPTY, Extent::merge)
        } else {
            refs.iter().fold(Extent::EMPTY, fold)
        }
    }

    /// Builds the subtree over `refs` (the span's references, `span.start..span.end` of
    /// the whole list) and returns its child code: the top of the tree on every thread,
    /// writing to the shared slots node by node; subtrees below
    /// [`PARALLEL_CHILDREN`] on one thread into lists of their own, copied to the slots
    /// in one block (one atomic step per subtree, not per node).
    fn subtree(&self, refs: &mut [PrimRef], span: Span, depth: usize) -> u32 {
        let span = without_copies(self.tris, refs, span);
        let refs = &mut refs[..span.len()];
        if span.len() < PARALLEL_CHILDREN {
            let mut local = Local::default();
            let root = self.local_subtree(refs, span, depth, &mut local);
            return self.flush(local, root);
        }
        let (kids, n) = self.kids(refs, span, depth);
        let index = self.nodes.reserve(1);
        let mut codes = [0u32; 4];
        self.children(refs, &kids[..n], &mut codes[..n], depth + 1);
        self.nodes.write(index, node(&kids[..n], codes));
        index as u32
    }

    /// Builds the subtrees of consecutive spans that together cover `refs`, in
    /// parallel halves.
    fn children(&self, refs: &mut [PrimRef], kids: &[Span], codes: &mut [u32], depth: usize) {
        if kids.len() == 1 {
            codes[0] = self.subtree(refs, kids[0], depth);
            return;
        }
        let h = kids.len() / 2;
        let (r0, r1) = refs.split_at_mut(kids[h].start - kids[0].start);
        let (c0, c1) = codes.split_at_mut(h);
        rayon::join(|| self.children(r0, &kids[..h], c0, depth), || self.children(r1, &kids[h..], c1, depth));
    }

    /// [`Builder::subtree`] on one thread, into `out` (codes index `out`'s lists).
    fn local_subtree(&self, refs: &mut [PrimRef], span: Span, depth: usize, out: &mut Local) -> u32 {
        let span = without_copies(self.tris, refs, span);
        let refs = &mut refs[..span.len()];
        if span.len() <= LEAF_SIZE {
            let mut ids = [0u32; LEAF_SIZE];
            refs.iter().zip(&mut ids).for_each(|(r, id)| *id = r.id);
            out.leaves.push(Leaf::new(self.tris, &ids[..refs.len()]));
            return leaf_code(out.leaves.len() - 1, refs.len());
        }
        let (kids, n) = self.kids(refs, span, depth);
        let index = out.nodes.len();
        out.nodes.push(node(&kids[..n], [0; 4]));
        let mut rest = refs;
        for (k, &kid) in kids[..n].iter().enumerate() {
            let (part, tail) = rest.split_at_mut(kid.len());
            rest = tail;
            out.nodes[index].child[k] = self.local_subtree(part, kid, depth + 1, out);
        }
        index as u32
    }

    /// Copies a subtree built on one thread into the shared slots, moving its codes by
    /// where its block lands; returns its root's code there.
    fn flush(&self, local: Local, root: u32) -> u32 {
        let node_base = self.nodes.reserve(local.nodes.len());
        let leaf_base = self.leaves.reserve(local.leaves.len());
        let moved = |code: u32| match code & LEAF {
            0 => code + node_base as u32,
            _ => {
                let (leaf, len) = leaf_of(code);
                leaf_code(leaf_base + leaf, len)
            }
        };
        for (i, mut n) in local.nodes.into_iter().enumerate() {
            n.child = n.child.map(moved);
            self.nodes.write(node_base + i, n);
        }
        for (i, l) in local.leaves.into_iter().enumerate() {
            self.leaves.write(leaf_base + i, l);
        }
        moved(root)
    }

    /// A node's children: the span split, the child of largest area first (of most
    /// triangles past the SAH levels), until there are four or none can be split.
    fn kids(&self, refs: &mut [PrimRef], span: Span, depth: usize) -> ([Span; 4], usize) {
        let base = span.start;
        let by_count = depth >= SAH_DEPTH;
        let mut kids = [span; 4];
        let mut n = 1;
        while n < 4 {
            let weight = |s: &Span| if by_count { s.len() as f32 } else { s.bounds.area() };
            let Some(k) = (0..n)
                .filter(|&k| kids[k].len() > LEAF_SIZE)
                .max_by(|&a, &b| weight(&kids[a]).total_cmp(&weight(&kids[b])).then(b.cmp(&a)))
            else {
                break;
            };
            let s = kids[k];
            let (lo, hi) = self.split(&mut refs[s.start - base..s.end - base], s, by_count);
            kids.copy_within(k + 1..n, k + 2);
            (kids[k], kids[k + 1]) = (lo, hi);
            n += 1;
        }
        (kids, n)
    }

    /// Splits a span in two (both non-empty), reordering its references: at the
    /// binned SAH's best plane, or by count when `by_count` or when no plane separates
    /// the centroids.
    fn split(&self, refs: &mut [PrimRef], span: Span, by_count: bool) -> (Span, Span) {
        let plane = match by_count {
            true => None,
            false if refs.len() >= FEW => best_plane::<BINS>(refs, &span),
            false => best_plane::<BINS_FEW>(refs, &span),
        };
        if let Some(Plane { axis, bin, bins, scale }) = plane {
            let lo = span.centroids.min;
            let (mut l, mut r) = (Extent::EMPTY, Extent::EMPTY);
            let (mut i, mut j) = (0, refs.len());
            while i < j {
                let b = refs[i].bounds;
                if bin_index(refs[i].centroid(), lo, scale, bins)[axis] < bin {
                    l.add(&b);
                    i += 1;
                } else {
                    r.add(&b);
                    j -= 1;
                    refs.swap(i, j);
                }
            }
            return (l.span(span.start), r.span(span.start + i));
        }
        // Halve by count along the centroids' longest axis (by index when all
        // centroids coincide).
        let mid = refs.len() / 2;
        let e = (span.centroids.max - span.centroids.min).max(Vec3A::ZERO);
        let axis = if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        };
        if e[axis] > 0.0 {
            refs.select_nth_unstable_by(mid, |a, b| {
                a.centroid()[axis].total_cmp(&b.centroid()[axis]).then(a.id.cmp(&b.id))
            });
        }
        let (l, r) = refs.split_at(mid);
        (self.extent(l).span(span.start), self.extent(r).span(span.start + mid))
    }
}

/// A subtree built on one thread: its nodes (its root first) and leaves.
#[derive(Default)]
struct Local {
    nodes: Vec<Node>,
    leaves: Vec<Leaf>,
}

/// The node over `kids` with child codes `codes`.
fn node(kids: &[Span], codes: [u32; 4]) -> Node {
    let mut boxes = [Aabb::EMPTY; 4];
    boxes.iter_mut().zip(kids).for_each(|(b, s)| *b = s.bounds.aabb());
    Node { boxes: Boxes4::new(&boxes[..kids.len()]), child: codes, children: kids.len() as u32 }
}

/// The span without exact copies where no plane can separate its triangles (all
/// centroids coincide): halving by count would keep them all, and a copy is never the
/// answer (the smallest id wins ties).
fn without_copies(tris: &[[Vec3; 3]], refs: &mut [PrimRef], mut span: Span) -> Span {
    if span.len() > LEAF_SIZE && span.centroids.min == span.centroids.max {
        span.end = span.start + drop_copies(tris, refs);
    }
    span
}

/// A split plane: between bins `bin - 1` and `bin` of `bins` on `axis`, the bins
/// `scale` apart per unit of (doubled) centroid coordinate.
#[derive(Clone, Copy, Debug)]
struct Plane {
    axis: usize,
    bin: usize,
    bins: usize,
    scale: Vec3A,
}

/// The binned SAH's best split plane over `N` bins per axis, or `None` when no plane
/// leaves triangles on both sides at a finite cost.
fn best_plane<const N: usize>(refs: &[PrimRef], span: &Span) -> Option<Plane> {
    let lo = span.centroids.min;
    let ext = (span.centroids.max - lo).max(Vec3A::ZERO);
    let scale = Vec3A::select(ext.cmpgt(Vec3A::ZERO), N as f32 / ext, Vec3A::ZERO);
    let bin = |chunk: &[PrimRef]| {
        let mut bins = [[Bin::EMPTY; N]; 3];
        for r in chunk {
            let k = bin_index(r.centroid(), lo, scale, N);
            for a in 0..3 {
                let bin = &mut bins[a][k[a]];
                bin.bounds = bin.bounds.union(r.bounds);
                bin.count += 1;
            }
        }
        bins
    };
    let merge = |mut x: [[Bin; N]; 3], y: [[Bin; N]; 3]| {
        for a in 0..3 {
            for k in 0..N {
                x[a][k] = x[a][k].merge(y[a][k]);
            }
        }
        x
    };
    let bins = if refs.len() >= PARALLEL_BINNING {
        refs.par_chunks(PARALLEL_BINNING / 4).map(bin).reduce(|| [[Bin::EMPTY; N]; 3], merge)
    } else {
        bin(refs)
    };
    let mut best: Option<(f32, usize, usize)> = None;
    for (a, bins) in bins.iter().enumerate() {
        if scale[a] == 0.0 {
            continue;
        }
        // Right-hand sums, then a left-to-right sweep over the N − 1 planes.
        let mut right = [(0.0f32, 0usize); N];
        let mut acc = Bin::EMPTY;
        for k in (1..N).rev() {
            acc = acc.merge(bins[k]);
            right[k] = (acc.bounds.area(), acc.count);
        }
        let mut left = Bin::EMPTY;
        for k in 1..N {
            left = left.merge(bins[k - 1]);
            let (ra, rn) = right[k];
            if left.count == 0 || rn == 0 {
                continue;
            }
            let cost = left.bounds.area() * left.count as f32 + ra * rn as f32;
            if cost.is_finite() && best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, a, k));
            }
        }
    }
    best.map(|(_, axis, bin)| Plane { axis, bin, bins: N, scale })
}

/// The bins of a (doubled) centroid on the three axes: `(c − lo) · scale`, clamped to
/// the `n` bins (NaN and overflow included). Binning and partitioning both ask here,
/// so a triangle goes to the side its bin was counted on.
#[inline]
fn bin_index(c: Vec3A, lo: Vec3A, scale: Vec3A, n: usize) -> [usize; 3] {
    // `min` returns its second operand for a NaN lane; then the cast is in range.
    let f = ((c - lo) * scale).min(Vec3A::splat((n - 1) as f32)).max(Vec3A::ZERO);
    f.as_uvec3().to_array().map(|k| k as usize)
}

/// Drops exact copies (the same nine coordinates, bit for bit) from `refs`, keeping
/// each triangle's smallest id at the front; returns how many remain.
fn drop_copies(tris: &[[Vec3; 3]], refs: &mut [PrimRef]) -> usize {
    let bits = |r: &PrimRef| tris[r.id as usize].map(|v| v.to_array().map(f32::to_bits));
    refs.sort_unstable_by(|a, b| bits(a).cmp(&bits(b)).then(a.id.cmp(&b.id)));
    let mut kept = 0;
    for i in 0..refs.len() {
        if kept == 0 || bits(&refs[i]) != bits(&refs[kept - 1]) {
            refs[kept] = refs[i];
            kept += 1;
        }
    }
    kept
}
