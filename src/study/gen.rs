//! `savsim study gen`: pairs of rows, `nominal` and `mitigated`, deterministic for a seed.
//!
//! **Approaches** ([`approaches`]), in the UAV Testing Competition's style. Pair `k`: a box of
//! random size across a straight path from home, at a random distance, lateral offset and
//! yaw, flown at a random speed and heading at 20 m; a `nominal` row (no feed, no proximity
//! sensor, avoidance off) and a `mitigated` row (`--feed proximity`, ArduCopter's proximity
//! avoidance stopping 3 m short).
//!
//! | drawn | range |
//! |---|---|
//! | heading | 0-360 degrees |
//! | speed | 3-8 m/s |
//! | box width across, depth along the path | 6-20 m, 4-12 m |
//! | box height | 40-60 m (the path, at 20 m, cannot pass over it) |
//! | box yaw against the path | -30 to +30 degrees |
//! | distance from home to the box's near face | 30-50 m |
//! | lateral offset of the box's centre | within a quarter of its width (the path hits it) |

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::daa::encounter_model::Model;
use crate::error::Result;
use crate::runs::model_tracks::{placed, sample, velocity};
use crate::study::manifest::StudyRow;

/// The height the paths are flown at, metres above home.
pub const PATH_UP_M: f64 = 20.0;
/// ArduCopter's parameters for the mitigated rows: MAVLink proximity, no low-pass filter,
/// proximity avoidance that stops 3 m short.
pub const MITIGATED_PARAMS: &str =
    "PRX1_TYPE=2;PRX_FILT=0;AVOID_ENABLE=3;AVOID_BEHAVE=1;AVOID_MARGIN=3";
/// The nominal rows': avoidance off.
pub const NOMINAL_PARAMS: &str = "AVOID_ENABLE=0";
/// PX4's mitigated rows: Collision Prevention keeping 5 m, in a Position-mode variant that has
/// it (smoothed velocity; which variants have it: docs/study.md).
pub const PX4_MITIGATED_PARAMS: &str = "CP_DIST=5;MPC_POS_MODE=3";
/// PX4's nominal rows: Collision Prevention off, the same Position-mode variant.
pub const PX4_NOMINAL_PARAMS: &str = "CP_DIST=-1;MPC_POS_MODE=3";
/// PX4 takes longer to reach its stick's speed: its velocity legs last this much longer.
const PX4_EXTRA_S: f64 = 15.0;

/// **Encounters** ([`encounters`]): the copter hovers at 30 m over home (open air); a
/// small-UAS intruder (`dji`) crosses at [`ENCOUNTER_TCA_S`] of the copter's clock, heading
/// 0-360 degrees, 15-30 m/s, horizontal miss distance 0-30 m, vertical -10 to +10 m at the
/// closest approach, waiting 1500 m out before it and flying on 1500 m after. Both rows have
/// the ADS-B feed and ArduCopter's ADS-B receiver (`ADSB_TYPE=1`); `nominal` has `AVD_ENABLE=0`,
/// `mitigated` `AVD_ENABLE=1` with the horizontal action (`AVD_F_ACTION=3`; the vertical one
/// steers towards the threat, docs/closed-loop.md).
pub const ENCOUNTER_TCA_S: f64 = 110.0;
/// The encounters' mitigated parameters.
pub const ADSB_MITIGATED_PARAMS: &str = "ADSB_TYPE=1;AVD_ENABLE=1;AVD_F_ACTION=3";
/// The encounters' nominal parameters.
pub const ADSB_NOMINAL_PARAMS: &str = "ADSB_TYPE=1;AVD_ENABLE=0";

/// PX4's encounters, mitigated: traffic avoidance that returns (RTL) on a conflict, read when
/// PX4 starts (the row's parameters are set before its boot), in the Position-mode variant the
/// pilot flies. PX4 1.15's navigator checks traffic in every mode but acts only on 2 (return)
/// or 3 (land): 1 only warns, and 4 (hold) sends a command its commander does not carry out
/// (docs/study.md, "PX4's traffic avoidance").
pub const PX4_ADSB_MITIGATED_PARAMS: &str = "NAV_TRAFF_AVOID=2;MPC_POS_MODE=3";
/// PX4's encounters, nominal: traffic only warned of.
pub const PX4_ADSB_NOMINAL_PARAMS: &str = "NAV_TRAFF_AVOID=1;MPC_POS_MODE=3";

/// Encounter pairs from `seed` (open air: no scene).
///
/// ```
/// let e = savsim::study::gen::encounters(2, 5);
/// assert_eq!(e[1][1].variant.as_deref(), Some("mitigated"));
/// assert!(e[0][0].intruder.is_some());
/// ```
pub fn encounters(n: usize, seed: u64) -> Vec<[StudyRow; 2]> {
    encounters_for(n, seed, false)
}

/// [`encounters`] for PX4 (`px4`: [`PX4_ADSB_MITIGATED_PARAMS`], [`PX4_ADSB_NOMINAL_PARAMS`])
/// or ArduCopter: the same geometry for the same seed.
///
/// ```
/// use savsim::study::gen::{encounters, encounters_for};
/// let (a, p) = (encounters(3, 9), encounters_for(3, 9, true));
/// assert_eq!(a[2][0].intruder, p[2][0].intruder);
/// assert_eq!(p[0][1].autopilot.as_deref(), Some("px4"));
/// assert!(p[0][1].params.as_deref().unwrap().contains("NAV_TRAFF_AVOID=2"));
/// ```
pub fn encounters_for(n: usize, seed: u64, px4: bool) -> Vec<[StudyRow; 2]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|k| {
            let rows = encounter(k, seed, &mut rng);
            if px4 {
                rows.map(for_px4)
            } else {
                rows
            }
        })
        .collect()
}

/// An ArduCopter encounter row flown by PX4 instead.
fn for_px4(row: StudyRow) -> StudyRow {
    let mitigated = row.variant.as_deref() == Some("mitigated");
    StudyRow {
        autopilot: Some("px4".into()),
        params: Some(
            if mitigated {
                PX4_ADSB_MITIGATED_PARAMS
            } else {
                PX4_ADSB_NOMINAL_PARAMS
            }
            .into(),
        ),
        ..row
    }
}

fn encounter(k: usize, seed: u64, rng: &mut ChaCha8Rng) -> [StudyRow; 2] {
    const UP_M: f64 = HOVER_UP_M;
    const OUT_M: f64 = 1500.0;
    let heading_deg: f64 = rng.random_range(0.0..360.0);
    let speed_mps: f64 = rng.random_range(15.0..30.0);
    let hmd_m: f64 = rng.random_range(0.0..30.0);
    let vmd_m: f64 = rng.random_range(-10.0..10.0);
    let (s, c) = heading_deg.to_radians().sin_cos();
    let (along, right) = ([s, c], [c, -s]);
    let at = |d: f64| {
        [
            along[0] * d + right[0] * hmd_m,
            along[1] * d + right[1] * hmd_m,
            UP_M + vmd_m,
        ]
    };
    let run_s = OUT_M / speed_mps;
    let point = |t: f64, p: [f64; 3]| format!("{t:.2} {:.2} {:.2} {:.2}", p[0], p[1], p[2]);
    let intruder = [
        point(0.0, at(-OUT_M)),
        point(ENCOUNTER_TCA_S - run_s, at(-OUT_M)),
        point(ENCOUNTER_TCA_S, at(0.0)),
        point(ENCOUNTER_TCA_S + run_s, at(OUT_M)),
    ]
    .join("; ");
    encounter_rows(format!("encounter-{k:05}"), seed, intruder)
}

/// The hovering copter's height over home in the encounters, m.
const HOVER_UP_M: f64 = 30.0;

/// **Encounters from an MIT LL encounter model** ([`model_encounters`]): the intruder's track
/// is sampled from the model (1 s steps, with its turns, climbs and speed changes) for the
/// row's 150 s, turned to a heading drawn uniformly, and placed so that at
/// [`ENCOUNTER_TCA_S`] it passes the hovering copter at a horizontal miss distance drawn
/// uniformly in 0-300 m (perpendicular to its velocity then, on a random side) and a vertical
/// one in -20 to +100 m (intruder above positive; it is never under 10 m over home then).
/// The tracks curve, so the closest approach may come at another time and nearer. Every
/// weight `w` is 1 (the geometry is drawn from these distributions themselves); the rows are
/// those of [`encounters`] otherwise.
///
/// ```
/// let text = std::fs::read_to_string("scenes/encounter-models/uncor_1200code_v2p1.txt").unwrap();
/// let model = savsim::daa::encounter_model::Model::parse(&text).unwrap();
/// let e = savsim::study::gen::model_encounters(2, 3, &model).unwrap();
/// assert_eq!(e.len(), 2);
/// assert_eq!(e, savsim::study::gen::model_encounters(2, 3, &model).unwrap());
/// assert!(e[0][1].intruder.as_ref().unwrap().split(';').count() > 100);
/// ```
pub fn model_encounters(n: usize, seed: u64, model: &Model) -> Result<Vec<[StudyRow; 2]>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let seconds = (ENCOUNTER_TCA_S + 40.0) as usize;
    let tca_s = ENCOUNTER_TCA_S as usize;
    (0..n)
        .map(|k| {
            let track = sample(model, seconds, &mut rng)?;
            let turn = rng.random_range(0.0..std::f64::consts::TAU);
            let hmd_m: f64 = rng.random_range(0.0..=300.0);
            let vmd_m: f64 = rng.random_range(-20.0..=100.0);
            let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let at_origin = placed(&track, turn, tca_s, DVec3::ZERO);
            let across = velocity(&at_origin, tca_s)
                .cross(DVec3::Z)
                .normalize_or_zero();
            let across = if across == DVec3::ZERO {
                DVec3::X
            } else {
                across
            };
            let copter = DVec3::new(0.0, 0.0, HOVER_UP_M);
            let at = copter + across * side * hmd_m + DVec3::Z * vmd_m;
            let intruder = placed(&track, turn, tca_s, at)
                .iter()
                .map(|(t, p)| format!("{t:.2} {:.2} {:.2} {:.2}", p.x, p.y, p.z))
                .collect::<Vec<_>>()
                .join("; ");
            Ok(encounter_rows(
                format!("model-encounter-{k:05}"),
                seed,
                intruder,
            ))
        })
        .collect()
}

/// An encounter's `nominal` and `mitigated` rows, the intruder flying `intruder`.
fn encounter_rows(id: String, seed: u64, intruder: String) -> [StudyRow; 2] {
    const UP_M: f64 = HOVER_UP_M;
    let row = |variant: &str, params: &str| StudyRow {
        id: Some(format!("{id}-{variant}")),
        autopilot: Some("arducopter".into()),
        variant: Some(variant.into()),
        pair: Some(id.clone()),
        params: Some(params.into()),
        feed: Some("adsb".into()),
        plan: Some(format!("takeoff {UP_M}; hold {}", ENCOUNTER_TCA_S + 40.0)),
        intruder: Some(intruder.clone()),
        intruder_kind: Some("dji".into()),
        duration_s: Some(ENCOUNTER_TCA_S + 40.0),
        seed: Some(seed),
        ..StudyRow::default()
    };
    [
        row("nominal", ADSB_NOMINAL_PARAMS),
        row("mitigated", ADSB_MITIGATED_PARAMS),
    ]
}

/// **Cooperative encounters** ([`cooperative_encounters`]): two ArduCopters, each flown by its
/// own SITL, cross in open air. The first takes off from home to [`HOVER_UP_M`], the second
/// from its own home (`intruder_home`) to that height plus the vertical miss; both wait until
/// [`COOP_START_S`] of the row's clock (`until`), then hold their velocity for
/// [`COOP_RUN_S`] + 30 s: unavoided, they pass at [`COOP_START_S`] + [`COOP_RUN_S`] =
/// [`ENCOUNTER_TCA_S`] + 10 s with the drawn miss. Both are fed ADS-B of the other. One row per
/// equipage: `none` (neither avoids: [`ADSB_NOMINAL_PARAMS`] on both), `one` (the first
/// avoids: [`ADSB_MITIGATED_PARAMS`]), `both`.
///
/// | drawn | range |
/// |---|---|
/// | first's heading | 0-360 degrees |
/// | second's heading, from the first's | 60-300 degrees (crossing or head-on, not overtaking) |
/// | speeds | 8-12 m/s each |
/// | horizontal miss, across their relative velocity | 0-30 m |
/// | vertical miss (second above positive) | -10 to +10 m |
///
/// ```
/// use savsim::study::gen::{cooperative_encounters, Equipage};
/// let e = cooperative_encounters(2, 5, &[Equipage::None, Equipage::Both]);
/// assert_eq!(e[0].len(), 2);
/// assert_eq!(e[0][1].variant.as_deref(), Some("both"));
/// assert_eq!(e[0][1].intruder_autopilot.as_deref(), Some("arducopter"));
/// assert!(e[0][1].intruder_params.as_deref().unwrap().contains("AVD_ENABLE=1"));
/// assert_eq!(e, cooperative_encounters(2, 5, &[Equipage::None, Equipage::Both]));
/// ```
pub fn cooperative_encounters(n: usize, seed: u64, equipage: &[Equipage]) -> Vec<Vec<StudyRow>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|k| cooperative(k, seed, &mut rng, equipage))
        .collect()
}

/// When a cooperative encounter's two vehicles start their run, seconds of the row's clock
/// (ArduCopter SITL arms 42-43 s after its boot and climbs for another 15).
pub const COOP_START_S: f64 = 85.0;
/// How long their run lasts until the closest approach, seconds.
pub const COOP_RUN_S: f64 = 35.0;

/// Which of an encounter's two aircraft avoid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Equipage {
    /// Neither.
    None,
    /// The first (the row's ownship).
    One,
    /// Both.
    Both,
}

impl Equipage {
    /// From its name: `none`, `one` or `both`.
    pub fn parse(name: &str) -> Option<Self> {
        match name.trim() {
            "none" => Some(Equipage::None),
            "one" => Some(Equipage::One),
            "both" => Some(Equipage::Both),
            _ => None,
        }
    }

    /// Its name: the row's variant.
    pub fn name(self) -> &'static str {
        match self {
            Equipage::None => "none",
            Equipage::One => "one",
            Equipage::Both => "both",
        }
    }
}

fn cooperative(k: usize, seed: u64, rng: &mut ChaCha8Rng, equipage: &[Equipage]) -> Vec<StudyRow> {
    let heading = |deg: f64| {
        let (s, c) = deg.to_radians().sin_cos();
        DVec3::new(s, c, 0.0)
    };
    let own_deg: f64 = rng.random_range(0.0..360.0);
    let other_deg = own_deg + rng.random_range(60.0..300.0);
    let own_v = heading(own_deg) * rng.random_range(8.0..12.0);
    let other_v = heading(other_deg) * rng.random_range(8.0..12.0);
    let hmd_m: f64 = rng.random_range(0.0..30.0);
    let vmd_m: f64 = rng.random_range(-10.0..10.0);
    let across = (other_v - own_v).cross(DVec3::Z).normalize_or_zero();
    // The first's closest approach point, and the second's start under its own.
    let own_at_tca = own_v * COOP_RUN_S;
    let other_home = own_at_tca + across * hmd_m - other_v * COOP_RUN_S;
    let run_s = COOP_RUN_S + 30.0;
    let plan = |up_m: f64, v: DVec3| {
        format!(
            "takeoff {up_m:.2}; until {COOP_START_S}; velocity {:.3} {:.3} 0 {run_s}",
            v.x, v.y
        )
    };
    let id = format!("coop-encounter-{k:05}");
    equipage
        .iter()
        .map(|e| {
            let (own, other) = match e {
                Equipage::None => (ADSB_NOMINAL_PARAMS, ADSB_NOMINAL_PARAMS),
                Equipage::One => (ADSB_MITIGATED_PARAMS, ADSB_NOMINAL_PARAMS),
                Equipage::Both => (ADSB_MITIGATED_PARAMS, ADSB_MITIGATED_PARAMS),
            };
            StudyRow {
                id: Some(format!("{id}-{}", e.name())),
                autopilot: Some("arducopter".into()),
                variant: Some(e.name().into()),
                pair: Some(id.clone()),
                params: Some(own.into()),
                feed: Some("adsb".into()),
                plan: Some(plan(HOVER_UP_M, own_v)),
                duration_s: Some(COOP_START_S + run_s),
                seed: Some(seed),
                intruder_autopilot: Some("arducopter".into()),
                intruder_plan: Some(plan(HOVER_UP_M + vmd_m, other_v)),
                intruder_params: Some(other.into()),
                intruder_home: Some(format!("{:.2} {:.2}", other_home.x, other_home.y)),
                ..StudyRow::default()
            }
        })
        .collect()
}

/// One generated approach: its scene's text and its two rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Approach {
    /// The scene file's name.
    pub scene_file: String,
    /// The scene (TOML).
    pub scene_toml: String,
    /// `nominal` and `mitigated`.
    pub rows: [StudyRow; 2],
}

/// `n` approaches from `seed`; rows name their scene as `scene_file` (relative to the
/// manifest).
///
/// ```
/// let a = savsim::study::gen::approaches(3, 7);
/// assert_eq!(a.len(), 3);
/// assert_eq!(a, savsim::study::gen::approaches(3, 7));
/// assert_eq!(a[0].rows[1].variant.as_deref(), Some("mitigated"));
/// ```
pub fn approaches(n: usize, seed: u64) -> Vec<Approach> {
    approaches_for(n, seed, false)
}

/// The same approaches for PX4 (`px4`: `--feed obstacle-distance`, CP_DIST) or ArduCopter;
/// the geometry is the same for a seed.
pub fn approaches_for(n: usize, seed: u64, px4: bool) -> Vec<Approach> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|k| approach(k, seed, px4, &mut rng)).collect()
}

fn approach(k: usize, seed: u64, px4: bool, rng: &mut ChaCha8Rng) -> Approach {
    let heading_deg: f64 = rng.random_range(0.0..360.0);
    let speed_mps: f64 = rng.random_range(3.0..8.0);
    let (width_m, depth_m, height_m): (f64, f64, f64) = (
        rng.random_range(6.0..20.0),
        rng.random_range(4.0..12.0),
        rng.random_range(40.0..60.0),
    );
    let yaw_off_deg: f64 = rng.random_range(-30.0..30.0);
    let near_m: f64 = rng.random_range(30.0..50.0);
    let lateral_m: f64 = rng.random_range(-0.25..0.25) * width_m;
    // Unit vectors along the path and to its right, ENU (heading clockwise from north).
    let (s, c) = heading_deg.to_radians().sin_cos();
    let (along, right) = ([s, c], [c, -s]);
    let centre_along = near_m + depth_m / 2.0;
    let centre = [
        along[0] * centre_along + right[0] * lateral_m,
        along[1] * centre_along + right[1] * lateral_m,
    ];
    // The scene's yaw is counter-clockwise from east; the box's x (east) side is `depth`
    // along the path: the path's direction is 90 - heading degrees from east.
    let yaw_deg = 90.0 - heading_deg + yaw_off_deg;
    let id = format!("approach-{k:05}");
    let scene_file = format!("{id}.toml");
    let o = crate::scene::gen::DEFAULT_ORIGIN;
    let scene_toml = format!(
        "# savsim study gen --seed {seed}: pair {k}\n[origin]\nlat_deg = {}\nlon_deg = {}\nalt_m = {}\n\n\
         [[obstacle]]\nid = \"box\"\nkind = \"building\"\nshape = {{ box = [{depth_m:.2}, {width_m:.2}, {height_m:.2}] }}\n\
         position_enu_m = [{:.2}, {:.2}, 0.0]\nyaw_deg = {yaw_deg:.2}\n",
        o.lat_deg, o.lon_deg, o.alt_m, centre[0], centre[1]
    );
    // Fly on 25 m past the box's far side.
    let leg_s = (near_m + depth_m + 25.0) / speed_mps + if px4 { PX4_EXTRA_S } else { 0.0 };
    let plan = format!(
        "takeoff {PATH_UP_M}; velocity {:.3} {:.3} 0 {leg_s:.1}",
        along[0] * speed_mps,
        along[1] * speed_mps
    );
    let row = |variant: &str, params: &str, feed: Option<&str>| StudyRow {
        id: Some(format!("{id}-{variant}")),
        scene: Some(scene_file.clone()),
        autopilot: Some(if px4 { "px4" } else { "arducopter" }.into()),
        variant: Some(variant.into()),
        pair: Some(id.clone()),
        params: Some(params.into()),
        feed: feed.map(str::to_string),
        plan: Some(plan.clone()),
        duration_s: Some((90.0 + leg_s).ceil()),
        seed: Some(seed),
        ..StudyRow::default()
    };
    Approach {
        scene_file: scene_file.clone(),
        scene_toml,
        rows: if px4 {
            [
                row("nominal", PX4_NOMINAL_PARAMS, None),
                row("mitigated", PX4_MITIGATED_PARAMS, Some("obstacle-distance")),
            ]
        } else {
            [
                row("nominal", NOMINAL_PARAMS, None),
                row("mitigated", MITIGATED_PARAMS, Some("proximity")),
            ]
        },
    }
}

/// Each `mitigated` row flown once per sensor set (`--sensors` lists): variant
/// `mitigated/SET`, id `ID/SET`, `sensors` the set; `nominal` rows once, as they are. No sets:
/// the rows as they are.
///
/// ```
/// let pairs = savsim::study::gen::encounters(1, 5);
/// let rows = pairs.into_iter().flatten().collect();
/// let sets = ["ideal".to_string(), "adsb-1090es:nacp=7".to_string()];
/// let rows = savsim::study::gen::per_sensor_set(rows, &sets);
/// let variants: Vec<_> = rows.iter().map(|r| r.variant.clone().unwrap()).collect();
/// assert_eq!(variants, ["nominal", "mitigated/ideal", "mitigated/adsb-1090es:nacp=7"]);
/// assert_eq!(rows[2].sensors.as_deref(), Some("adsb-1090es:nacp=7"));
/// ```
pub fn per_sensor_set(rows: Vec<StudyRow>, sets: &[String]) -> Vec<StudyRow> {
    if sets.is_empty() {
        return rows;
    }
    let mut out = Vec::with_capacity(rows.len() * sets.len());
    for row in rows {
        if row.variant.as_deref() != Some("mitigated") {
            out.push(row);
            continue;
        }
        for set in sets {
            out.push(StudyRow {
                id: row.id.as_ref().map(|id| format!("{id}/{set}")),
                variant: Some(format!("mitigated/{set}")),
                sensors: Some(set.clone()),
                ..row.clone()
            });
        }
    }
    out
}
