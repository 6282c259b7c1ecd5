//! The `ideal` feed: an exact, levelled ring of 72 rays from the vehicle's reference point (the
//! proximity sectors and OBSTACLE_DISTANCE), exact up and down rays (the rangefinder), ADS-B of
//! every other aircraft at the ADS-B rate, exact and on time, and COLLISION for savsim's own
//! threats.

use glam::DVec3;

use super::aircraft::{aircraft, body_velocity};
use super::sectors::{self, Levelled};
use super::{
    at_or_after, threats, wire, Feed, Frame, FrameInput, Reading, ORIENTATION_DOWN, ORIENTATION_UP,
};
use crate::pipeline::{Pipeline, Rays};

impl Feed {
    /// The range sensors: proximity sectors and up, OBSTACLE_DISTANCE, the rangefinder.
    pub(super) fn range_readings(&mut self, pipeline: &mut Pipeline, f: &mut Frame<'_, '_>) {
        let cfg = &self.config;
        let kinds = cfg.kinds;
        let attitude = &f.input.current.attitude;
        let down_enu = (attitude.enu_from_frd * DVec3::Z).normalize_or(-f.up_enu);
        let levelled = Levelled::new(attitude.forward_enu(), down_enu, f.up_enu);
        let mut caster = Caster {
            pipeline,
            input: f.input,
            max_m: cfg.range.max_m,
        };
        if let (true, Some(levelled)) = (kinds.needs_bins(), levelled) {
            levelled.bin_directions(&mut self.dirs);
            caster.cast(&self.dirs, &mut self.bins);
        }
        let readings = &mut self.readings;
        if let (true, Some(levelled)) = (kinds.proximity, levelled) {
            for (id, &o) in cfg.orientations.iter().enumerate() {
                let (dir_enu, distance_m) = if o == ORIENTATION_UP {
                    (f.up_enu, caster.one(f.up_enu))
                } else {
                    let centre = levelled.direction(f64::from(o) * 45.0);
                    (
                        centre,
                        sectors::sector_from_bins(&self.bins, usize::from(o)),
                    )
                };
                readings.push(Reading {
                    dir_enu,
                    distance_m,
                });
                let m = wire::distance_sensor(
                    f.stamp,
                    cfg.range,
                    distance_m,
                    o,
                    cfg.sensor_type,
                    id as u8,
                );
                f.push(m);
            }
        }
        if let (true, Some(_)) = (kinds.obstacle_distance, levelled) {
            readings.extend(
                self.dirs
                    .iter()
                    .zip(&self.bins)
                    .map(|(&dir_enu, &distance_m)| Reading {
                        dir_enu,
                        distance_m,
                    }),
            );
            f.push(wire::obstacle_distance(
                f.stamp,
                cfg.range,
                &self.bins,
                cfg.sensor_type,
            ));
        }
        if kinds.rangefinder {
            let mut distance_m = caster.one(down_enu);
            if !caster.pipeline.has_terrain() {
                // No terrain: the ground is the ellipsoid's surface at the origin's height.
                let ground = f.input.plane.distance_to_height_m(
                    f.input.current.position_enu_m,
                    down_enu,
                    cfg.range.max_m,
                    f.input.plane.origin().alt_m,
                );
                distance_m = nearest(distance_m, ground);
            }
            readings.push(Reading {
                dir_enu: down_enu,
                distance_m,
            });
            let id = cfg.orientations.len() as u8;
            f.push(wire::distance_sensor(
                f.stamp,
                cfg.range,
                distance_m,
                ORIENTATION_DOWN,
                cfg.sensor_type,
                id,
            ));
        }
    }

    /// ADSB_VEHICLE for each aircraft within the ADS-B radius, at the ADS-B rate.
    pub(super) fn adsb(&mut self, f: &mut Frame<'_, '_>) {
        let cfg = &self.config;
        let v = self.vehicles.entry(f.input.sender).or_default();
        if v.next_adsb_ms
            .is_some_and(|next| !at_or_after(f.stamp, next))
        {
            return;
        }
        let period_ms = (1000.0 / cfg.adsb_hz).round().max(1.0) as u32;
        v.next_adsb_ms = Some(f.stamp.wrapping_add(period_ms));
        for (aircraft, body) in aircraft(f.input) {
            if f.within_adsb_radius(body.current.position_enu_m) {
                f.push_adsb(&aircraft, 0.0);
            }
        }
    }

    /// COLLISION for each aircraft whose straight-on course enters the threat volume.
    pub(super) fn collisions(&mut self, f: &mut Frame<'_, '_>) {
        let current = f.input.current;
        let to_local = f
            .input
            .plane
            .plane_enu_from_local_enu_at(&current.position)
            .transpose();
        for (aircraft, body) in aircraft(f.input) {
            // In the local ENU axes at the vehicle: "horizontal" and "vertical" are its own.
            let threat = threats::threat(
                DVec3::ZERO,
                to_local * current.velocity_enu_mps,
                to_local * (body.current.position_enu_m - current.position_enu_m),
                to_local * body_velocity(body),
                &self.config,
            );
            if let Some(threat) = threat {
                f.push(threats::collision(aircraft.icao_address, &threat));
            }
        }
    }
}

/// Exact rays from the vehicle into the scene and the other moving bodies.
struct Caster<'p, 'i> {
    pipeline: &'p mut Pipeline,
    input: &'i FrameInput<'i>,
    max_m: f64,
}

impl Caster<'_, '_> {
    fn cast(&mut self, dirs: &[DVec3], out: &mut [Option<f64>]) {
        let rays = Rays {
            origin_enu_m: self.input.current.position_enu_m,
            dirs_enu: dirs,
            max_m: self.max_m,
        };
        let own = self.input.key.source();
        self.pipeline
            .cast_exact_rays(self.input.scene, own, self.input.dynamic, rays, out);
    }

    fn one(&mut self, dir: DVec3) -> Option<f64> {
        let mut hit = [None];
        self.cast(&[dir], &mut hit);
        hit[0]
    }
}

fn nearest(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}
