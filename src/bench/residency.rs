//! The residency run: the first scene with every building as a loaded triangle mesh (its
//! blocks' tessellated facades, as a modelled city arrives), the whole flight set flown one
//! after the other through one `exact` pipeline under a mesh budget, and through the
//! reference. Resident meshes must stay within the budget and nothing may be missed.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::bench::compare::{collisions, compare};
use crate::bench::flights::Flight;
use crate::bench::fly::run_samples;
use crate::costs::percentiles_us;
use crate::pipeline::{CollisionConfig, Mode, Pipeline};
use crate::scene::geometry::{Geometry, GeometrySource};
use crate::scene::Scene;

/// What the residency run measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ResidencyRow {
    /// The scene the meshes came from.
    pub scene: String,
    /// Obstacles made meshes, and their triangles.
    pub mesh_obstacles: usize,
    /// Triangles of those meshes.
    pub mesh_triangles: usize,
    /// Every mesh built at once would hold this, bytes (estimate).
    pub all_meshes_bytes: usize,
    /// The budget, bytes.
    pub budget_bytes: usize,
    /// Most bytes the resident meshes held at once.
    pub peak_bytes: usize,
    /// Meshes built (rebuilds after eviction included).
    pub built: usize,
    /// Of those, built because a contact needed one not resident.
    pub built_on_contact: usize,
    /// Meshes evicted to stay within the budget.
    pub evicted: usize,
    /// Residency requests the budget had no room for.
    pub prefetch_refused: usize,
    /// Ticks flown.
    pub ticks: u64,
    /// Per-tick cost, median and 99th percentile, microseconds.
    pub cost_median_us: f64,
    /// Per-tick cost, 99th percentile, microseconds.
    pub cost_p99_us: f64,
    /// The reference's collisions.
    pub collisions: usize,
    /// Missed against the reference.
    pub missed: usize,
    /// False against the reference.
    pub false_collisions: usize,
}

/// `scene` with every block or box geometry of a static obstacle replaced by its triangles as a
/// loaded mesh (same indices, so the flight set generated for `scene` flies it as it is).
pub fn as_meshes(scene: &Scene) -> Scene {
    let mut out = scene.clone();
    let mut converted: Vec<Option<Arc<Geometry>>> = vec![None; scene.geometries.len()];
    for o in &mut out.obstacles {
        if !matches!(
            o.geometry.source,
            GeometrySource::Blocks { .. } | GeometrySource::Cuboid { .. }
        ) {
            continue;
        }
        let mesh = converted[o.geometry_index].get_or_insert_with(|| {
            let (vertices, indices) = o.geometry.triangles();
            Arc::new(Geometry::mesh(vertices, indices).expect("a block's triangles have area"))
        });
        o.geometry = mesh.clone();
        out.geometries[o.geometry_index] = mesh.clone();
    }
    out
}

/// Fly `flights` over `scene` made meshes, one after the other, through one `exact` pipeline
/// under `budget_mib` and through the reference.
pub fn run(
    scene: &Scene,
    flights: &[Flight],
    config: CollisionConfig,
    budget_mib: f64,
) -> ResidencyRow {
    let meshes = as_meshes(scene);
    let mesh_obstacles: Vec<&Geometry> = meshes
        .obstacles
        .iter()
        .filter(|o| matches!(o.geometry.source, GeometrySource::Mesh { .. }))
        .map(|o| o.geometry.as_ref())
        .collect();
    let mesh_triangles = mesh_obstacles.iter().map(|g| g.triangle_count()).sum();
    let all_meshes_bytes = mesh_obstacles
        .iter()
        .map(|g| {
            let v = match &g.source {
                GeometrySource::Mesh { vertices, .. } => vertices.len(),
                _ => 0,
            };
            crate::scene::geometry::trimesh_bytes(v, g.triangle_count())
        })
        .sum();
    let mut exact = Pipeline::new(
        &meshes,
        CollisionConfig {
            mode: Mode::Exact,
            mesh_budget_mib: budget_mib,
            ..config
        },
    );
    let mut reference = Pipeline::new(
        &meshes,
        CollisionConfig {
            mode: Mode::Reference,
            ..config
        },
    );
    let (mut tick_ns, mut missed, mut false_collisions, mut truth_count) = (Vec::new(), 0, 0, 0);
    for (k, f) in flights.iter().enumerate() {
        let vehicle = k as u16 + 1;
        let (costs, found) = run_samples(&mut exact, &meshes, vehicle, &f.samples, &f.traffic);
        let (_, truth) = run_samples(&mut reference, &meshes, vehicle, &f.samples, &f.traffic);
        tick_ns.extend(costs.tick_ns);
        let (truth, found) = (collisions(&truth), collisions(&found));
        let (m, fa, _, _) = compare(&truth, &found);
        truth_count += truth.len();
        missed += m;
        false_collisions += fa;
    }
    let (cost_median_us, cost_p99_us) = percentiles_us(&tick_ns);
    let m = &exact.meshes();
    ResidencyRow {
        scene: scene.name.clone(),
        mesh_obstacles: mesh_obstacles.len(),
        mesh_triangles,
        all_meshes_bytes,
        budget_bytes: m.budget(),
        peak_bytes: m.counts().peak_bytes,
        built: m.counts().built,
        built_on_contact: m.counts().built_on_contact,
        evicted: m.counts().evicted,
        prefetch_refused: m.counts().prefetch_refused,
        ticks: exact.totals().ticks,
        cost_median_us,
        cost_p99_us,
        collisions: truth_count,
        missed,
        false_collisions,
    }
}
