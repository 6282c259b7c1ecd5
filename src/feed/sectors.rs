//! The feed's geometry: which way each reading looks, and how the 72 five-degree bins make the
//! eight 45-degree sectors.
//!
//! Angles go clockwise from the vehicle's nose seen from above, as ArduPilot's sectors
//! (orientation 0 front, 2 right, 4 back, 6 left) and OBSTACLE_DISTANCE in `MAV_FRAME_BODY_FRD`
//! count them. The horizontal readings are levelled: cast from the vehicle's heading alone
//! (yaw only), so a pitched copter does not see the ground ahead as a wall. The downward
//! reading is body-fixed, as a rangefinder is mounted (the autopilot corrects it for tilt).
//!
//! Pure; no I/O.

use glam::DVec3;

/// Horizontal bins: 72 of 5 degrees, bin `j` centred `BIN0_DEG + 5 j` degrees clockwise from
/// the nose.
pub const BINS: usize = 72;
/// Width of one bin, degrees.
pub const BIN_DEG: f64 = 5.0;
/// Where bin 0 is centred, degrees clockwise from the nose (OBSTACLE_DISTANCE's
/// `angle_offset`): 20 degrees left, so that each 45-degree sector is nine consecutive bins,
/// bins 9 k to 9 k + 8 for sector k. ArduPilot (AP_Proximity_MAV) walks the bins in order and
/// keeps, for each sector, the nearest of the last run of bins that fell in it: with bin 0 on
/// the nose the forward sector is two runs (0 to 20 degrees, then 340 to 355) and only the
/// second counted, so a wall dead ahead went unseen in a SITL run against ArduCopter whenever
/// the bins 5 to 20 degrees left of the nose saw something farther. PX4 takes any offset.
pub const BIN0_DEG: f64 = -20.0;
/// Horizontal sectors: 8 of 45 degrees, sector `k` centred `45 k` degrees from the nose.
pub const SECTORS: usize = 8;
/// Bins per sector: the nine bins centred within 20 degrees of the sector's centre line.
pub const BINS_PER_SECTOR: usize = 9;

/// The vehicle's levelled frame: its nose and right-hand side projected on the horizontal
/// plane at the vehicle (perpendicular to its local vertical), ENU unit vectors. `forward_enu` is the body's x axis; a nose pointing straight up or
/// down (no heading) falls back to the body's `down_enu` axis projected, which then points
/// where the nose would level out.
///
/// ```
/// use glam::DVec3;
/// use savsim::feed::sectors::Levelled;
/// // Nose north-east and pitched 30 degrees up: the levelled nose is north-east, level.
/// let f = DVec3::new(1.0, 1.0, 2f64.sqrt() * 30f64.to_radians().tan()).normalize();
/// let l = Levelled::new(f, DVec3::NEG_Z, DVec3::Z).unwrap();
/// assert!((l.forward_enu - DVec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-12);
/// // Clockwise from above: the right-hand side of a north-east nose is south-east.
/// assert!((l.right_enu - DVec3::new(1.0, -1.0, 0.0).normalize()).length() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Levelled {
    /// The nose, levelled, ENU.
    pub forward_enu: DVec3,
    /// 90 degrees clockwise from the nose seen from above, ENU.
    pub right_enu: DVec3,
}

impl Levelled {
    /// From the body's forward (x) and down (z) axes and the local vertical `up_enu` at the
    /// vehicle (all ENU); `None` if neither axis gives a heading (not finite).
    pub fn new(forward_enu: DVec3, down_enu: DVec3, up_enu: DVec3) -> Option<Self> {
        let up = up_enu.try_normalize()?;
        let flat = |v: DVec3| (v - up * v.dot(up)).try_normalize();
        // Nose vertical: the body's down axis, levelled, points along the heading when the
        // nose is up (pitched up 90 degrees, the belly faces ahead), back when it is down.
        let forward = flat(forward_enu)
            .or_else(|| flat(down_enu).map(|d| if forward_enu.dot(up) > 0.0 { d } else { -d }))?;
        Some(Self {
            forward_enu: forward,
            right_enu: forward.cross(up),
        })
    }

    /// The horizontal direction `clockwise_deg` degrees clockwise from the nose, ENU unit.
    pub fn direction(&self, clockwise_deg: f64) -> DVec3 {
        let (s, c) = clockwise_deg.to_radians().sin_cos();
        self.forward_enu * c + self.right_enu * s
    }

    /// The 72 bins' centre lines, ENU unit vectors, bin 0 at [`BIN0_DEG`].
    pub fn bin_directions(&self, out: &mut [DVec3; BINS]) {
        for (j, d) in out.iter_mut().enumerate() {
            *d = self.direction(BIN0_DEG + j as f64 * BIN_DEG);
        }
    }
}

/// Sector `k`'s distance: the nearest of its nine bins (the bins centred 20, 15, ... 0, ...
/// 20 degrees either side of the sector's centre line: bins 9 k to 9 k + 8), or `None` if
/// none saw anything.
///
/// ```
/// use savsim::feed::sectors::{sector_from_bins, BINS};
/// let mut bins = [None; BINS];
/// bins[8] = Some(7.0); // 20 degrees right of the nose: still sector 0
/// bins[9] = Some(3.0); // 25 degrees: sector 1
/// bins[0] = Some(9.0); // 20 degrees left of the nose: sector 0 too
/// assert_eq!(sector_from_bins(&bins, 0), Some(7.0));
/// assert_eq!(sector_from_bins(&bins, 1), Some(3.0));
/// assert_eq!(sector_from_bins(&bins, 4), None);
/// ```
pub fn sector_from_bins(bins: &[Option<f64>; BINS], k: usize) -> Option<f64> {
    let first = k * BINS_PER_SECTOR;
    bins[first..first + BINS_PER_SECTOR]
        .iter()
        .flatten()
        .copied()
        .min_by(f64::total_cmp)
}
