//! How a geodetic `.daa` state becomes a Euclidean one, the way DAIDALUS does it, so that the
//! two tools compare on the same numbers: a spherical Earth whose radius makes one nautical
//! mile one minute of arc, each aircraft's position projected orthographically onto the plane
//! tangent at the ownship (east, north; altitude minus the ownship's), and its velocity as the
//! projected displacement over 10 s along the great circle it starts on.
//!
//! (savsim's own scenes use WGS84, `geo`; at 40 nmi the two differ by metres, more than
//! DAIDALUS prints.)

use glam::DVec3;

use crate::daa::well_clear::NMI_M;

/// The sphere's radius: 1 nmi per minute of arc, metres.
pub const SPHERE_RADIUS_M: f64 = NMI_M * 60.0 * 180.0 / std::f64::consts::PI;

/// The time over which a velocity is projected, seconds.
const VELOCITY_STEP_S: f64 = 10.0;

/// The plane tangent to the sphere at a reference point.
#[derive(Debug, Clone, Copy)]
pub struct TangentPlane {
    east: DVec3,
    north: DVec3,
    alt_m: f64,
}

/// The unit vector of a latitude and longitude (radians).
fn unit(lat_rad: f64, lon_rad: f64) -> DVec3 {
    DVec3::new(
        lat_rad.cos() * lon_rad.cos(),
        lat_rad.cos() * lon_rad.sin(),
        lat_rad.sin(),
    )
}

impl TangentPlane {
    /// The plane at latitude, longitude (degrees) and altitude (metres).
    pub fn at(lat_deg: f64, lon_deg: f64, alt_m: f64) -> Self {
        let (lat, lon) = (lat_deg.to_radians(), lon_deg.to_radians());
        TangentPlane {
            east: DVec3::new(-lon.sin(), lon.cos(), 0.0),
            north: DVec3::new(-lat.sin() * lon.cos(), -lat.sin() * lon.sin(), lat.cos()),
            alt_m,
        }
    }

    /// A point's east, north and up (altitude above the reference's), metres.
    ///
    /// ```
    /// use savsim_core::daa::projection::{TangentPlane, SPHERE_RADIUS_M};
    /// let plane = TangentPlane::at(0.0, 0.0, 100.0);
    /// // One minute of arc north at the equator: sin(1') R north, 50 m below.
    /// let p = plane.project(1.0 / 60.0, 0.0, 50.0);
    /// let expect = (1.0f64 / 60.0).to_radians().sin() * SPHERE_RADIUS_M;
    /// assert!(p.x.abs() < 1e-9 && (p.y - expect).abs() < 1e-9 && (p.z + 50.0).abs() < 1e-12);
    /// ```
    pub fn project(&self, lat_deg: f64, lon_deg: f64, alt_m: f64) -> DVec3 {
        let p = unit(lat_deg.to_radians(), lon_deg.to_radians()) * SPHERE_RADIUS_M;
        DVec3::new(p.dot(self.east), p.dot(self.north), alt_m - self.alt_m)
    }

    /// A velocity (east, north, up, m/s) of an aircraft at latitude, longitude (degrees) and
    /// altitude (metres), in this plane: where 10 s along its great circle takes it, projected,
    /// less where it is, over 10 s.
    pub fn project_velocity(
        &self,
        lat_deg: f64,
        lon_deg: f64,
        alt_m: f64,
        v_enu_mps: DVec3,
    ) -> DVec3 {
        let (lat, lon) = (lat_deg.to_radians(), lon_deg.to_radians());
        let track = v_enu_mps.x.atan2(v_enu_mps.y);
        let angle = v_enu_mps.truncate().length() * VELOCITY_STEP_S / SPHERE_RADIUS_M;
        let lat2 = (lat.sin() * angle.cos() + lat.cos() * angle.sin() * track.cos())
            .clamp(-1.0, 1.0)
            .asin();
        let dlon =
            (track.sin() * angle.sin() * lat.cos()).atan2(angle.cos() - lat.sin() * lat2.sin());
        let here = self.project(lat_deg, lon_deg, alt_m);
        let there = self.project(
            lat2.to_degrees(),
            (lon + dlon).to_degrees(),
            alt_m + v_enu_mps.z * VELOCITY_STEP_S,
        );
        (there - here) / VELOCITY_STEP_S
    }
}
