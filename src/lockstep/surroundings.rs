//! What a vehicle savsim flies can run into, from the scene: the ground under it (terrain, or
//! the scene's ground plane) and the first obstacle along its motion (an exact ray against
//! every obstacle's shape: the contact layer's own fan).

use std::cell::RefCell;

use glam::DVec3;
use savsim_core::dynamics::Surroundings;

use crate::pipeline::{BodySource, MovingBodies, Pipeline, Rays};
use crate::scene::Scene;

/// A scene as seen from one home (NED from `home_enu_m`).
pub struct SceneSurroundings<'a> {
    scene: &'a Scene,
    /// A pipeline of the scene's exact shapes for the rays (a query needs its caches).
    pipeline: RefCell<&'a mut Pipeline>,
    home_enu_m: DVec3,
    own: BodySource,
}

impl<'a> SceneSurroundings<'a> {
    /// `scene` from `home_enu_m`, for the vehicle `own` (never its own obstacle), its rays cast
    /// with `pipeline`.
    pub fn new(
        scene: &'a Scene,
        pipeline: &'a mut Pipeline,
        home_enu_m: DVec3,
        own: BodySource,
    ) -> Self {
        SceneSurroundings {
            scene,
            pipeline: RefCell::new(pipeline),
            home_enu_m,
            own,
        }
    }

    fn enu_m(&self, ned_m: DVec3) -> DVec3 {
        self.home_enu_m + DVec3::new(ned_m.y, ned_m.x, -ned_m.z)
    }
}

impl Surroundings for SceneSurroundings<'_> {
    fn ground_down_m(&self, north_m: f64, east_m: f64) -> f64 {
        let at = self.enu_m(DVec3::new(north_m, east_m, 0.0));
        let ground_up_m = self.scene.ground_height_enu_m(at.x, at.y).unwrap_or(0.0);
        self.home_enu_m.z - ground_up_m
    }

    /// The ray from the centre along the motion: where it meets an obstacle (not the ground),
    /// the fraction of the way; the normal taken against the motion (the body stops dead
    /// against what it meets). The centre stops at the surface, whatever the radius: the
    /// vehicle's shape then overlaps the obstacle, and the contact layer reports the
    /// collision it decides.
    fn first_contact(
        &self,
        from_ned_m: DVec3,
        to_ned_m: DVec3,
        _radius_m: f64,
    ) -> Option<(f64, DVec3)> {
        let travel = to_ned_m - from_ned_m;
        let length_m = travel.length();
        if length_m.is_nan() || length_m <= 1e-9 {
            return None;
        }
        let dir_ned = travel / length_m;
        let dir_enu = DVec3::new(dir_ned.y, dir_ned.x, -dir_ned.z);
        let mut hit = [None];
        self.pipeline.borrow_mut().cast_exact_rays(
            self.scene,
            self.own,
            &MovingBodies::default(),
            Rays {
                origin_enu_m: self.enu_m(from_ned_m),
                dirs_enu: &[dir_enu],
                max_m: length_m,
            },
            &mut hit,
        );
        let distance_m = hit[0]?;
        // The ground (terrain included) is the ground's to answer: landing is resting on it.
        let at = self.enu_m(from_ned_m) + dir_enu * distance_m;
        let ground_up_m = self.scene.ground_height_enu_m(at.x, at.y).unwrap_or(0.0);
        if at.z <= ground_up_m + 0.05 {
            return None;
        }
        Some(((distance_m / length_m).clamp(0.0, 1.0), -dir_ned))
    }
}
