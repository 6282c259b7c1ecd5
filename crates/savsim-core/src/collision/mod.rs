//! The collision core: octree, colliders, six rays, AHP threat, box <-> mesh swapping, contacts
//! and swept time of impact, per tick and per vehicle (Li et al. 2019, with savsim's changes in
//! docs/threat-model.md).
//!
//! Two layers, each in its own room: the **contact layer** ([`contact`]) decides what was hit
//! (exact shapes, swept between samples: the truth savsim reports), the **sensing layer**
//! ([`sensing`]) models what the vehicle perceives (the paper's node, rays, beta and box/mesh
//! state) at a sensor rate. What both use lies beside them. A mode swaps a stage, never adds a
//! branch to every stage.
//!
//! Pure and synchronous: [`crate::pipeline::Pipeline::step`] takes the scene and one vehicle's samples
//! and pushes [`events::Event`]s. No tokio, no rerun, no files, no clap or mavlink types here.
//!
//! - [`config`]: the modes and every threshold.
//! - [`bodies`]: identities (generational keys) and poses.
//! - [`placed`]: colliders placed for a query (a shape and its pose).
//! - [`view`]: what a stage of a tick looks at: the world and each obstacle at the tick.
//! - [`contact`]: the contact layer, one strategy per mode: its exact queries, shapes,
//!   distances, sweeps and spans.
//! - [`sensing`]: the sensing layer (the paper's algorithm): the octree, node, activation,
//!   rays, the AHP threat, collider swaps and residency.
//! - [`broad_phase`]: the static broad phase (parry's `Bvh`): region queries and rays.
//! - [`moving`]: the moving bodies of a tick and their broad phase.
//! - [`mesh_worker`]: the thread that builds meshes off the tick path.
//! - [`meshes`]: the triangle meshes, built on demand, resident within a budget.
//! - [`episodes`]: contacts and near misses into events.
//! - [`events`]: what is reported; [`digest`]: what a run's events add up to.
//! - [`fan`]: exact ray fans (what a range sensor measures; the closed-loop feed).
//!
//! Closest approach, NMAC and well clear between aircraft are detect and avoid's:
//! `crate::daa::approach`.

pub mod bodies;
pub mod broad_phase;
pub mod config;
pub mod contact;
pub mod digest;
pub mod episodes;
pub mod events;
pub mod fan;
pub mod mesh_worker;
pub mod meshes;
pub mod moving;
pub mod placed;
pub mod sensing;
pub mod view;

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
