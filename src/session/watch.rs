//! How far a vehicle's tick looks for moving bodies (its *watch*), as distances between the
//! vehicle's interval and a body's, both as boxes, not counting the models' size.
//!
//! - The *approach reach*: the contact layer's near-miss band, NMAC, the well-clear volume's
//!   DTHR + TTHR x closing speed, the separation minimum, and the feed's ADS-B radius,
//!   COLLISION horizon and sensor range. Closest approaches, well clear and separation are
//!   judged within it, by the bodies' positions.
//! - The *contact reach*: the near-miss band and `look_ahead_s` of closing speed, and how far
//!   the body moved; the contact layer's candidates are within it.
//! - The *sensing neighbourhood*, at a tick with a sensing frame: `1.5 x` the rays' reach (the
//!   sensor's region and its margin) or where a mesh is made (`mesh_within_m`), and the
//!   look-ahead of closing speed. The frame's own region (`Pipeline::sensing_region`) is
//!   checked besides (session::traffic); the neighbourhood is what the viewer and the modes
//!   that pose every body take around it.

use crate::collision::bodies::radius_m;
use crate::daa::well_clear::{Volume, FT_M};
use crate::feed::FeedConfig;
use crate::pipeline::CollisionConfig;
use crate::scene::Scene;

/// NMAC's horizontal threshold (500 ft), metres: the widest NMAC reaches.
const NMAC_M: f64 = 500.0 * FT_M;

/// What decides how far a vehicle's tick looks for moving bodies.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Watch {
    /// The pipeline's settings.
    pub collision: CollisionConfig,
    /// The well-clear volume judged, if any.
    pub volume: Option<Volume>,
    /// The separation minimum judged, if any, metres.
    pub separation_m: Option<f64>,
    /// The feed's ADS-B radius, COLLISION reach and horizon, and sensor range, when on.
    pub feed: Option<(f64, f64, f64, f64)>,
    /// The largest radius of any model a moving body or vehicle can have, metres.
    pub max_model_radius_m: f64,
    /// Whether every body taken is given to the pipeline with its whole state (the mode counts
    /// every collider or is the reference, the viewer draws them, or the feed reads them), not
    /// only those within the pipeline's own reach.
    pub pose_all: bool,
}

/// The largest radius of any model a moving body or a vehicle can have in `scene`, metres.
pub(crate) fn max_model_radius_m(scene: &Scene) -> f64 {
    let models = scene
        .vehicle_models
        .iter()
        .map(|(_, g)| *g)
        .chain(scene.kind_models.iter().map(|(_, g)| *g))
        .chain(scene.dynamic.iter().map(|d| d.geometry_index))
        .chain([0]);
    models.map(|g| model_radius_m(scene, g)).fold(0.0, f64::max)
}

impl Watch {
    /// The feed's part of the watch: its ADS-B radius, COLLISION reach and horizon, and
    /// sensor range.
    pub(crate) fn feed_of(feed: &FeedConfig) -> (f64, f64, f64, f64) {
        (
            feed.adsb_radius_m,
            feed.collision_horizontal_m,
            feed.collision_horizon_s,
            feed.range.max_m,
        )
    }

    /// How far apart (box to box) a vehicle at `own_mps` and a body at `body_mps` can be and
    /// still matter to closest approaches, NMAC, well clear, contacts or the feed, metres, not
    /// counting their models' size.
    pub(super) fn approach_range_m(&self, own_mps: f64, body_mps: f64) -> f64 {
        let c = &self.collision;
        let closing_mps = own_mps + body_mps;
        let contact = c.near_miss_m + closing_mps * c.look_ahead_s;
        let well_clear = self
            .volume
            .map_or(0.0, |v| v.dthr_m + v.tthr_s * closing_mps);
        let feed = self.feed.map_or(0.0, |(adsb, h, horizon, sensor)| {
            adsb.max(h + horizon * closing_mps).max(sensor)
        });
        // The boxes cover the interval's motion: within the minimum of them is all that can
        // come under it.
        let separation = self.separation_m.unwrap_or(0.0);
        contact
            .max(well_clear)
            .max(feed)
            .max(separation)
            .max(NMAC_M)
            + 1.0
    }

    /// How far apart (box to box) a body that moved `moved_m` in the interval can be and still
    /// be a contact layer's candidate: its near-miss band and `look_ahead_s` of closing speed,
    /// metres, not counting the models' size.
    pub(super) fn contact_range_m(&self, own_mps: f64, body_mps: f64, moved_m: f64) -> f64 {
        let c = &self.collision;
        c.near_miss_m + (own_mps + body_mps) * c.look_ahead_s + moved_m + 1.0
    }

    /// The sensing neighbourhood: `1.5 x` the rays' reach (or the look-ahead's) or where a mesh
    /// is made, and the look-ahead of closing speed, metres, not counting the models' size.
    pub(super) fn sensing_range_m(&self, own_mps: f64, body_mps: f64) -> f64 {
        let c = &self.collision;
        let sensed = 1.5 * c.ray_length_m.max(own_mps * c.look_ahead_s) + 10.0;
        let swaps = sensed.max(c.mesh_within_m) + (own_mps + body_mps) * c.look_ahead_s;
        swaps + 1.0
    }

    /// The tick's range: the approach reach, and at a tick with a sensing frame the sensing
    /// neighbourhood.
    pub(super) fn range_m(&self, sensing: bool, own_mps: f64, body_mps: f64) -> f64 {
        let approach = self.approach_range_m(own_mps, body_mps);
        if sensing {
            approach.max(self.sensing_range_m(own_mps, body_mps))
        } else {
            approach
        }
    }
}

/// The radius of geometry `index` (0 when the scene has none such), metres.
pub(super) fn model_radius_m(scene: &Scene, index: usize) -> f64 {
    scene.geometries.get(index).map_or(0.0, |g| radius_m(g))
}
