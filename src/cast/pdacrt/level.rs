//! One breadth-first level of PDACRT: the stage calls of the module docs, in order.

use super::kernels::*;
use super::{LevelRecord, Pdacrt, Workspace};
use simt::{DeviceBuffer, LaunchConfig, Readable};
use std::time::Instant;

fn add3(a: Triple, b: Triple) -> Triple {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// The sum of a scanned array: its last exclusive-scan entry plus its last input.
fn scan_total(flags: &DeviceBuffer<Triple>, scan: &DeviceBuffer<Triple>) -> Triple {
    let n = flags.len();
    add3(scan.as_slice()[n - 1], flags.as_slice()[n - 1])
}

impl Pdacrt {
    /// One level over `ws.cur`: fills `ws.next`, solves this level's terminal nodes,
    /// and returns the level's record (its launches are added by the caller).
    pub(super) fn level(&self, ws: &mut Workspace, depth: u32, any_hit: bool) -> LevelRecord {
        let start = Instant::now();
        let (n_nodes, n_rays, n_tris) = (ws.cur.nodes.len(), ws.cur.ray_ids.len(), ws.cur.tri_ids.len());
        self.split_nodes(ws);
        let boxes =
            if self.params.inspect { ws.cur.nodes.as_slice().iter().map(|n| n.bounds).collect() } else { vec![] };
        self.filter(ws, any_hit);
        self.split_codes(ws, n_nodes);
        let terminal = self.place_children(ws, depth);
        self.scatter(ws);
        if terminal[0] > 0 {
            self.solve_terminals(ws, any_hit);
        }
        LevelRecord {
            level: depth,
            nodes: n_nodes,
            rays: n_rays,
            triangle_refs: n_tris,
            terminal_nodes: terminal[0] as usize,
            terminal_rays: terminal[1] as usize,
            terminal_triangles: terminal[2] as usize,
            id_bytes: (n_rays + n_tris) * 8,
            seconds: start.elapsed().as_secs_f64(),
            kernels: Vec::new(),
            boxes,
        }
    }

    /// `node_bounds` then `split_nodes`: tight node boxes and the two children of each.
    fn split_nodes(&self, ws: &mut Workspace) {
        let dev = &self.dev;
        let n_nodes = ws.cur.nodes.len();
        ws.tight.resize(6 * n_nodes);
        {
            let tv = ws.tight.view_mut();
            dev.for_each("pdacrt::clear_bounds", 6 * n_nodes, |t, i| t.store(&tv, i, EMPTY_ORDERED[i % 6]));
        }
        {
            let (ids, nd, tris, tv) =
                (ws.cur.tri_ids.view(), ws.cur.tri_node.view(), self.tris.view(), ws.tight.view_mut());
            dev.for_each_in("pdacrt::node_bounds", &["bounds"], ids.len().div_ceil(BOUNDS_RUN), |t, k| {
                node_bounds(t, &ids, &nd, &tris, &tv, k)
            });
        }
        ws.child_boxes.resize(2 * n_nodes);
        let (nv, tv, cv) = (ws.cur.nodes.view_mut(), ws.tight.view(), ws.child_boxes.view_mut());
        dev.for_each("pdacrt::split_nodes", n_nodes, |t, n| split_node(t, &nv, &tv, &cv, n));
    }

    /// `filter_triangles`, `filter_rays`: the status codes.
    fn filter(&self, ws: &mut Workspace, any_hit: bool) {
        let dev = &self.dev;
        let lv = &ws.cur;
        ws.tri_codes.resize(lv.tri_ids.len());
        {
            let (ids, nd, tv, cb, out) = (
                lv.tri_ids.view(),
                lv.tri_node.view(),
                self.tris.view(),
                ws.child_boxes.view(),
                ws.tri_codes.view_mut(),
            );
            dev.for_each("pdacrt::filter_triangles", ids.len(), |t, i| {
                filter_triangle(t, &ids, &nd, &tv, &cb, &out, i)
            });
        }
        ws.ray_codes.resize(lv.ray_ids.len());
        let (ids, nd, rv, kv, cb, out) = (
            lv.ray_ids.view(),
            lv.ray_node.view(),
            ws.rays.view(),
            ws.keys.view(),
            ws.child_boxes.view(),
            ws.ray_codes.view_mut(),
        );
        let grow = ws.grow;
        dev.for_each("pdacrt::filter_rays", ids.len(), |t, i| {
            filter_ray(t, &ids, &nd, &rv, &kv, &cb, any_hit, grow, &out, i)
        });
    }

    /// The segmented sort by status code, as a split: each node's elements are
    /// contiguous, so one exclusive scan of one-hot (L, B, R) vectors ranks every
    /// element within its node and code (a transform scan of their codes), and the same scan
    /// gives every node's counts (`count_codes`). The scatter then writes the order a
    /// stable segmented sort would give, without its radix passes.
    fn split_codes(&self, ws: &mut Workspace, n_nodes: usize) {
        let dev = &self.dev;
        let sides = [
            (true, &ws.ray_codes, &mut ws.ray_ranks, &mut ws.ray_counts, &mut ws.ray_base),
            (false, &ws.tri_codes, &mut ws.tri_ranks, &mut ws.tri_counts, &mut ws.tri_base),
        ];
        for (rays, codes, ranks, counts, base) in sides {
            ranks.resize(codes.len());
            simt::transform_exclusive_scan(dev, codes, ranks, one_hot, [0; 3], [0; 3], add3);
            counts.resize(4 * n_nodes);
            base.resize(n_nodes);
            let (nv, rv, cv, nc, bv) =
                (ws.cur.nodes.view(), ranks.view(), codes.view(), counts.view_mut(), base.view_mut());
            dev.for_each("pdacrt::count_codes", n_nodes, |t, k| count_node_codes(t, &nv, rays, &rv, &cv, &nc, &bv, k));
        }
    }

    /// `classify_children`, two scans and `emit_children`: every child's kind and
    /// place; sizes `ws.next` and the terminal buffers. Returns the terminal totals
    /// (nodes, ray references, triangle references).
    fn place_children(&self, ws: &mut Workspace, depth: u32) -> Triple {
        let dev = &self.dev;
        let n_children = 2 * ws.cur.nodes.len();
        for b in [&mut ws.inner, &mut ws.terminal, &mut ws.inner_scan, &mut ws.terminal_scan] {
            b.resize(n_children);
        }
        ws.children.resize(n_children);
        {
            let rule = LeafRule {
                leaf_rays: self.params.leaf_rays,
                leaf_tris: self.params.leaf_triangles,
                at_max_depth: depth + 1 >= self.params.max_depth,
            };
            let (nv, rc, tc) = (ws.cur.nodes.view(), ws.ray_counts.view(), ws.tri_counts.view());
            let (cv, iv, tv) = (ws.children.view_mut(), ws.inner.view_mut(), ws.terminal.view_mut());
            dev.for_each_in("pdacrt::classify_children", &["classify"], n_children, |t, c| {
                classify_child(t, &nv, &rc, &tc, rule, &cv, &iv, &tv, c)
            });
        }
        simt::exclusive_scan(dev, &ws.inner, &mut ws.inner_scan, [0; 3], [0; 3], add3);
        simt::exclusive_scan(dev, &ws.terminal, &mut ws.terminal_scan, [0; 3], [0; 3], add3);
        let [next_nodes, next_rays, next_tris] = scan_total(&ws.inner, &ws.inner_scan);
        let terminal = scan_total(&ws.terminal, &ws.terminal_scan);
        ws.next.nodes.resize(next_nodes as usize);
        ws.term_nodes.resize(terminal[0] as usize);
        {
            let (nv, cb, is, ts) =
                (ws.cur.nodes.view(), ws.child_boxes.view(), ws.inner_scan.view(), ws.terminal_scan.view());
            let (cv, nn, tn) = (ws.children.view_mut(), ws.next.nodes.view_mut(), ws.term_nodes.view_mut());
            dev.for_each("pdacrt::emit_children", n_children, |t, c| {
                emit_child(t, &nv, &cb, &is, &ts, &cv, &nn, &tn, c)
            });
        }
        ws.next.ray_ids.resize(next_rays as usize);
        ws.next.ray_node.resize(next_rays as usize);
        ws.next.tri_ids.resize(next_tris as usize);
        ws.next.tri_node.resize(next_tris as usize);
        ws.term_ray_ids.resize(terminal[1] as usize);
        ws.term_tri_ids.resize(terminal[2] as usize);
        terminal
    }

    /// `scatter_rays`, `scatter_triangles`: the next level's id arrays and the terminal
    /// buffer.
    fn scatter(&self, ws: &mut Workspace) {
        let dev = &self.dev;
        let cv = ws.children.view();
        let split = Split {
            ids: ws.cur.ray_ids.view(),
            node_of: ws.cur.ray_node.view(),
            codes: ws.ray_codes.view(),
            ranks: ws.ray_ranks.view(),
            base: ws.ray_base.view(),
            counts: ws.ray_counts.view(),
        };
        let dest = Destinations {
            next_ids: ws.next.ray_ids.view_mut(),
            next_node: ws.next.ray_node.view_mut(),
            terminal_ids: ws.term_ray_ids.view_mut(),
        };
        dev.for_each("pdacrt::scatter_rays", split.ids.len(), |t, i| scatter_ref(t, &split, &cv, true, &dest, i));
        let split = Split {
            ids: ws.cur.tri_ids.view(),
            node_of: ws.cur.tri_node.view(),
            codes: ws.tri_codes.view(),
            ranks: ws.tri_ranks.view(),
            base: ws.tri_base.view(),
            counts: ws.tri_counts.view(),
        };
        let dest = Destinations {
            next_ids: ws.next.tri_ids.view_mut(),
            next_node: ws.next.tri_node.view_mut(),
            terminal_ids: ws.term_tri_ids.view_mut(),
        };
        dev.for_each("pdacrt::scatter_triangles", split.ids.len(), |t, i| scatter_ref(t, &split, &cv, false, &dest, i));
    }

    /// `count_chunks`, a scan and `brute_force`: the terminal buffer, solved.
    fn solve_terminals(&self, ws: &mut Workspace, any_hit: bool) {
        let dev = &self.dev;
        let k = ws.term_nodes.len();
        let block = self.params.brute_force_block;
        ws.chunks.resize(k);
        ws.chunk_start.resize(k);
        {
            let (tv, cv) = (ws.term_nodes.view(), ws.chunks.view_mut());
            dev.for_each("pdacrt::count_chunks", k, |t, i| {
                t.store(&cv, i, t.load_field(&tv, i, |x| &x.ray_count).div_ceil(block))
            });
        }
        simt::exclusive_scan(dev, &ws.chunks, &mut ws.chunk_start, 0, 0, |a, b| a + b);
        let grid = ws.chunk_start.as_slice()[k - 1] + ws.chunks.as_slice()[k - 1];
        let args = BruteForceArgs {
            terminals: ws.term_nodes.view(),
            chunk_start: ws.chunk_start.view(),
            terminal_count: k,
            ray_ids: ws.term_ray_ids.view(),
            tri_ids: ws.term_tri_ids.view(),
            rays: ws.rays.view(),
            tris: self.tris.view(),
            keys: ws.keys.view_mut(),
            visits: self.params.inspect.then(|| ws.visits.view_mut()),
            tests: ws.tests.view_mut(),
            any_hit,
        };
        let cfg = LaunchConfig {
            grid,
            block,
            shared_bytes: BRUTE_FORCE_SHARED_BYTES,
            regions: &["tests"],
            registers: 0,
            code_bytes: 0,
        };
        dev.launch("pdacrt::brute_force", cfg, |blk| brute_force(blk, &args))
            .expect("brute-force launch shape is valid");
    }
}
