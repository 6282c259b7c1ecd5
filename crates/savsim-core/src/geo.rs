//! WGS84 geodesy: geodetic <-> ECEF <-> a local East-North-Up tangent plane, all in `f64`.
//!
//! Owns the only place where latitude and longitude become metres. Exact transforms only: the
//! ellipsoid is WGS84, geodetic -> ECEF is the closed form, ECEF -> geodetic is Vermeille's
//! (2011) exact solution, and the tangent plane is a rotation of ECEF about the scene origin, so
//! a point 1000 km away or beyond the antimeridian lands where it really is, not where a
//! flat-earth approximation would put it. Must not import tokio, rerun or anything doing I/O.
//!
//! Heights: savsim feeds MAVLink's `alt` (metres above mean sea level) and scene altitudes
//! (the same reference) in as ellipsoidal heights. Because both sides use the same reference,
//! the geoid separation (tens of metres, nearly constant across a scene) cancels in the local
//! frame; see docs/frames-and-units.md for the residual.

use glam::{DMat3, DVec3};

/// WGS84 semi-major axis, metres.
pub const WGS84_A_M: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// WGS84 first eccentricity squared.
pub const WGS84_E2: f64 = WGS84_F * (2.0 - WGS84_F);

/// A WGS84 geodetic position.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Geodetic {
    /// Latitude, degrees, positive north, in [-90, 90].
    pub lat_deg: f64,
    /// Longitude, degrees, positive east (any value; wrapped by the trigonometry).
    pub lon_deg: f64,
    /// Height, metres (savsim passes AMSL here: see the module doc).
    pub alt_m: f64,
}

impl Geodetic {
    /// A new geodetic position.
    pub const fn new(lat_deg: f64, lon_deg: f64, alt_m: f64) -> Self {
        Self {
            lat_deg,
            lon_deg,
            alt_m,
        }
    }

    /// True when every field is finite and the latitude is within [-90, 90].
    ///
    /// ```
    /// use savsim_core::geo::Geodetic;
    /// assert!(Geodetic::new(-35.36, 149.16, 584.0).is_valid());
    /// assert!(!Geodetic::new(91.0, 0.0, 0.0).is_valid());
    /// assert!(!Geodetic::new(f64::NAN, 0.0, 0.0).is_valid());
    /// ```
    pub fn is_valid(&self) -> bool {
        self.lat_deg.is_finite()
            && self.lon_deg.is_finite()
            && self.alt_m.is_finite()
            && (-90.0..=90.0).contains(&self.lat_deg)
    }

    /// Earth-centred, earth-fixed coordinates, metres.
    ///
    /// ```
    /// use savsim_core::geo::{Geodetic, WGS84_A_M};
    /// let p = Geodetic::new(0.0, 0.0, 0.0).to_ecef_m();
    /// assert!((p.x - WGS84_A_M).abs() < 1e-9 && p.y.abs() < 1e-9 && p.z.abs() < 1e-9);
    /// ```
    pub fn to_ecef_m(&self) -> DVec3 {
        let (sin_lat, cos_lat) = self.lat_deg.to_radians().sin_cos();
        let (sin_lon, cos_lon) = self.lon_deg.to_radians().sin_cos();
        let prime_vertical_radius_m = WGS84_A_M / (1.0 - WGS84_E2 * sin_lat * sin_lat).sqrt();
        let r_m = (prime_vertical_radius_m + self.alt_m) * cos_lat;
        DVec3::new(
            r_m * cos_lon,
            r_m * sin_lon,
            (prime_vertical_radius_m * (1.0 - WGS84_E2) + self.alt_m) * sin_lat,
        )
    }

    /// The geodetic position of an ECEF point (Vermeille 2011, exact, valid everywhere outside
    /// a small region around the earth's centre).
    ///
    /// ```
    /// use savsim_core::geo::Geodetic;
    /// let g = Geodetic::new(44.2708, -71.3033, 1916.6);
    /// let back = Geodetic::from_ecef_m(g.to_ecef_m());
    /// assert!((back.lat_deg - g.lat_deg).abs() < 1e-11);
    /// assert!((back.lon_deg - g.lon_deg).abs() < 1e-11);
    /// assert!((back.alt_m - g.alt_m).abs() < 1e-6);
    /// ```
    pub fn from_ecef_m(ecef_m: DVec3) -> Self {
        let a2 = WGS84_A_M * WGS84_A_M;
        let e4 = WGS84_E2 * WGS84_E2;
        let p = (ecef_m.x * ecef_m.x + ecef_m.y * ecef_m.y) / a2;
        let q = (1.0 - WGS84_E2) / a2 * ecef_m.z * ecef_m.z;
        let r = (p + q - e4) / 6.0;
        let s = e4 * p * q / (4.0 * r * r * r);
        let t = (1.0 + s + (s * (2.0 + s)).sqrt()).cbrt();
        let u = r * (1.0 + t + 1.0 / t);
        let v = (u * u + e4 * q).sqrt();
        let w = WGS84_E2 * (u + v - q) / (2.0 * v);
        let k = (u + v + w * w).sqrt() - w;
        let horizontal_m = (ecef_m.x * ecef_m.x + ecef_m.y * ecef_m.y).sqrt();
        let d = k * horizontal_m / (k + WGS84_E2);
        let hyp = (d * d + ecef_m.z * ecef_m.z).sqrt();
        let lat_rad = 2.0 * ecef_m.z.atan2(d + hyp);
        let lon_rad = ecef_m.y.atan2(ecef_m.x);
        let alt_m = (k + WGS84_E2 - 1.0) / k * hyp;
        Self::new(lat_rad.to_degrees(), lon_rad.to_degrees(), alt_m)
    }
}

/// A local East-North-Up tangent plane at a geodetic origin.
///
/// `position_enu_m` values are metres east, north and up of the origin, measured along the
/// plane's axes (not along the ground): the exact rotation of the ECEF offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalTangentPlane {
    origin: Geodetic,
    origin_ecef_m: DVec3,
    /// Rows are the east, north and up unit vectors in ECEF.
    enu_from_ecef: DMat3,
}

impl LocalTangentPlane {
    /// The tangent plane at `origin`.
    pub fn new(origin: Geodetic) -> Self {
        let (sin_lat, cos_lat) = origin.lat_deg.to_radians().sin_cos();
        let (sin_lon, cos_lon) = origin.lon_deg.to_radians().sin_cos();
        let east = DVec3::new(-sin_lon, cos_lon, 0.0);
        let north = DVec3::new(-sin_lat * cos_lon, -sin_lat * sin_lon, cos_lat);
        let up = DVec3::new(cos_lat * cos_lon, cos_lat * sin_lon, sin_lat);
        Self {
            origin,
            origin_ecef_m: origin.to_ecef_m(),
            enu_from_ecef: DMat3::from_cols(east, north, up).transpose(),
        }
    }

    /// The geodetic origin of the plane.
    pub fn origin(&self) -> Geodetic {
        self.origin
    }

    /// Local ENU metres of a geodetic position.
    ///
    /// ```
    /// use savsim_core::geo::{Geodetic, LocalTangentPlane};
    /// let origin = Geodetic::new(-35.363261, 149.165230, 584.0);
    /// let plane = LocalTangentPlane::new(origin);
    /// let p = plane.enu_m_from_geodetic(&Geodetic::new(-35.363261, 149.165230, 634.0));
    /// assert!(p.x.abs() < 1e-6 && p.y.abs() < 1e-6 && (p.z - 50.0).abs() < 1e-6);
    /// ```
    pub fn enu_m_from_geodetic(&self, position: &Geodetic) -> DVec3 {
        self.enu_m_from_ecef_m(position.to_ecef_m())
    }

    /// Local ENU metres of an ECEF position.
    pub fn enu_m_from_ecef_m(&self, ecef_m: DVec3) -> DVec3 {
        self.enu_from_ecef * (ecef_m - self.origin_ecef_m)
    }

    /// The geodetic position of a local ENU point.
    pub fn geodetic_from_enu_m(&self, position_enu_m: DVec3) -> Geodetic {
        Geodetic::from_ecef_m(self.ecef_m_from_enu_m(position_enu_m))
    }

    /// ECEF metres of a local ENU point.
    pub fn ecef_m_from_enu_m(&self, position_enu_m: DVec3) -> DVec3 {
        self.origin_ecef_m + self.enu_from_ecef.transpose() * position_enu_m
    }

    /// A vector given in the local North-East-Down frame *at `position`* expressed in this
    /// plane's ENU axes. Away from the origin the local vertical tilts with the earth's
    /// curvature; this rotation accounts for it (at 1000 km the tilt is about 9 degrees).
    pub fn enu_vector_from_ned_at(&self, position: &Geodetic, vector_ned: DVec3) -> DVec3 {
        let local = LocalTangentPlane::new(*position);
        let vector_enu_local = DVec3::new(vector_ned.y, vector_ned.x, -vector_ned.z);
        let vector_ecef = local.enu_from_ecef.transpose() * vector_enu_local;
        self.enu_from_ecef * vector_ecef
    }

    /// The rotation taking vectors in the local ENU axes at `position` into this plane's ENU axes.
    pub fn plane_enu_from_local_enu_at(&self, position: &Geodetic) -> DMat3 {
        let local = LocalTangentPlane::new(*position);
        self.enu_from_ecef * local.enu_from_ecef.transpose()
    }

    /// The local vertical (up) at `position`, in this plane's ENU axes.
    pub fn up_at(&self, position: &Geodetic) -> DVec3 {
        self.plane_enu_from_local_enu_at(position) * DVec3::Z
    }

    /// A vector given in this plane's ENU axes, in the local North-East-Down frame at
    /// `position` (the inverse of [`Self::enu_vector_from_ned_at`]).
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::geo::{Geodetic, LocalTangentPlane};
    /// let plane = LocalTangentPlane::new(Geodetic::new(47.0, 8.0, 500.0));
    /// let far = Geodetic::new(47.0, 8.2, 500.0); // 15 km east: north there is turned
    /// let ned = DVec3::new(3.0, -4.0, 1.5);
    /// let back = plane.ned_vector_at(&far, plane.enu_vector_from_ned_at(&far, ned));
    /// assert!((back - ned).length() < 1e-12);
    /// ```
    pub fn ned_vector_at(&self, position: &Geodetic, vector_enu: DVec3) -> DVec3 {
        let local = self.plane_enu_from_local_enu_at(position).transpose() * vector_enu;
        DVec3::new(local.y, local.x, -local.z)
    }

    /// How far along the ray from `origin_enu_m` in direction `dir_enu` (unit), up to `max_m`,
    /// the surface `height_m` above the WGS84 ellipsoid lies: 0 when the origin is below it,
    /// `None` when the ray does not reach it. The height along a straight ray of up to a few
    /// kilometres is convex (the earth curves away under it), so its lowest point decides.
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::geo::{Geodetic, LocalTangentPlane};
    /// let plane = LocalTangentPlane::new(Geodetic::new(-35.0, 149.0, 584.0));
    /// // 10 km east of the origin, 30 m above the ellipsoidal surface at the origin's height:
    /// let up = plane.up_at(&Geodetic::new(-35.0, 149.0 + 10_000.0 / 91_300.0, 614.0));
    /// let p = plane.enu_m_from_geodetic(&Geodetic::new(-35.0, 149.0 + 10_000.0 / 91_300.0, 614.0));
    /// let d = plane.distance_to_height_m(p, -up, 40.0, 584.0).unwrap();
    /// assert!((d - 30.0).abs() < 1e-6, "{d}");
    /// ```
    pub fn distance_to_height_m(
        &self,
        origin_enu_m: DVec3,
        dir_enu: DVec3,
        max_m: f64,
        height_m: f64,
    ) -> Option<f64> {
        let above = |t: f64| self.geodetic_from_enu_m(origin_enu_m + dir_enu * t).alt_m - height_m;
        if above(0.0) <= 0.0 {
            return Some(0.0);
        }
        // The lowest point within reach (golden-section search on a convex function).
        let (mut lo, mut hi) = (0.0, max_m);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..80 {
            let (a, b) = (hi - g * (hi - lo), lo + g * (hi - lo));
            if above(a) < above(b) {
                hi = b;
            } else {
                lo = a;
            }
        }
        let lowest = 0.5 * (lo + hi);
        if above(lowest) > 0.0 {
            return None;
        }
        // The first crossing, between the origin and the lowest point.
        let (mut clear, mut under) = (0.0, lowest);
        for _ in 0..80 {
            let mid = 0.5 * (clear + under);
            if above(mid) > 0.0 {
                clear = mid;
            } else {
                under = mid;
            }
        }
        Some(under)
    }
}
