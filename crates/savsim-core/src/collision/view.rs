//! What a stage of one tick looks at: the world (the scene, the moving bodies, the static
//! broad phase, the exact shapes) and each obstacle as it stands at the tick, static or moving.

use crate::collision::bodies::{BodyPose, BodySource, DynamicBody, ObstacleRef};
use crate::collision::moving::MovingBodies;
use crate::scene::geometry::Geometry;
use crate::scene::{Aabb64, Kind, Scene};

/// The world a stage looks at in one tick.
pub(crate) struct World<'a> {
    pub scene: &'a Scene,
    /// The moving bodies; the ticking vehicle's own body, if listed, is skipped.
    pub dynamic: &'a MovingBodies,
    /// The ticking vehicle as a moving body.
    pub own: BodySource,
    pub octree: &'a crate::collision::sensing::octree::Octree,
    /// The static broad phase (region queries and rays).
    pub statics: &'a crate::collision::broad_phase::StaticBroadPhase,
    pub shapes: &'a crate::collision::contact::shapes::ExactShapes,
}

impl World<'_> {
    /// Call `visit(index, body)` for every moving body but the ticking vehicle's own that may
    /// come within `lead_s` seconds of its speed of `region` in this interval.
    pub fn moving_near(
        &self,
        region: &Aabb64,
        lead_s: f64,
        mut visit: impl FnMut(usize, &DynamicBody),
    ) {
        let own = self.own;
        self.dynamic.near(self.scene, region, lead_s, |i, d| {
            if d.key.source != own {
                visit(i, d)
            }
        });
    }
}

/// Everything a stage needs to know about an obstacle at this tick.
pub(crate) struct ObstacleView<'s> {
    pub geometry: &'s Geometry,
    pub geometry_index: usize,
    pub kind: Kind,
    pub threat: f64,
    pub speed_mps: f64,
    pub previous: BodyPose,
    pub current: BodyPose,
    pub aabb_enu_m: Aabb64,
    pub id: &'s str,
}

/// The obstacle `o` at this tick; `None` for a moving body that is not in `dynamic` (its track
/// ended): state that names it is stale.
pub(crate) fn view<'s>(
    scene: &'s Scene,
    dynamic: &'s MovingBodies,
    o: ObstacleRef,
) -> Option<ObstacleView<'s>> {
    match o {
        ObstacleRef::Static(i) => {
            let s = scene.obstacles.get(i as usize)?;
            let pose = BodyPose {
                position_enu_m: s.placement.position_enu_m,
                enu_from_body: s.placement.enu_from_local,
            };
            Some(ObstacleView {
                geometry: &s.geometry,
                geometry_index: s.geometry_index,
                kind: s.kind,
                threat: s.threat,
                speed_mps: 0.0,
                previous: pose,
                current: pose,
                aabb_enu_m: s.aabb_enu_m,
                id: &s.id,
            })
        }
        ObstacleRef::Dynamic(key) => view_dynamic(scene, dynamic, dynamic.find(scene, key)?),
    }
}

/// Moving body `i` of `dynamic` at this tick (`None` for a model the scene does not have).
pub(crate) fn view_dynamic<'s>(
    scene: &'s Scene,
    dynamic: &'s MovingBodies,
    i: usize,
) -> Option<ObstacleView<'s>> {
    let d = dynamic.get(i);
    let g = scene.geometries.get(d.geometry_index)?;
    Some(ObstacleView {
        geometry: g,
        geometry_index: d.geometry_index,
        kind: d.kind,
        threat: d.threat,
        speed_mps: d.speed_mps,
        previous: d.previous,
        current: d.current,
        aabb_enu_m: dynamic.aabb(scene, i),
        id: &d.id,
    })
}
