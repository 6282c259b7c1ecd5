//! The octree over the static scene (paper §3.1): built once, never updated.
//!
//! Nodes are cubes with bounds and depth; an object is stored in every leaf whose cube its box
//! touches. Queries take a reusable [`OctreeWorkspace`] and never allocate: the point query
//! gives the vehicle's node, the box query visits each object once (by id: the exact test is
//! the caller's closure, as in parry's `Bvh`).

use smallvec::SmallVec;

use crate::scene::Aabb64;
use glam::DVec3;

/// Index of a node.
pub type NodeId = u32;

#[derive(Debug, Clone)]
struct Node {
    centre: DVec3,
    half_m: f64,
    depth: u8,
    /// Index of the first of 8 children, or 0 for a leaf.
    first_child: u32,
    /// Range of this leaf's objects in `Octree::items`.
    items: (u32, u32),
}

/// How the octree is shaped. Defaults in the field docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OctreeConfig {
    /// Leaves are split until they are about this size (metres) or small enough in objects.
    /// Default 128 m. The depth follows from the scene size.
    pub leaf_target_m: f64,
    /// A node with at most this many objects is not split. Default 8.
    pub max_items_per_leaf: usize,
    /// Depth never exceeds this. Default 12.
    pub max_depth: u8,
}

impl Default for OctreeConfig {
    fn default() -> Self {
        Self {
            leaf_target_m: 128.0,
            max_items_per_leaf: 8,
            max_depth: 12,
        }
    }
}

/// Scratch space for queries: a traversal stack and per-object visit marks.
#[derive(Debug, Clone, Default)]
pub struct OctreeWorkspace {
    stack: SmallVec<[NodeId; 64]>,
    ray_stack: SmallVec<[(NodeId, f64); 64]>,
    marks: Vec<u32>,
    epoch: u32,
}

impl OctreeWorkspace {
    fn begin(&mut self, objects: usize) {
        if self.marks.len() < objects {
            self.marks.resize(objects, 0);
        }
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.marks.fill(0);
            self.epoch = 1;
        }
        self.stack.clear();
    }
}

/// An octree of object boxes.
#[derive(Debug, Clone)]
pub struct Octree {
    nodes: Vec<Node>,
    items: Vec<u32>,
    object_boxes: Vec<Aabb64>,
    depth: u8,
}

impl Octree {
    /// Build over `boxes` (object `i` has box `boxes[i]`).
    ///
    /// ```
    /// use savsim_core::collision::sensing::octree::{Octree, OctreeConfig, OctreeWorkspace};
    /// use savsim_core::scene::Aabb64;
    /// use glam::DVec3;
    /// let boxes: Vec<Aabb64> = (0..100)
    ///     .map(|i| Aabb64::around(DVec3::new(i as f64 * 50.0, 0.0, 10.0), DVec3::splat(5.0)))
    ///     .collect();
    /// let tree = Octree::build(&boxes, OctreeConfig::default());
    /// let mut ws = OctreeWorkspace::default();
    /// let mut hits = Vec::new();
    /// tree.query_aabb(&Aabb64::around(DVec3::new(100.0, 0.0, 10.0), DVec3::splat(60.0)), &mut ws, |i| hits.push(i));
    /// hits.sort();
    /// assert_eq!(hits, vec![1, 2, 3]);
    /// assert!(tree.leaf_at(DVec3::new(100.0, 0.0, 10.0)).is_some());
    /// ```
    pub fn build(boxes: &[Aabb64], config: OctreeConfig) -> Self {
        let bounds = boxes.iter().fold(Aabb64::EMPTY, |b, o| b.union(*o));
        let (centre, half_m) = if boxes.is_empty() {
            (DVec3::ZERO, 1.0)
        } else {
            let half = (bounds.max - bounds.min).max_element() * 0.5 * 1.001 + 1e-3;
            (bounds.centre(), half)
        };
        let wanted = ((2.0 * half_m) / config.leaf_target_m.max(1e-3))
            .log2()
            .ceil();
        let depth = (wanted.max(0.0) as u8).min(config.max_depth);
        let mut tree = Octree {
            nodes: vec![Node {
                centre,
                half_m,
                depth: 0,
                first_child: 0,
                items: (0, 0),
            }],
            items: Vec::new(),
            object_boxes: boxes.to_vec(),
            depth: 0,
        };
        let all: Vec<u32> = (0..boxes.len() as u32).collect();
        tree.split(0, all, depth, config.max_items_per_leaf);
        tree
    }

    fn split(&mut self, node: usize, objects: Vec<u32>, max_depth: u8, max_items: usize) {
        let (centre, half_m, depth) = {
            let n = &self.nodes[node];
            (n.centre, n.half_m, n.depth)
        };
        if depth >= max_depth || objects.len() <= max_items {
            let start = self.items.len() as u32;
            self.items.extend_from_slice(&objects);
            self.nodes[node].items = (start, self.items.len() as u32);
            self.depth = self.depth.max(depth);
            return;
        }
        let first = self.nodes.len();
        self.nodes[node].first_child = first as u32;
        let child_half = half_m * 0.5;
        for octant in 0..8 {
            let offset = DVec3::new(
                if octant & 1 == 0 { -1.0 } else { 1.0 },
                if octant & 2 == 0 { -1.0 } else { 1.0 },
                if octant & 4 == 0 { -1.0 } else { 1.0 },
            ) * child_half;
            self.nodes.push(Node {
                centre: centre + offset,
                half_m: child_half,
                depth: depth + 1,
                first_child: 0,
                items: (0, 0),
            });
        }
        for octant in 0..8 {
            let child = first + octant;
            let cube = self.node_aabb(child as NodeId);
            let inside: Vec<u32> = objects
                .iter()
                .copied()
                .filter(|&o| self.object_boxes[o as usize].intersects(&cube))
                .collect();
            self.split(child, inside, max_depth, max_items);
        }
    }

    /// The cube of a node.
    pub fn node_aabb(&self, node: NodeId) -> Aabb64 {
        let n = &self.nodes[node as usize];
        Aabb64::around(n.centre, DVec3::splat(n.half_m))
    }

    /// Depth of a node (root 0).
    pub fn node_depth(&self, node: NodeId) -> u8 {
        self.nodes[node as usize].depth
    }

    /// The deepest leaf depth.
    pub fn depth(&self) -> u8 {
        self.depth
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The leaf containing `point`, or `None` outside the tree.
    pub fn leaf_at(&self, point: DVec3) -> Option<NodeId> {
        if !self.node_aabb(0).contains(point) {
            return None;
        }
        let mut id = 0usize;
        loop {
            let n = &self.nodes[id];
            if n.first_child == 0 {
                return Some(id as NodeId);
            }
            let octant = usize::from(point.x >= n.centre.x)
                | usize::from(point.y >= n.centre.y) << 1
                | usize::from(point.z >= n.centre.z) << 2;
            id = n.first_child as usize + octant;
        }
    }

    /// The objects stored in a leaf (empty for inner nodes).
    pub fn leaf_items(&self, node: NodeId) -> &[u32] {
        let (a, b) = self.nodes[node as usize].items;
        &self.items[a as usize..b as usize]
    }

    /// Every leaf, with its cube and object count (for drawing).
    pub fn leaves(&self) -> impl Iterator<Item = (NodeId, Aabb64, usize)> + '_ {
        self.nodes
            .iter()
            .enumerate()
            .filter(|(_, n)| n.first_child == 0)
            .map(|(i, n)| {
                (
                    i as NodeId,
                    Aabb64::around(n.centre, DVec3::splat(n.half_m)),
                    (n.items.1 - n.items.0) as usize,
                )
            })
    }

    /// Call `visit` once for every object whose box intersects `query`.
    pub fn query_aabb(&self, query: &Aabb64, ws: &mut OctreeWorkspace, visit: impl FnMut(u32)) {
        self.traverse(ws, |b| b.intersects(query), visit);
    }

    /// The nearest hit of a ray: objects are offered to `hit` nearest box first (front to back)
    /// with the distance to beat, and nodes and boxes beyond the best hit so far are skipped.
    /// `hit(object, limit_m)` returns the exact distance if the object is hit closer than
    /// `limit_m`. Returns the object and distance of the nearest hit.
    ///
    /// ```
    /// use savsim_core::collision::sensing::octree::{Octree, OctreeConfig, OctreeWorkspace};
    /// use savsim_core::scene::Aabb64;
    /// use glam::DVec3;
    /// let boxes: Vec<Aabb64> = (0..100)
    ///     .map(|i| Aabb64::around(DVec3::new(i as f64 * 50.0, 0.0, 0.0), DVec3::splat(5.0)))
    ///     .collect();
    /// let tree = Octree::build(&boxes, OctreeConfig::default());
    /// let mut ws = OctreeWorkspace::default();
    /// let mut offered = 0;
    /// let exact = |i: u32, limit: f64| {
    ///     let t = boxes[i as usize].min.x - 1000.0;
    ///     (t >= 0.0 && t < limit).then_some(t)
    /// };
    /// let best = tree.cast_ray(DVec3::new(1000.0, 0.0, 0.0), DVec3::X, 500.0, &mut ws, |i, limit| {
    ///     offered += 1;
    ///     exact(i, limit)
    /// });
    /// assert_eq!(best, Some((21, 45.0)));
    /// assert!(offered < 3, "boxes beyond the first hit are not offered");
    /// ```
    pub fn cast_ray(
        &self,
        origin: DVec3,
        dir: DVec3,
        max_m: f64,
        ws: &mut OctreeWorkspace,
        mut hit: impl FnMut(u32, f64) -> Option<f64>,
    ) -> Option<(u32, f64)> {
        ws.begin(self.object_boxes.len());
        let mut best: Option<(u32, f64)> = None;
        let limit = |best: Option<(u32, f64)>| best.map_or(max_m, |b| b.1);
        let t0 = self.node_aabb(0).ray_entry(origin, dir, max_m)?;
        ws.ray_stack.clear();
        ws.ray_stack.push((0, t0));
        while let Some((id, entry)) = ws.ray_stack.pop() {
            if entry > limit(best) {
                continue;
            }
            let n = &self.nodes[id as usize];
            if n.first_child != 0 {
                // Children nearest last, so that they are popped first.
                let mut children: SmallVec<[(NodeId, f64); 8]> = SmallVec::new();
                for c in n.first_child..n.first_child + 8 {
                    if let Some(t) = self.node_aabb(c).ray_entry(origin, dir, limit(best)) {
                        children.push((c, t));
                    }
                }
                children.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
                ws.ray_stack.extend(children);
                continue;
            }
            for &o in &self.items[n.items.0 as usize..n.items.1 as usize] {
                let mark = &mut ws.marks[o as usize];
                if *mark == ws.epoch {
                    continue;
                }
                *mark = ws.epoch;
                let l = limit(best);
                if self.object_boxes[o as usize]
                    .ray_entry(origin, dir, l)
                    .is_some()
                {
                    if let Some(d) = hit(o, l).filter(|&d| d < l) {
                        best = Some((o, d));
                    }
                }
            }
        }
        best
    }

    /// Visit once each object whose box passes `test`, descending only into nodes whose cube
    /// passes it.
    fn traverse(
        &self,
        ws: &mut OctreeWorkspace,
        test: impl Fn(&Aabb64) -> bool,
        mut visit: impl FnMut(u32),
    ) {
        ws.begin(self.object_boxes.len());
        ws.stack.push(0);
        while let Some(id) = ws.stack.pop() {
            if !test(&self.node_aabb(id)) {
                continue;
            }
            let n = &self.nodes[id as usize];
            if n.first_child != 0 {
                ws.stack.extend((0..8).map(|o| n.first_child + o));
                continue;
            }
            for &o in &self.items[n.items.0 as usize..n.items.1 as usize] {
                let mark = &mut ws.marks[o as usize];
                if *mark != ws.epoch && test(&self.object_boxes[o as usize]) {
                    *mark = ws.epoch;
                    visit(o);
                }
            }
        }
    }

    /// Number of objects indexed.
    pub fn object_count(&self) -> usize {
        self.object_boxes.len()
    }

    /// Heap bytes held (nodes, item lists, object boxes).
    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>()
            + self.items.capacity() * 4
            + self.object_boxes.capacity() * std::mem::size_of::<Aabb64>()
    }
}
