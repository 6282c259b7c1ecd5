//! Every rerun entity path savsim logs, spelled in one place (listed in docs/rerun.md).

/// The 3D world: scene ENU metres minus the viz offset, Z up.
pub const WORLD: &str = "world";
/// Static obstacles, one entity per kind: `world/obstacles/building`, ...
pub const OBSTACLES: &str = "world/obstacles";
/// The octree's leaves (static).
pub const OCTREE: &str = "world/octree";
/// Collision markers (all so far).
pub const COLLISIONS: &str = "world/events/collisions";
/// Near-miss markers (all so far).
pub const NEAR_MISSES: &str = "world/events/near_misses";
/// Metrics root.
pub const METRICS: &str = "metrics";

/// A vehicle's root: `world/vehicles/{sysid}`.
pub fn vehicle(system_id: u8) -> String {
    format!("world/vehicles/{system_id}")
}

/// The vehicle's body (Transform3D), with `model` and `axes` below it.
pub fn body(system_id: u8) -> String {
    format!("world/vehicles/{system_id}/body")
}

/// Something below a vehicle: `track`, `rays`, `rays/hits`, `node`.
pub fn vehicle_part(system_id: u8, part: &str) -> String {
    format!("world/vehicles/{system_id}/{part}")
}

/// The collider a vehicle's pipeline currently gives an obstacle.
pub fn collider(system_id: u8, obstacle_id: &str) -> String {
    format!(
        "world/vehicles/{system_id}/colliders/{}",
        sanitize(obstacle_id)
    )
}

/// A traffic aircraft or other moving obstacle.
pub fn traffic(id: &str) -> String {
    format!("world/traffic/{}", sanitize(id))
}

/// A per-vehicle scalar: `metrics/{sysid}/{name}`.
pub fn metric(system_id: u8, name: &str) -> String {
    format!("{METRICS}/{system_id}/{name}")
}

/// Beta of one obstacle for one vehicle.
pub fn beta(system_id: u8, obstacle_id: &str) -> String {
    format!("{METRICS}/{system_id}/beta/{}", sanitize(obstacle_id))
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
