//! Every rerun entity path savsim logs, spelled in one place (listed in docs/rerun.md).

/// The 3D world: scene ENU metres minus the viz offset, Z up.
pub const WORLD: &str = "world";
/// Static obstacles, one entity per kind: `world/obstacles/building`, ...
pub const OBSTACLES: &str = "world/obstacles";
/// The octree's leaves (static; only with `--rerun-octree`).
pub const OCTREE: &str = "world/octree";
/// Collision markers (all so far), labelled.
pub const COLLISIONS: &str = "world/events/collisions";
/// The contact normal at each collision marker.
pub const COLLISION_NORMALS: &str = "world/events/collision_normals";
/// Near-miss markers (all so far).
pub const NEAR_MISSES: &str = "world/events/near_misses";
/// Loss-of-well-clear markers (all so far): where the vehicle was when it lost well clear.
pub const WELL_CLEAR: &str = "world/events/well_clear";
/// Vehicle `sysid`'s closest approach to body `track` over the run:
/// `world/events/closest_approaches/{sysid}/{track}`, and its NMAC volume below it (`nmac`).
pub fn closest_approach(system_id: u8, track: &str) -> String {
    format!(
        "world/events/closest_approaches/{system_id}/{}",
        sanitize(track)
    )
}

/// The well-clear volume around the vehicle where each loss of well clear happened.
pub const WELL_CLEAR_VOLUMES: &str = "world/events/well_clear/volumes";
/// Metrics root.
pub const METRICS: &str = "metrics";

/// What vehicles said (STATUSTEXTs, mode changes, COLLISION messages), as text logs.
pub const MESSAGES: &str = "messages";

/// What vehicle `sysid` said: `messages/{sysid}`.
pub fn messages(system_id: u8) -> String {
    format!("{MESSAGES}/{system_id}")
}

/// A vehicle's root: `world/vehicles/{sysid}`.
pub fn vehicle(system_id: u8) -> String {
    format!("world/vehicles/{system_id}")
}

/// The vehicle's body (Transform3D), with `model` and `axes` below it.
pub fn body(system_id: u8) -> String {
    format!("world/vehicles/{system_id}/body")
}

/// The chase frame (Transform3D: the vehicle's position and heading, no roll or pitch): the
/// origin of the vehicle's chase view.
pub fn chase(system_id: u8) -> String {
    format!("world/vehicles/{system_id}/chase")
}

/// One segment of a vehicle's track: `world/vehicles/{sysid}/track/{k}`.
pub fn track_segment(system_id: u8, k: u32) -> String {
    format!("world/vehicles/{system_id}/track/{k}")
}

/// Something below a vehicle: `rays`, `rays/hits`, `node`, `node/neighbours`, `feed`.
pub fn vehicle_part(system_id: u8, part: &str) -> String {
    format!("world/vehicles/{system_id}/{part}")
}

/// A modelled device on a vehicle (Transform3D: where it was and looked at its last reading;
/// `image` (a pinhole, `depth`, `class`) or `points` below it):
/// `world/vehicles/{sysid}/sensors/{device}`.
pub fn sensor(system_id: u8, device: &str) -> String {
    format!("world/vehicles/{system_id}/sensors/{}", sanitize(device))
}

/// A depth camera's pinhole, with `depth` and `class` below it:
/// `world/vehicles/{sysid}/sensors/{device}/image`.
pub fn sensor_image(system_id: u8, device: &str) -> String {
    format!("{}/image", sensor(system_id, device))
}

/// A vehicle's colliders of one group (`boxes`, `seen`, `moving`; see
/// `viz::colliders`): `world/vehicles/{sysid}/colliders/{group}`.
pub fn colliders(system_id: u8, group: &str) -> String {
    format!("world/vehicles/{system_id}/colliders/{group}")
}

/// One mesh collider: `world/vehicles/{sysid}/colliders/meshes/{obstacle}`.
pub fn mesh_collider(system_id: u8, obstacle_id: &str) -> String {
    format!(
        "world/vehicles/{system_id}/colliders/meshes/{}",
        sanitize(obstacle_id)
    )
}

/// A traffic aircraft or other moving obstacle.
pub fn traffic(id: &str) -> String {
    format!("world/traffic/{}", sanitize(id))
}

/// A tick's cost, µs: `metrics/cost_us/{sysid}`.
pub fn cost(system_id: u8) -> String {
    format!("{METRICS}/cost_us/{system_id}")
}

/// Active colliders of one kind (`box`, `mesh`): `metrics/colliders/{sysid}/{kind}`.
pub fn colliders_count(system_id: u8, kind: &str) -> String {
    format!("{METRICS}/colliders/{system_id}/{kind}")
}

/// Active triangles: `metrics/triangles/{sysid}`.
pub fn triangles(system_id: u8) -> String {
    format!("{METRICS}/triangles/{system_id}")
}

/// Beta of one obstacle for one vehicle: `metrics/beta/{sysid}/{obstacle}`.
pub fn beta(system_id: u8, obstacle_id: &str) -> String {
    format!("{METRICS}/beta/{system_id}/{}", sanitize(obstacle_id))
}

/// Keep ids to characters that need no escaping in an entity path part (`/` in terrain patch
/// ids stays a level of hierarchy).
pub fn sanitize(id: &str) -> String {
    id.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '/' {
                c
            } else {
                '_'
            }
        })
        .collect()
}
