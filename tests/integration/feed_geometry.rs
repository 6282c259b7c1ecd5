//! The feed's geometry far from the scene's origin: the rangefinder reads the height above the
//! ellipsoid where there is no terrain, sectors are level where the vehicle is, ADS-B heading
//! and climb are the aircraft's own and far aircraft are not sent, and COLLISION reports
//! traffic already inside its volume.

use std::sync::Arc;

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{MavAutopilot, MavMessage, MavType};
use savsim::feed::{FeedConfig, FeedKinds};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;

use crate::common::{feed, frame_v2, heartbeat, pose_messages, rangefinder_m, scene_at};

const ORIGIN: Geodetic = Geodetic::new(-35.363261, 149.165230, 584.0);

/// A session over `scene` (no terrain) with `--feed LIST` and the ADS-B radius given, a vehicle
/// heartbeat taken.
fn fed_session(scene: &str, list: &str, adsb_radius_m: f64) -> Session {
    fed_session_with(scene, list, adsb_radius_m, "ideal")
}

/// [`fed_session`] with the vehicles' `sensors` (as `--sensors`).
fn fed_session_with(scene: &str, list: &str, adsb_radius_m: f64, sensors: &str) -> Session {
    let mut session = Session::new(
        Some(Arc::new(scene_at(ORIGIN, scene))),
        CollisionConfig::default(),
        None,
    )
    .unwrap();
    session
        .start_feed(FeedConfig {
            kinds: FeedKinds::parse(list).unwrap(),
            adsb_radius_m,
            sensors: savsim::sensors::suite::Suite::parse(sensors, |_| Err(String::new())).unwrap(),
            ..FeedConfig::default()
        })
        .unwrap();
    let hb = heartbeat(
        MavType::MAV_TYPE_QUADROTOR,
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
    );
    feed(&mut session, 10.0, &frame_v2(1, 1, 0, &hb));
    feed(&mut session, 10.0, &frame_v2(2, 1, 0, &hb));
    session
}

/// Vehicle `sysid` level at the geodetic `at`, nose north, stamped `t_ms`; returns what the
/// feed sent it.
fn hover_at(session: &mut Session, sysid: u8, at: Geodetic, t_ms: u32) -> Vec<MavMessage> {
    let plane = LocalTangentPlane::new(ORIGIN);
    let p = plane.enu_m_from_geodetic(&at);
    let mut bytes = Vec::new();
    for (k, m) in pose_messages(&plane, t_ms, p, DVec3::ZERO, [0.0, 0.0, 0.0])
        .iter()
        .enumerate()
    {
        bytes.extend(frame_v2(sysid, 1, k as u8, m));
    }
    feed(session, 10.0 + f64::from(t_ms) / 1e3, &bytes);
    session
        .drain_feed()
        .filter(|m| m.to.system_id == sysid)
        .map(|m| m.message)
        .collect()
}

/// `metres` east of the origin, `up_m` above the ellipsoid at the origin's height.
fn east_of_origin(metres: f64, up_m: f64) -> Geodetic {
    // Longitude per metre east at the origin's latitude (WGS84 prime vertical radius).
    let (a, e2) = (6_378_137.0, 6.694_379_990_14e-3);
    let lat = ORIGIN.lat_deg.to_radians();
    let n = a / (1.0 - e2 * lat.sin().powi(2)).sqrt();
    Geodetic::new(
        ORIGIN.lat_deg,
        ORIGIN.lon_deg + (metres / (n * lat.cos())).to_degrees(),
        ORIGIN.alt_m + up_m,
    )
}

#[test]
fn with_no_terrain_the_rangefinder_reads_the_height_above_the_ellipsoid_far_from_the_origin() {
    let mut session = fed_session("", "rangefinder", 2000.0);
    for (i, east_m) in [0.0, 10_000.0, 30_000.0].into_iter().enumerate() {
        let sent = hover_at(
            &mut session,
            1,
            east_of_origin(east_m, 20.0),
            1000 + 100 * i as u32,
        );
        let got = rangefinder_m(&sent);
        // Before its fix the ground was the plane through the origin: 7.8 m higher 10 km out.
        assert!(
            got.is_some_and(|g| (g - 20.0).abs() <= 0.011),
            "{east_m} m east, 20 m up: rangefinder {got:?}"
        );
    }
}

#[test]
fn levelled_sectors_are_level_where_the_vehicle_is() {
    let mut session = fed_session("", "proximity", 2000.0);
    let plane = LocalTangentPlane::new(ORIGIN);
    let at = east_of_origin(100_000.0, 50.0);
    hover_at(&mut session, 1, at, 1000);
    let p = plane.enu_m_from_geodetic(&at);
    let readings = session.feed().unwrap().readings().to_vec();
    assert_eq!(readings.len(), 9);
    for r in readings.iter().filter(|r| r.dir_enu.z.abs() < 0.5) {
        // 30 m along a level ray the height above the ellipsoid changes by the earth's
        // curvature only (0.07 mm); before its fix the rays were level in the scene's plane, 0.9
        // degrees off 100 km out.
        let climb_m = plane.geodetic_from_enu_m(p + r.dir_enu * 30.0).alt_m - at.alt_m;
        assert!(
            climb_m.abs() < 1e-3,
            "{:?}: climbs {climb_m} m over 30 m",
            r.dir_enu
        );
    }
}

#[test]
fn adsb_heading_and_climb_are_the_aircrafts_own_and_far_aircraft_are_not_sent() {
    let plane = LocalTangentPlane::new(ORIGIN);
    // A track 50 km east, flying along the scene's north axis at 100 m/s, level in the
    // scene's plane.
    let start = plane.enu_m_from_geodetic(&east_of_origin(50_000.0, 300.0));
    let end = start + DVec3::new(0.0, 6000.0, 0.0);
    let scene = format!(
        "[[dynamic]]\nid = \"far\"\nkind = \"a320\"\nwaypoints = [ {{ t_s = 0.0, position_enu_m = {:?} }}, {{ t_s = 60.0, position_enu_m = {:?} }} ]\n",
        start.to_array(),
        end.to_array()
    );
    let mut session = fed_session(&scene, "adsb", 60_000.0);
    hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 1000);
    let sent = hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 2000);
    let Some(MavMessage::ADSB_VEHICLE(a)) = sent
        .iter()
        .find(|m| matches!(m, MavMessage::ADSB_VEHICLE(_)))
    else {
        panic!("no ADSB_VEHICLE in {sent:?}")
    };
    // The truth from two geodetic points 1 s apart on the track (ellipsoidal radii).
    let t_s = 1.0;
    let p0 = plane.geodetic_from_enu_m(start + (end - start) * (t_s / 60.0));
    let p1 = plane.geodetic_from_enu_m(start + (end - start) * ((t_s + 1.0) / 60.0));
    let (a_m, e2) = (6_378_137.0, 6.694_379_990_14e-3);
    let lat = p0.lat_deg.to_radians();
    let w = (1.0 - e2 * lat.sin().powi(2)).sqrt();
    let (m_r, n_r) = (a_m * (1.0 - e2) / w.powi(3), a_m / w);
    let north = (p1.lat_deg - p0.lat_deg).to_radians() * (m_r + p0.alt_m);
    let east = (p1.lon_deg - p0.lon_deg).to_radians() * (n_r + p0.alt_m) * lat.cos();
    let heading_cdeg = (east.atan2(north).to_degrees().rem_euclid(360.0) * 100.0).round();
    let climb_cms = ((p1.alt_m - p0.alt_m) * 100.0).round();
    assert!(
        (f64::from(a.heading) - heading_cdeg).abs() <= 1.0,
        "heading {} cdeg, the track's own {heading_cdeg}",
        a.heading
    );
    assert!(
        (f64::from(a.ver_velocity) - climb_cms).abs() <= 1.0,
        "vertical speed {} cm/s, the track's own {climb_cms}",
        a.ver_velocity
    );

    // Two vehicles 3 km apart do not hear of each other with the default radius; 1 km apart do.
    for (apart_m, heard) in [(3000.0, false), (1000.0, true)] {
        let mut session = fed_session("", "adsb", 2000.0);
        hover_at(&mut session, 2, east_of_origin(apart_m, 30.0), 1000);
        let sent = hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 1000);
        let adsb = sent
            .iter()
            .filter(|m| matches!(m, MavMessage::ADSB_VEHICLE(_)))
            .count();
        assert_eq!(adsb, usize::from(heard), "{apart_m} m apart");
    }
}

/// `--feed-adsb-radius-m` is one rule whatever the sensors: with a modelled ADS-B receiver
/// (`adsb-1090es` receives to 20 NM; `ideal-adsb` is exact), a vehicle 3.2 km, 5 NM and 15 NM
/// off is not sent with the default 2000 m (it was, before), and is sent with a radius past it.
#[test]
fn the_adsb_radius_holds_for_modelled_receivers_too() {
    for sensors in ["ideal-adsb", "adsb-1090es:nacp=10"] {
        for apart_m in [3200.0, 9260.0, 27780.0] {
            for (radius_m, heard) in [(2000.0, false), (apart_m + 500.0, true)] {
                let mut session = fed_session_with("", "adsb", radius_m, sensors);
                let mut sent = 0;
                // 20 s at 10 Hz: Appendix Q's reception gets a report through in that time.
                for t_ms in (1000..21_000).step_by(100) {
                    hover_at(&mut session, 2, east_of_origin(apart_m, 30.0), t_ms);
                    sent += hover_at(&mut session, 1, east_of_origin(0.0, 30.0), t_ms)
                        .iter()
                        .filter(|m| matches!(m, MavMessage::ADSB_VEHICLE(_)))
                        .count();
                }
                assert_eq!(
                    sent > 0,
                    heard,
                    "{sensors}: {apart_m} m apart, radius {radius_m} m: {sent} sent"
                );
            }
        }
    }
}

#[test]
fn collision_reports_traffic_already_inside_its_volume_whatever_the_time_to_closest() {
    let plane = LocalTangentPlane::new(ORIGIN);
    let at = plane.enu_m_from_geodetic(&east_of_origin(0.0, 30.0));
    // 100 m east at the vehicle's height, closing at 1 m/s: closest approach in 100 s.
    let a = at + DVec3::new(100.0, 0.0, 0.0);
    let b = at + DVec3::new(-100.0, 0.0, 0.0);
    let scene = format!(
        "[[dynamic]]\nid = \"slow\"\nkind = \"balloon\"\nwaypoints = [ {{ t_s = 0.0, position_enu_m = {:?} }}, {{ t_s = 200.0, position_enu_m = {:?} }} ]\n",
        a.to_array(),
        b.to_array()
    );
    let mut session = fed_session(&scene, "collision", 2000.0);
    hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 1000);
    let sent = hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 2000);
    assert!(
        sent.iter().any(|m| matches!(m, MavMessage::COLLISION(_))),
        "no COLLISION for a balloon 99 m away: {sent:?}"
    );
}
