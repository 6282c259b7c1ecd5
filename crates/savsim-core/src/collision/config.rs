//! Collision settings: the modes and every threshold, each with its default and unit.

use crate::collision::sensing::octree::OctreeConfig;
use crate::collision::sensing::threat::{AhpWeights, PAPER_MATRIX};

/// How contacts are decided and how the sensing layer runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// No colliders at all.
    None,
    /// Every obstacle and the vehicle a box; checks at samples only.
    Box,
    /// Every obstacle and the vehicle a mesh (all built at start-up); checks at samples only.
    Mesh,
    /// The paper as written: current node only, six rays, the beta rule; contacts at samples
    /// against whatever collider the paper's state holds.
    Paper,
    /// The contact layer: every obstacle the swept vehicle can reach, as its exact shape
    /// (boxes and blocks as solids, terrain and loaded meshes as triangles), swept between
    /// samples. The sensing layer (the paper's node, rays, beta, swaps) runs beside it at
    /// `sensor_hz` and never decides a contact. The default (`adaptive` on the command line
    /// is an alias).
    Exact,
    /// The ground truth: dense sub-stepping of every interval (at most 1 cm of travel and
    /// 0.1 degree of turn a step) with exact intersection tests, sharing no code with the
    /// contact layer's sweep. Slow; for the bench and tests.
    Reference,
}

impl Mode {
    /// Every mode, cheapest first.
    pub const ALL: [Mode; 6] = [
        Mode::None,
        Mode::Box,
        Mode::Mesh,
        Mode::Paper,
        Mode::Exact,
        Mode::Reference,
    ];

    /// The mode of a name as [`Mode::name`] gives it (`adaptive` is an alias of `exact`).
    ///
    /// ```
    /// use savsim_core::pipeline::Mode;
    /// assert_eq!(Mode::from_name("adaptive"), Some(Mode::Exact));
    /// assert_eq!(Mode::from_name("fast"), None);
    /// ```
    pub fn from_name(name: &str) -> Option<Mode> {
        if name == "adaptive" {
            return Some(Mode::Exact);
        }
        Mode::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Mode::None => "none",
            Mode::Box => "box",
            Mode::Mesh => "mesh",
            Mode::Paper => "paper",
            Mode::Exact => "exact",
            Mode::Reference => "reference",
        }
    }
}

/// A sensor fan's name that is not one.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FanError {
    /// A ray count out of range.
    #[error("{0:?}: give 3 to 360 rays")]
    Rays(String),
    /// Not a fan's name.
    #[error("{0:?}: use six, ring:N or level-ring:N")]
    Name(String),
}

/// The sensing layer's rays: which directions it casts at each frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensorFan {
    /// The paper's six body axes: forward, back, right, left, down, up.
    Axes,
    /// `rays` rays evenly spaced around the body's horizontal plane (forward first, then
    /// clockwise seen from above), plus body up and down.
    Ring {
        /// Rays around (3 to 360).
        rays: u16,
    },
    /// `rays` rays evenly spaced around the horizon, levelled (the heading only: a pitched
    /// or rolled vehicle's ring does not see the ground), plus straight up and down.
    LevelRing {
        /// Rays around (3 to 360).
        rays: u16,
    },
}

impl SensorFan {
    /// The fan of a name: `six` (the paper), `ring:N` or `level-ring:N`.
    ///
    /// ```
    /// use savsim_core::collision::config::SensorFan;
    /// assert_eq!(SensorFan::parse("six"), Ok(SensorFan::Axes));
    /// assert_eq!(SensorFan::parse("level-ring:72"), Ok(SensorFan::LevelRing { rays: 72 }));
    /// assert!(SensorFan::parse("ring:2").is_err());
    /// assert_eq!(SensorFan::Ring { rays: 8 }.len(), 10);
    /// ```
    pub fn parse(text: &str) -> Result<Self, FanError> {
        let count = |n: &str| match n.parse::<u16>() {
            Ok(n) if (3..=360).contains(&n) => Ok(n),
            _ => Err(FanError::Rays(n.into())),
        };
        match text.split_once(':') {
            None if text == "six" => Ok(SensorFan::Axes),
            Some(("ring", n)) => Ok(SensorFan::Ring { rays: count(n)? }),
            Some(("level-ring", n)) => Ok(SensorFan::LevelRing { rays: count(n)? }),
            _ => Err(FanError::Name(text.into())),
        }
    }

    /// How many rays a frame casts.
    pub fn len(self) -> usize {
        match self {
            SensorFan::Axes => 6,
            SensorFan::Ring { rays } | SensorFan::LevelRing { rays } => usize::from(rays) + 2,
        }
    }

    /// False: a fan always has rays (for clippy's `len` rule).
    pub fn is_empty(self) -> bool {
        false
    }

    /// Ray `k`'s direction in ENU for a body whose FRD axes turn into ENU by `enu_from_frd`.
    pub fn direction_enu(self, k: usize, enu_from_frd: glam::DQuat) -> glam::DVec3 {
        use glam::DVec3;
        const AXES_FRD: [DVec3; 6] = [
            DVec3::X,
            DVec3::NEG_X,
            DVec3::Y,
            DVec3::NEG_Y,
            DVec3::Z,
            DVec3::NEG_Z,
        ];
        let around = |n: u16| (k as f64) * std::f64::consts::TAU / f64::from(n);
        match self {
            SensorFan::Axes => enu_from_frd * AXES_FRD[k.min(5)],
            SensorFan::Ring { rays } => {
                let frd = match k.checked_sub(usize::from(rays)) {
                    None => DVec3::new(around(rays).cos(), around(rays).sin(), 0.0),
                    Some(0) => DVec3::Z,
                    Some(_) => DVec3::NEG_Z,
                };
                enu_from_frd * frd
            }
            SensorFan::LevelRing { rays } => match k.checked_sub(usize::from(rays)) {
                // Clockwise from the heading seen from above: ENU angles go down.
                None => {
                    let f = enu_from_frd * DVec3::X;
                    let heading = f.y.atan2(f.x) - around(rays);
                    DVec3::new(heading.cos(), heading.sin(), 0.0)
                }
                Some(0) => DVec3::NEG_Z,
                Some(_) => DVec3::Z,
            },
        }
    }
}

/// Collision settings. Every default and unit is in the field's doc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollisionConfig {
    /// How contacts are decided. Default `exact`.
    pub mode: Mode,
    /// Length of each sensing ray, metres. Default 300 (the paper's mesh distance).
    pub ray_length_m: f64,
    /// Look-ahead time for the sensing region around the vehicle, seconds. Default 3.
    pub look_ahead_s: f64,
    /// Beta above which a seen obstacle gets a mesh. Default 50 (paper).
    pub mesh_beta: f64,
    /// ... if it is closer than this, metres. Default 300 (paper).
    pub mesh_within_m: f64,
    /// A mesh farther than this turns back into a box, metres. Default 800 (paper).
    pub box_beyond_m: f64,
    /// A collider keeps its state at least this long before it is downgraded, seconds.
    /// Default 2 (ArduPilot's AP_Avoidance never lowers a threat faster). 0 in `paper` mode.
    pub hold_s: f64,
    /// Closer than this without contact is a near miss, metres. Default 10.
    pub near_miss_m: f64,
    /// A telemetry gap longer than this is reported and not swept, seconds. Default 1.
    pub max_gap_s: f64,
    /// A sample more than this far below the terrain surface is implausible (an altitude
    /// reference not yet set, e.g. before the autopilot's EKF has an origin): it is counted
    /// and skipped, and no sweep starts or ends at it. Metres. Default 50.
    pub max_below_terrain_m: f64,
    /// Sensing frames per second in `exact` mode (every sample when telemetry is slower).
    /// Default 20. `paper` senses at every sample.
    pub sensor_hz: f64,
    /// The sensing layer's rays. Default the paper's six body axes.
    pub sensor_fan: SensorFan,
    /// Most memory the built triangle meshes may hold, MiB; the least recently used mesh
    /// that no tick needs is evicted beyond it. Default 512. (`mesh` mode keeps all.)
    pub mesh_budget_mib: f64,
    /// AHP weights for beta. Default: the paper's Table 3.
    pub ahp: AhpWeights,
    /// Octree shape.
    pub octree: OctreeConfig,
}

impl Default for CollisionConfig {
    fn default() -> Self {
        Self {
            mode: Mode::Exact,
            ray_length_m: 300.0,
            look_ahead_s: 3.0,
            mesh_beta: 50.0,
            mesh_within_m: 300.0,
            box_beyond_m: 800.0,
            hold_s: 2.0,
            near_miss_m: 10.0,
            max_gap_s: 1.0,
            max_below_terrain_m: 50.0,
            sensor_hz: 20.0,
            sensor_fan: SensorFan::Axes,
            mesh_budget_mib: 512.0,
            ahp: AhpWeights::from_matrix(PAPER_MATRIX).expect("the paper's matrix is valid"),
            octree: OctreeConfig::default(),
        }
    }
}

impl CollisionConfig {
    /// Check every threshold against its range (each named by its command-line flag):
    /// lengths up to 100 km, times up to a day, rates up to 1000 Hz, the mesh budget up to
    /// 1 TiB.
    ///
    /// ```
    /// use savsim_core::collision::config::CollisionConfig;
    /// assert!(CollisionConfig::default().validate().is_ok());
    /// let huge = CollisionConfig { ray_length_m: 1e300, ..CollisionConfig::default() };
    /// assert!(huge.validate().unwrap_err().to_string().starts_with("--ray-length-m"));
    /// ```
    pub fn validate(&self) -> Result<(), crate::bounds::OutOfRange> {
        use crate::bounds::within;
        const LENGTH_M: f64 = 100_000.0;
        const TIME_S: f64 = 86_400.0;
        for (name, v, max) in [
            ("--ray-length-m", self.ray_length_m, LENGTH_M),
            ("--near-miss-m", self.near_miss_m, LENGTH_M),
            ("--max-gap-s", self.max_gap_s, TIME_S),
            ("--look-ahead-s", self.look_ahead_s, TIME_S),
            ("--mesh-beta", self.mesh_beta, 1e6),
            ("--mesh-within-m", self.mesh_within_m, LENGTH_M),
            ("--box-beyond-m", self.box_beyond_m, LENGTH_M),
            ("--hold-s", self.hold_s, TIME_S),
            ("--max-below-terrain-m", self.max_below_terrain_m, LENGTH_M),
            ("--sensor-hz", self.sensor_hz, crate::bounds::MAX_RATE_HZ),
            ("--mesh-budget-mib", self.mesh_budget_mib, 1024.0 * 1024.0),
        ] {
            within(name, v, 0.0, max)?;
        }
        Ok(())
    }
}
