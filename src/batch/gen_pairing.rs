//! `savsim batch gen-encounters --model FILE --pairing FILE.ini`: model tracks paired by
//! importance sampling as MIT LL's em-pairing-uncor-importancesampling pairs them
//! (`savsim_core::daa::pairing`), each encounter with its weight `w`.
//!
//! Per encounter, from the ChaCha8 stream seeded with `seed`: both tracks are sampled from the
//! model for the `.ini`'s `sample_time` (each at its own sampled altitude); the VMD at `tCPA`
//! is kept or the pair drawn again (rejection toward `desired_proportions_VMD`); the
//! intruder's course relative to the ownship's at TCA is drawn with density proportional to
//! the relative speed; the signed HMD from the `bin_edges_HMD` proposal, perpendicular to the
//! relative velocity at TCA; the whole encounter is turned to a uniform heading with the
//! ownship at TCA uniform in a 3 km square around the scene's origin; a pair that starts
//! closer than `H_min` vertically and `R_min` horizontally is drawn again.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::batch::gen::GenOptions;
use crate::batch::gen_model::waypoints;
use crate::batch::manifest::Run;
use crate::daa::encounter_model::{Model, TrackPoint};
use crate::daa::pairing::{heading_norm_ftps, hmd_weight, relative_heading};
use crate::daa::pairing_ini::PairingSettings;
use crate::daa::well_clear::FT_M;
use crate::error::{Error, Result};
use crate::runs::model_tracks::{placed, sample, velocity};

/// Track pairs drawn for one encounter before the settings are judged unable to give one.
const MAX_PAIR_TRIES: usize = 100_000;

/// One paired encounter: the placed tracks and what built them.
struct Paired {
    own: Vec<(f64, DVec3)>,
    intruder: Vec<(f64, DVec3)>,
    hmd_m: f64,
    vmd_m: f64,
    w: f64,
}

/// A track's velocity at `k` (m/s; as `velocity`, unplaced).
fn track_velocity(track: &[TrackPoint], k: usize) -> DVec3 {
    let points: Vec<(f64, DVec3)> = track.iter().map(|p| (p.t_s, p.position_enu_m)).collect();
    velocity(&points, k)
}

/// The compass course (radians from north, clockwise) of a horizontal velocity.
fn course(v: DVec3) -> f64 {
    v.x.atan2(v.y)
}

/// Pair two sampled tracks, or `None` when this pair is rejected.
fn pair(
    own: &[TrackPoint],
    intruder: &[TrackPoint],
    settings: &PairingSettings,
    rng: &mut ChaCha8Rng,
) -> Option<Paired> {
    let tca = settings.tca_s;
    let vmd_m = intruder[tca].position_enu_m.z - own[tca].position_enu_m.z;
    let keep = settings.vmd_m.acceptance(vmd_m)?;
    if rng.random::<f64>() > keep {
        return None;
    }
    let (v_own, v_int) = (track_velocity(own, tca), track_velocity(intruder, tca));
    let (s_own, s_int) = (
        v_own.truncate().length() / FT_M,
        v_int.truncate().length() / FT_M,
    );
    let dvz_ftps = (v_int.z - v_own.z) / FT_M;
    let psi = relative_heading(s_own, s_int, dvz_ftps, rng);
    let base = rng.random_range(0.0..std::f64::consts::TAU);
    let own_at = DVec3::new(
        rng.random_range(-1500.0..=1500.0),
        rng.random_range(-1500.0..=1500.0),
        own[tca].position_enu_m.z,
    );
    let own = placed(own, base - course(v_own), tca, own_at);
    let intruder_turn = base + psi - course(v_int);
    let at_origin = placed(intruder, intruder_turn, tca, DVec3::ZERO);
    let relative = velocity(&at_origin, tca) - velocity(&own, tca);
    let across = relative.cross(DVec3::Z).normalize_or_zero();
    let across = if across == DVec3::ZERO {
        DVec3::X
    } else {
        across
    };
    let hmd_m = settings.hmd_m.sample(rng);
    let intruder_at =
        DVec3::new(own_at.x, own_at.y, intruder[tca].position_enu_m.z) + across * hmd_m;
    let intruder = placed(intruder, intruder_turn, tca, intruder_at);
    let start = intruder[0].1 - own[0].1;
    if start.z.abs() < settings.min_start_vertical_m
        && start.truncate().length() < settings.min_start_horizontal_m
    {
        return None;
    }
    let w = heading_norm_ftps(s_own, s_int, dvz_ftps)
        * hmd_weight(hmd_m, &settings.hmd_m, settings.max_hmd_m)
        / keep;
    Some(Paired {
        own,
        intruder,
        hmd_m,
        vmd_m,
        w,
    })
}

/// One encounter: pairs drawn until one is kept.
fn encounter(model: &Model, settings: &PairingSettings, rng: &mut ChaCha8Rng) -> Result<Paired> {
    for _ in 0..MAX_PAIR_TRIES {
        let own = sample(model, settings.duration_s, rng)?;
        let intruder = sample(model, settings.duration_s, rng)?;
        if let Some(p) = pair(&own, &intruder, settings, rng) {
            return Ok(p);
        }
    }
    Err(Error::Usage(format!(
        "--pairing: no pair of model tracks met the VMD bins and the start separation in \
         {MAX_PAIR_TRIES} draws"
    )))
}

/// The encounters, as manifest rows (`options.duration_s` is the settings' `sample_time`).
pub fn encounters(
    options: &GenOptions,
    model: &Model,
    settings: &PairingSettings,
) -> Result<Vec<Run>> {
    crate::batch::gen::check(options)?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    (0..options.n)
        .map(|i| {
            let p = encounter(model, settings, &mut rng)?;
            Ok(Run {
                id: Some(format!("enc-{i:06}")),
                scene: options.scene.clone(),
                mode: Some(options.mode.clone()),
                own: Some(waypoints(&p.own)),
                intruder: Some(waypoints(&p.intruder)),
                intruder_kind: Some(options.intruder_kind.clone()),
                rate_hz: Some(options.rate_hz),
                duration_s: Some(settings.duration_s as f64),
                tca_s: Some(settings.tca_s as f64),
                hmd_at_tca_m: Some(p.hmd_m.abs()),
                vmd_at_tca_m: Some(p.vmd_m),
                pair: Some(format!("enc-{i:06}")),
                w: Some(p.w),
                seed: Some(options.seed),
                ..Run::default()
            })
        })
        .collect()
}
