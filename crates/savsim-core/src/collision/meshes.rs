//! The mesh cache: a triangle-mesh collider is built the first time any obstacle using that
//! geometry needs one, then shared; beyond a memory budget the least recently used mesh that
//! no current tick needs is evicted (and rebuilt if it is needed again, which is counted).
//! Two ways in: [`MeshCache::get`] builds what a contact needs whatever the budget (correctness
//! first), [`MeshCache::prefetch`] makes a mesh resident ahead of need only if it fits, built
//! by a worker thread (`collision::mesh_worker`) and installed at the next sensing frame
//! ([`MeshCache::install_requested`]), so that the tick path rarely builds one.

use std::sync::Arc;
use std::time::{Duration, Instant};

use parry3d::shape::TriMesh;

use crate::collision::mesh_worker::{MeshWorker, Slot};
use crate::scene::geometry::{trimesh_bytes, Geometry};

/// What a mesh cache built, evicted and holds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MeshCounts {
    /// Meshes built so far (rebuilds after an eviction included).
    pub built: usize,
    /// Meshes built because a contact needed one that the sensing layer had not made
    /// resident: correctness first, counted.
    pub built_on_contact: usize,
    /// Meshes evicted to stay within the budget.
    pub evicted: usize,
    /// Triangles in the built meshes (over the run).
    pub triangles: usize,
    /// Estimated heap bytes of the meshes held now.
    pub bytes: usize,
    /// Most bytes held at once.
    pub peak_bytes: usize,
    /// Time spent building.
    pub build_time: Duration,
    /// Meshes a residency decision wanted but the budget had no room for.
    pub prefetch_refused: usize,
    /// Meshes the worker failed to build (a panic in the build): built on the caller's thread
    /// instead, counted.
    pub worker_failures: usize,
}

/// Built meshes by geometry index.
#[derive(Debug, Clone, Default)]
pub struct MeshCache {
    meshes: Vec<Option<(Arc<TriMesh>, usize)>>,
    /// The tick at which each built mesh was last used (same index as `meshes`).
    last_used: Vec<u64>,
    tick: u64,
    /// What it built, evicted and holds.
    counts: MeshCounts,
    /// Most bytes the meshes may hold (`usize::MAX`: no budget).
    budget_bytes: usize,
    /// Meshes asked of the worker and not installed yet: geometry index, where the result
    /// appears, the bytes reserved for it.
    requested: Vec<(usize, Arc<Slot>, usize)>,
    /// Bytes reserved for the requested meshes.
    reserved_bytes: usize,
    /// The worker thread, started on the first request of this cache or of any clone of it
    /// (clones share it: a batch's rows run on clones of one pipeline), `None` inside if it
    /// could not start (then prefetches build here).
    worker: Arc<std::sync::OnceLock<Option<MeshWorker>>>,
    /// Build prefetched meshes on the worker (default) or on the caller's thread.
    use_worker: bool,
}

/// [`trimesh_bytes`] of a geometry's mesh before it is built (a loaded mesh's vertices as
/// given; otherwise, as a closed grid has, half a vertex per triangle).
fn geometry_bytes(geometry: &Geometry) -> usize {
    let triangles = geometry.triangle_count();
    let vertices = match &geometry.source {
        crate::scene::geometry::GeometrySource::Mesh { vertices, .. } => vertices.len(),
        _ => triangles / 2 + 8,
    };
    trimesh_bytes(vertices, triangles)
}

impl MeshCache {
    /// What it built, evicted and holds so far.
    pub fn counts(&self) -> &MeshCounts {
        &self.counts
    }

    /// Count a mesh built because a contact needed one not made resident.
    pub(crate) fn count_built_on_contact(&mut self) {
        self.counts.built_on_contact += 1;
    }

    /// A cache for `geometries` geometries.
    pub fn new(geometries: usize) -> Self {
        Self {
            meshes: vec![None; geometries],
            last_used: vec![0; geometries],
            budget_bytes: usize::MAX,
            use_worker: true,
            ..Self::default()
        }
    }

    /// Build prefetched meshes on a worker thread (`true`, the default) or at once on the
    /// caller's thread. Either way, the same meshes are resident at the same decisions.
    pub fn set_worker(&mut self, on: bool) {
        self.use_worker = on;
    }

    /// True when geometry `index`'s mesh is built or asked for.
    pub fn held_or_requested(&self, index: usize) -> bool {
        self.built(index).is_some() || self.requested.iter().any(|r| r.0 == index)
    }

    /// Install every mesh asked of the worker, waiting for any still being built (called at
    /// each sensing frame, so that the same meshes are resident whatever the worker's speed).
    pub fn install_requested(&mut self) {
        for (index, slot, reserved) in std::mem::take(&mut self.requested) {
            self.reserved_bytes -= reserved;
            match slot.wait() {
                Some((mesh, took)) => {
                    self.counts.build_time += took;
                    self.install(index, mesh);
                }
                // Left unbuilt: the next `get` builds it on this thread.
                None => self.counts.worker_failures += 1,
            }
        }
    }

    fn install(&mut self, index: usize, mesh: Arc<TriMesh>) {
        if index >= self.meshes.len() {
            self.meshes.resize(index + 1, None);
            self.last_used.resize(index + 1, 0);
        }
        self.last_used[index] = self.tick;
        self.counts.built += 1;
        self.counts.triangles += mesh.num_triangles();
        let bytes = trimesh_bytes(mesh.vertices().len(), mesh.num_triangles());
        self.counts.bytes += bytes;
        self.counts.peak_bytes = self.counts.peak_bytes.max(self.counts.bytes);
        self.meshes[index] = Some((mesh, bytes));
    }

    /// Hold at most `bytes` of meshes (what [`prefetch`](Self::prefetch) fills and
    /// [`evict_to`](Self::evict_to) is called with).
    pub fn set_budget(&mut self, bytes: usize) {
        self.budget_bytes = bytes;
    }

    /// The budget, bytes.
    pub fn budget(&self) -> usize {
        self.budget_bytes
    }

    /// Make geometry `index`'s mesh resident ahead of need if it fits within the budget (after
    /// evicting meshes no tick has used since the last one). True when it is resident.
    ///
    /// ```
    /// use savsim_core::collision::meshes::MeshCache;
    /// use savsim_core::scene::geometry::Geometry;
    /// use glam::Vec3;
    /// let tower = Geometry::blocks(vec![(Vec3::ZERO, Vec3::splat(10.0))], 1.0).unwrap();
    /// let mut cache = MeshCache::new(1);
    /// cache.set_budget(1000);
    /// assert!(!cache.prefetch(0, &tower), "600 triangles do not fit in 1000 bytes");
    /// assert_eq!((cache.counts().built, cache.counts().prefetch_refused), (0, 1));
    /// cache.set_budget(1 << 20);
    /// assert!(cache.prefetch(0, &tower), "asked of the worker");
    /// cache.install_requested();
    /// assert!(cache.built(0).is_some());
    /// ```
    pub fn prefetch(&mut self, index: usize, geometry: &Geometry) -> bool {
        if self.held_or_requested(index) {
            self.touch(index);
            return true;
        }
        let need = geometry_bytes(geometry);
        let held = |c: &Self| c.counts.bytes.saturating_add(c.reserved_bytes);
        if held(self).saturating_add(need) > self.budget_bytes {
            let room = self
                .budget_bytes
                .saturating_sub(need)
                .saturating_sub(self.reserved_bytes);
            self.evict_to(room);
        }
        if held(self).saturating_add(need) > self.budget_bytes {
            self.counts.prefetch_refused += 1;
            return false;
        }
        let worker = self
            .use_worker
            .then(|| self.worker.get_or_init(MeshWorker::start).as_ref())
            .flatten();
        match worker.and_then(|w| w.request(geometry)) {
            Some(slot) => {
                self.requested.push((index, slot, need));
                self.reserved_bytes += need;
            }
            None => {
                self.get(index, geometry);
            }
        }
        true
    }

    /// Start a new tick: meshes used from now on are this tick's.
    pub fn next_tick(&mut self) {
        self.tick += 1;
    }

    /// Mark geometry `index`'s mesh as used in this tick (if it is held).
    pub fn touch(&mut self, index: usize) {
        if let Some(t) = self.last_used.get_mut(index) {
            *t = self.tick;
        }
    }

    /// The mesh of geometry `index`, built now if it is not held.
    pub fn get(&mut self, index: usize, geometry: &Geometry) -> Arc<TriMesh> {
        if index >= self.meshes.len() {
            self.meshes.resize(index + 1, None);
            self.last_used.resize(index + 1, 0);
        }
        self.last_used[index] = self.tick;
        if let Some((mesh, _)) = &self.meshes[index] {
            return mesh.clone();
        }
        // Asked of the worker already: that one, when it is done.
        if let Some(k) = self.requested.iter().position(|r| r.0 == index) {
            let (_, slot, reserved) = self.requested.remove(k);
            self.reserved_bytes -= reserved;
            if let Some((mesh, took)) = slot.wait() {
                self.counts.build_time += took;
                self.install(index, mesh.clone());
                return mesh;
            }
            self.counts.worker_failures += 1;
        }
        let started = Instant::now();
        let mesh = Arc::new(geometry.build_trimesh());
        self.counts.build_time += started.elapsed();
        self.install(index, mesh.clone());
        mesh
    }

    /// The mesh of geometry `index` if it is held.
    pub fn built(&self, index: usize) -> Option<&Arc<TriMesh>> {
        self.meshes
            .get(index)
            .and_then(Option::as_ref)
            .map(|(m, _)| m)
    }

    /// Evict least recently used meshes not used in the current tick until at most
    /// `budget_bytes` are held. Returns how many went.
    pub fn evict_to(&mut self, budget_bytes: usize) -> usize {
        let mut gone = 0;
        while self.counts.bytes > budget_bytes {
            let oldest = self
                .meshes
                .iter()
                .enumerate()
                .filter(|(i, m)| m.is_some() && self.last_used[*i] < self.tick)
                .min_by_key(|(i, _)| self.last_used[*i])
                .map(|(i, _)| i);
            let Some(i) = oldest else { break };
            if let Some((_, bytes)) = self.meshes[i].take() {
                self.counts.bytes -= bytes;
                self.counts.evicted += 1;
                gone += 1;
            }
        }
        gone
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A batch's rows fly clones of one pipeline: the first prefetch of any clone starts the
    /// one worker they all use.
    #[test]
    fn clones_of_a_cache_share_one_worker_started_once() {
        let tower = Geometry::blocks(
            vec![(glam::Vec3::ZERO, glam::Vec3::new(10.0, 10.0, 50.0))],
            1.0,
        )
        .unwrap();
        let original = MeshCache::new(2);
        let mut a = original.clone();
        let mut b = original.clone();
        assert!(original.worker.get().is_none());
        assert!(a.prefetch(0, &tower));
        assert!(b.prefetch(1, &tower));
        let started = original.worker.get().and_then(Option::as_ref);
        assert!(started.is_some(), "started through a clone, seen by all");
        assert!(Arc::ptr_eq(&a.worker, &b.worker));
        a.install_requested();
        b.install_requested();
        assert!(a.built(0).is_some() && b.built(1).is_some());
    }
}
