//! The collision core: octree, colliders, six rays, AHP threat, box <-> mesh swapping, contacts
//! and swept time of impact, per tick and per vehicle (Li et al. 2019, with savsim's changes in
//! ../shared/ALGORITHM.md and docs/threat-model.md).
//!
//! Two layers: the **contact layer** decides what was hit (exact shapes, swept between samples:
//! the truth savsim reports), the **sensing layer** models what the vehicle perceives (the
//! paper's node, rays, beta and box/mesh state) at a sensor rate. A mode swaps a stage, never
//! adds a branch to every stage.
//!
//! Pure and synchronous: [`crate::pipeline::Pipeline::step`] takes the scene and one vehicle's samples
//! and pushes [`events::Event`]s. No tokio, no rerun, no files, no clap or mavlink types here.
//!
//! - [`config`]: the modes and every threshold.
//! - [`bodies`]: identities (generational keys), poses, placed colliders.
//! - [`octree`]: the static scene's octree (the paper's nodes).
//! - [`broad_phase`]: the static broad phase (parry's `Bvh`): region queries and rays.
//! - [`shapes`]: the contact layer's exact shapes (cuboids, compounds, meshes).
//! - [`contact`]: exact f64-anchored queries (intersection, distance, sweep, ray).
//! - [`distance`]: distances through parry, with cuboid pairs repaired.
//! - [`ray_height_field`]: exact rays against terrain height fields.
//! - [`swept`]: the contact layer's `exact` strategy (shortcuts that prove, then sweeps).
//! - [`spans`]: every span of contact within an interval (part by part).
//! - [`moving`]: the moving bodies of a tick and their broad phase.
//! - [`mesh_worker`]: the thread that builds meshes off the tick path.
//! - [`meshes`]: the triangle meshes, built on demand, resident within a budget.
//! - [`contacts`]: the contact layer, one strategy per mode.
//! - [`sensing`]: the sensing layer (the paper's algorithm): node, activation, rays;
//!   [`swaps`]: its threat, collider swaps and residency.
//! - [`threat`]: AHP weights and beta.
//! - [`episodes`]: contacts and near misses into events.
//! - [`events`]: what is reported.
//! - [`fan`]: exact ray fans (what a range sensor measures; the closed-loop feed).
//! - [`approach`]: closest point of approach and NMAC between two tracks.

pub mod approach;
pub mod bodies;
pub mod broad_phase;
pub mod config;
pub mod contact;
pub mod contacts;
pub mod digest;
pub mod distance;
pub mod episodes;
pub mod events;
pub mod fan;
pub mod mesh_worker;
pub mod meshes;
pub mod moving;
pub mod octree;
pub mod ray_height_field;
pub mod sensing;
pub mod shapes;
pub mod spans;
pub mod swaps;
pub mod swept;
pub mod threat;

/// Which collider an obstacle currently has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ColliderKind {
    /// No collider: the obstacle is invisible to rays and contacts.
    None,
    /// The box enclosing the obstacle.
    Box,
    /// The obstacle's triangle mesh.
    Mesh,
}

impl ColliderKind {
    /// The name used in events and summaries.
    pub fn name(self) -> &'static str {
        match self {
            ColliderKind::None => "none",
            ColliderKind::Box => "box",
            ColliderKind::Mesh => "mesh",
        }
    }
}
