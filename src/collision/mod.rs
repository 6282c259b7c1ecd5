//! The collision core: octree, colliders, six rays, AHP threat, box <-> mesh swapping, contacts
//! and swept time of impact, per tick and per vehicle (Li et al. 2019, with savsim's changes in
//! ../shared/ALGORITHM.md and docs/threat-model.md).
//!
//! Pure and synchronous: [`pipeline::Pipeline::step`] takes the scene and one vehicle's samples
//! and pushes [`events::Event`]s. No tokio, no rerun, no files here.
//!
//! - [`octree`]: the static scene's octree.
//! - [`threat`]: AHP weights and beta.
//! - [`contact`]: exact f64-anchored queries (intersection, distance, sweep, ray).
//! - [`meshes`]: the lazily built, cached triangle meshes.
//! - [`pipeline`]: modes, per-vehicle collider state, the per-tick steps.
//! - [`events`]: what is reported.

pub mod contact;
pub mod events;
pub mod meshes;
pub mod octree;
pub mod pipeline;
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
