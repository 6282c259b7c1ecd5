//! `savsim batch gen-encounters --model FILE`: encounters of two tracks sampled from an MIT
//! LL encounter model (`savsim_core::daa::encounter_model`), with turns, climbs and speed
//! changes, paired at a chosen geometry.
//!
//! Each encounter samples two tracks of the encounter's length from the model (a rejected
//! track is drawn again) and places them in the scene's ENU frame (open air unless a scene is
//! given), from a ChaCha8 stream seeded with `seed`:
//!
//! | quantity | distribution |
//! |---|---|
//! | time of closest approach (TCA) | uniform, 1/3 to 2/3 of the duration |
//! | ownship position then | uniform in a 3 km square around the origin, at its sampled altitude |
//! | each track's heading | uniform 0 to 360 deg (the track turned about its start) |
//! | horizontal miss distance at TCA | uniform 0 to 500 m, perpendicular to the relative velocity then, on a random side |
//! | vertical miss distance at TCA | uniform -100 to 100 m (intruder above positive) |
//!
//! The miss distances hold at TCA by construction (written as `tca_s`, `hmd_at_tca_m`,
//! `vmd_at_tca_m`); the tracks curve, so the closest approach may come at another time and
//! nearer (the results' `cpa_*`). The geometry is drawn from these distributions themselves,
//! so every weight `w` is 1; each encounter is its own `pair`.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::batch::gen::GenOptions;
use crate::batch::manifest::Run;
use crate::daa::encounter_model::Model;
use crate::error::{Error, Result};
use crate::runs::model_tracks::{placed, sample, velocity};

pub(crate) fn waypoints(points: &[(f64, DVec3)]) -> String {
    points
        .iter()
        .map(|(t, p)| format!("{t} {:.3} {:.3} {:.3}", p.x, p.y, p.z))
        .collect::<Vec<_>>()
        .join("; ")
}

/// The encounters, as manifest rows.
pub fn encounters(options: &GenOptions, model: &Model) -> Result<Vec<Run>> {
    crate::batch::gen::check(options)?;
    let seconds = options.duration_s.round() as usize;
    if seconds < 3 {
        return Err(Error::Usage(
            "--duration-s: at least 3 s with a model".into(),
        ));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    (0..options.n)
        .map(|i| {
            let tca_s = rng.random_range(seconds / 3..=2 * seconds / 3);
            let own = sample(model, seconds, &mut rng)?;
            let intruder = sample(model, seconds, &mut rng)?;
            let own_at = DVec3::new(
                rng.random_range(-1500.0..=1500.0),
                rng.random_range(-1500.0..=1500.0),
                own[tca_s].position_enu_m.z,
            );
            let own = placed(
                &own,
                rng.random_range(0.0..std::f64::consts::TAU),
                tca_s,
                own_at,
            );
            let intruder_turn = rng.random_range(0.0..std::f64::consts::TAU);
            // Perpendicular to the horizontal relative velocity at TCA (any horizontal
            // direction when there is none).
            let at_origin = placed(&intruder, intruder_turn, tca_s, DVec3::ZERO);
            let relative = velocity(&at_origin, tca_s) - velocity(&own, tca_s);
            let across = relative.cross(DVec3::Z).normalize_or_zero();
            let across = if across == DVec3::ZERO {
                DVec3::X
            } else {
                across
            };
            let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let hmd_m: f64 = rng.random_range(0.0..=500.0);
            let vmd_m: f64 = rng.random_range(-100.0..=100.0);
            let intruder_at = own_at + across * side * hmd_m + DVec3::Z * vmd_m;
            let intruder = placed(&intruder, intruder_turn, tca_s, intruder_at);
            Ok(Run {
                id: Some(format!("enc-{i:06}")),
                scene: options.scene.clone(),
                mode: Some(options.mode.clone()),
                own: Some(waypoints(&own)),
                intruder: Some(waypoints(&intruder)),
                intruder_kind: Some(options.intruder_kind.clone()),
                rate_hz: Some(options.rate_hz),
                duration_s: Some(seconds as f64),
                tca_s: Some(tca_s as f64),
                hmd_at_tca_m: Some(hmd_m),
                vmd_at_tca_m: Some(vmd_m),
                pair: Some(format!("enc-{i:06}")),
                w: Some(1.0),
                seed: Some(options.seed),
                ..Run::default()
            })
        })
        .collect()
}
