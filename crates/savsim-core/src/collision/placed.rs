//! Colliders placed for a query: an obstacle's or the vehicle's shape (its box, a mesh, an
//! exact solid, a terrain field) with its pose, as the contact and sensing layers test it.

use std::sync::Arc;

use glam::{DQuat, DVec3, Vec3};
use parry3d::shape::{Cuboid, Shape, SharedShape, TriMesh};

use crate::collision::bodies::BodyPose;
use crate::collision::contact::queries::Placed;
use crate::scene::geometry::Geometry;

/// A collider's shape, owned or shared.
pub(crate) enum Holder {
    /// The enclosing box (exact for a cuboid geometry).
    Box(Cuboid),
    /// A triangle mesh (surfaces only).
    Mesh(Arc<TriMesh>),
    /// An exact solid made of parts (a union of blocks as a parry `Compound`).
    Solid(SharedShape),
    /// Terrain as a parry `HeightField`: a surface, whose inside is what lies under it.
    Field(SharedShape),
}

/// A shape with its placement.
pub(crate) struct Body {
    holder: Holder,
    position_enu_m: DVec3,
    rotation: DQuat,
    pivot_local_m: Vec3,
    /// The shape's frame in the body's frame (identity but for a height field, whose up is
    /// its y axis).
    local_rotation: DQuat,
}

impl Body {
    /// A body whose shape's frame is the geometry's frame, placed at `pose`.
    pub fn new(holder: Holder, pose: BodyPose) -> Body {
        Body {
            holder,
            position_enu_m: pose.position_enu_m,
            rotation: pose.enu_from_body,
            pivot_local_m: Vec3::ZERO,
            local_rotation: DQuat::IDENTITY,
        }
    }

    /// A terrain patch's height field (centred on the patch, y up), placed at `pose`.
    pub fn field(shape: SharedShape, geometry: &Geometry, pose: BodyPose) -> Body {
        let local_rotation = field_rotation();
        // The field's centre in the patch's frame: the middle of its footprint, at height 0.
        let c = geometry.local_aabb.center();
        let centre = Vec3::new(c.x, c.y, 0.0);
        Body {
            holder: Holder::Field(shape),
            position_enu_m: pose.position_enu_m + pose.enu_from_body * centre.as_dvec3(),
            rotation: pose.enu_from_body * local_rotation,
            pivot_local_m: (local_rotation.inverse() * -centre.as_dvec3()).as_vec3(),
            local_rotation,
        }
    }

    /// The geometry's enclosing box, placed at `pose`.
    pub fn boxed(geometry: &Geometry, pose: BodyPose) -> Body {
        let (cuboid, centre) = geometry.box_collider();
        Body {
            holder: Holder::Box(cuboid),
            position_enu_m: pose.position_enu_m + pose.enu_from_body * centre.as_dvec3(),
            rotation: pose.enu_from_body,
            pivot_local_m: -centre,
            local_rotation: DQuat::IDENTITY,
        }
    }

    /// True when the body is a surface mesh (it holds no inside).
    pub fn is_surface(&self) -> bool {
        matches!(self.holder, Holder::Mesh(_) | Holder::Field(_))
    }

    /// True when the body is a solid of several convex parts (a compound of blocks).
    pub fn is_compound(&self) -> bool {
        matches!(self.holder, Holder::Solid(_))
    }

    /// The body where it was placed.
    pub fn placed(&self) -> Placed<'_> {
        Placed {
            shape: match &self.holder {
                Holder::Box(c) => c as &dyn Shape,
                Holder::Mesh(m) => m.as_ref() as &dyn Shape,
                Holder::Solid(s) | Holder::Field(s) => s.as_ref(),
            },
            position_enu_m: self.position_enu_m,
            enu_from_shape: self.rotation,
            pivot_local_m: self.pivot_local_m,
        }
    }

    /// The same body moved so that its reference point has pose `pose`.
    pub fn at(&self, pose: BodyPose) -> Placed<'_> {
        let rotation = pose.enu_from_body * self.local_rotation;
        let offset = -(rotation * self.pivot_local_m.as_dvec3());
        self.placed().moved(pose.position_enu_m + offset, rotation)
    }
}

/// The rotation from a parry height field's frame (y up, rows along z) to a terrain patch's
/// (z up): +90 degrees about x, so that the field's y is up and its z is south.
pub(crate) fn field_rotation() -> DQuat {
    DQuat::from_rotation_x(std::f64::consts::FRAC_PI_2)
}

/// True when `point` is inside the obstacle's solid (see [`Geometry::contains_local_point`]).
pub(crate) fn inside_solid(geometry: &Geometry, pose: &BodyPose, point: DVec3) -> bool {
    let local = pose.enu_from_body.inverse() * (point - pose.position_enu_m);
    geometry.contains_local_point(local.as_vec3())
}
