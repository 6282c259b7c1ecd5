//! Framing, decoding and bad input; tlogs written by pymavlink replay to pymavlink's counts.

use std::collections::BTreeMap;

use glam::DVec3;
use savsim::codec::decode::{decode, Rejection, Report};
use savsim::codec::frame::{scan, FrameStatus, Scan};
use savsim::codec::stats::{IngestStats, SequenceCounts};
use savsim::codec::Ingestor;
use savsim::geo::Geodetic;
use savsim::links::stream::frames_in_datagram;
use savsim::logs::tlog::{TlogReader, TlogWriter};
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;
use savsim::world::SenderId;
use savsim::world::{WorldConfig, WorldStore};

use mavlink::dialects::ardupilotmega::{MavMessage, ATTITUDE_DATA, GLOBAL_POSITION_INT_DATA};
use mavlink::{MavHeader, MavlinkVersion};

use crate::common::{feed, frame_v2, have_pymavlink, python, root};

fn frame(version: MavlinkVersion, system_id: u8, message: &MavMessage) -> Vec<u8> {
    let mut buf = Vec::new();
    let header = MavHeader {
        system_id: u32::from(system_id),
        component_id: 1,
        sequence: 0,
    };
    mavlink::write_versioned_msg(&mut buf, version, header, message).unwrap();
    buf
}

fn position(time_boot_ms: u32, lat: i32, lon: i32, alt_mm: i32) -> MavMessage {
    MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        time_boot_ms,
        lat,
        lon,
        alt: alt_mm,
        relative_alt: 0,
        vx: 100,
        vy: -200,
        vz: 50,
        hdg: 9000,
    })
}

fn attitude(time_boot_ms: u32, roll: f32) -> MavMessage {
    MavMessage::ATTITUDE(ATTITUDE_DATA {
        time_boot_ms,
        roll,
        pitch: 0.1,
        yaw: 1.0,
        rollspeed: 0.0,
        pitchspeed: 0.0,
        yawspeed: 0.0,
    })
}

fn tlog(records: &[(u64, Vec<u8>)]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut w = TlogWriter::new(&mut out);
    for (t, f) in records {
        w.write_record(*t, f).unwrap();
    }
    out
}

fn replay_bytes(bytes: &[u8]) -> (IngestStats, usize) {
    let mut ingestor = Ingestor::default();
    let mut reader = TlogReader::new(bytes);
    let mut decoded = 0;
    while let Some(r) = reader.next_record(&mut ingestor.stats).unwrap() {
        decoded += usize::from(ingestor.frame(&r.frame).is_some());
    }
    (ingestor.stats, decoded)
}

#[test]
fn decodes_units_once() {
    let bytes = frame(
        MavlinkVersion::V2,
        1,
        &position(5000, -353632610, 1491652300, 584_090),
    );
    let Scan::Frame(f) = scan(&bytes) else {
        panic!()
    };
    assert_eq!(f.status, FrameStatus::Valid);
    let Ok(Some(Report::Position(p))) = decode(&f) else {
        panic!()
    };
    assert_eq!(p.time_boot_ms, 5000);
    assert!((p.position.lat_deg + 35.363261).abs() < 1e-9);
    assert!((p.position.alt_m - 584.09).abs() < 1e-9);
    assert!((p.velocity_ned_mps - glam::DVec3::new(1.0, -2.0, 0.5)).length() < 1e-12);
    assert_eq!(p.heading_deg, Some(90.0));
}

#[test]
fn rejects_no_fix_out_of_range_and_nan() {
    for (message, reason) in [
        (position(1, 0, 0, 0), Rejection::NoFix),
        (position(1, 950_000_000, 0, 0), Rejection::LatLonOutOfRange),
        (
            position(1, 0, 1_900_000_000, 0),
            Rejection::LatLonOutOfRange,
        ),
        (attitude(1, f32::NAN), Rejection::NonFiniteAttitude),
        (attitude(1, f32::INFINITY), Rejection::NonFiniteAttitude),
    ] {
        let bytes = frame(MavlinkVersion::V1, 1, &message);
        let Scan::Frame(f) = scan(&bytes) else {
            panic!()
        };
        assert_eq!(decode(&f), Err(reason));
    }
}

#[test]
fn garbage_and_bad_crc_are_skipped_and_counted_with_resync() {
    let good = frame(MavlinkVersion::V2, 1, &attitude(1, 0.1));
    let mut bad = good.clone();
    let last = bad.len() - 1;
    bad[last] ^= 0x55;
    let records = [(1_000, good.clone()), (2_000, bad), (3_000, good.clone())];
    let mut bytes = tlog(&records[..2]);
    bytes.extend_from_slice(&[0x00, 0xfe, 0x13, 0x37, 0xfd, 0x00]); // garbage, with false magics
    bytes.extend_from_slice(&tlog(&records[2..]));
    let (stats, decoded) = replay_bytes(&bytes);
    assert_eq!(decoded, 2);
    assert_eq!(stats.bad_crc, 1);
    assert_eq!(stats.garbage_bytes, 6);
    assert_eq!(stats.resyncs, 1);
    assert_eq!(stats.tlog_records, 3);
}

#[test]
fn truncated_tlog_replays_every_whole_record_then_reports_the_cut() {
    let f = frame(MavlinkVersion::V1, 1, &attitude(1, 0.1));
    let records: Vec<_> = (0..10).map(|i| (i * 1000, f.clone())).collect();
    let whole = tlog(&records);
    for cut in [
        whole.len() - 1,
        whole.len() - f.len(),
        whole.len() - f.len() - 5,
    ] {
        let (stats, decoded) = replay_bytes(&whole[..cut]);
        let record_len = f.len() + 8;
        assert_eq!(decoded, cut / record_len, "cut at {cut}");
        let (at, left) = stats.truncated_at.expect("reported");
        assert_eq!(at as usize, cut / record_len * record_len);
        assert_eq!(left as usize, cut % record_len);
    }
}

#[test]
fn unknown_ids_and_bad_flags_are_counted() {
    // A v2 frame with an id no dialect defines, and one with an unknown incompat flag.
    let mut unknown = frame(MavlinkVersion::V2, 1, &attitude(1, 0.1));
    unknown[7] = 0xEE;
    unknown[8] = 0xEE;
    unknown[9] = 0x0E;
    let mut flagged = frame(MavlinkVersion::V2, 1, &attitude(1, 0.1));
    flagged[2] = 0x80;
    let bytes = tlog(&[(1, unknown), (2, flagged)]);
    let (stats, decoded) = replay_bytes(&bytes);
    assert_eq!(decoded, 0);
    assert_eq!(stats.unknown_ids.values().sum::<u64>(), 1);
    assert_eq!(stats.bad_incompat_flags, 1);
}

#[test]
fn datagrams_resync_inside_a_failed_frame() {
    let good = frame(MavlinkVersion::V1, 1, &attitude(1, 0.1));
    // A false start: a v2 magic whose "frame" swallows the real one and fails its CRC.
    let mut datagram = vec![0xfd, 4, 0, 0, 0, 1, 1, 30, 0, 0];
    datagram.extend_from_slice(&good);
    let mut stats = IngestStats::default();
    let mut valid = 0;
    frames_in_datagram(&datagram, |f| {
        if stats.count_frame(f) {
            valid += 1
        }
    })
    .count_into(&mut stats);
    assert_eq!(valid, 1);
}

#[test]
fn vehicle_clock_wrap_reset_and_backwards_never_panic() {
    let origin = Geodetic::new(-35.0, 149.0, 500.0);
    let mut world = WorldStore::new(origin, WorldConfig::default());
    let sender = SenderId {
        system_id: 1,
        component_id: 1,
    };
    let report = |ms: u32| {
        let bytes = frame(
            MavlinkVersion::V2,
            1,
            &position(ms, -350_000_000, 1_490_000_000, 500_000),
        );
        let Scan::Frame(f) = scan(&bytes) else {
            panic!()
        };
        decode(&f).unwrap().unwrap()
    };
    for (t, ms) in [
        (1.0, u32::MAX - 100),
        (1.1, 50),        // wrap: not a reboot
        (1.2, 10),        // small step back: a reordered message, not applied
        (1.3, 3_000_000), // forward jump
        (1.4, 200),       // reboot
        (1.0, 300),       // receive clock backwards
    ] {
        world.apply(t, sender, &report(ms));
    }
    let seen = world.seen[&sender];
    assert_eq!(seen.positions, 5);
    assert_eq!(seen.reordered, 1);
    assert_eq!(seen.boot_resets, 1);
}

#[test]
fn tlog_written_by_pymavlink_matches_pymavlink_counts() {
    if !have_pymavlink() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.tlog");
    python(
        &root().join("tests/fixtures/make_tlog.py"),
        &[path.to_str().unwrap()],
    );
    let out = python(
        &root().join("tests/fixtures/count_tlog.py"),
        &[path.to_str().unwrap()],
    );
    let want: BTreeMap<String, u64> = serde_json::from_str(out.trim()).unwrap();
    let session = crate::common::replay_into_session(&path, None);
    let stats = &session.stats();
    let got: BTreeMap<String, u64> = stats
        .messages_by_name()
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v))
        .collect();
    assert_eq!(got, want);
    // What the script planted, each counted once.
    assert_eq!(stats.rejected[&Rejection::NoFix], 10);
    assert_eq!(stats.rejected[&Rejection::LatLonOutOfRange], 1);
    assert_eq!(stats.rejected[&Rejection::NonFiniteAttitude], 1);
    assert_eq!(stats.bad_crc, 1);
    assert_eq!(stats.garbage_bytes, 37);
    assert_eq!(stats.clock_backwards, 1);
    assert!(stats.truncated_at.is_some());
    // Two vehicles and one ADS-B aircraft in the world.
    assert_eq!(session.world().seen.len(), 2);
    assert_eq!(session.world().traffic().len(), 1);
}

/// PX4 SITL started again after a shutdown is silent for 0.49 s and numbers its frames from 0
/// in the middle of the old count (docs/live.md): a restart, not 69 late frames.
#[test]
fn a_sequence_from_zero_after_a_half_second_pause_is_a_restart() {
    let mut counts = SequenceCounts::starting_at(0);
    let mut t_s = 100.0;
    for sequence in 0..=69u8 {
        counts.observe_at(sequence, t_s);
        t_s += 0.007;
    }
    t_s += 0.489;
    for sequence in 0..=200u8 {
        counts.observe_at(sequence, t_s);
        t_s += 0.007;
    }
    assert_eq!((counts.lost, counts.late, counts.restarts), (0, 0, 1));
    // A 20 ms gap of a 50 Hz stream that loses frames up to the wrap is no restart.
    let mut counts = SequenceCounts::starting_at(250);
    counts.observe_at(250, 200.0);
    counts.observe_at(0, 200.12);
    assert_eq!((counts.lost, counts.restarts), (5, 0));
}

fn adsb_frame(icao: u32, flags: u16, altitude_type: u8) -> Vec<u8> {
    use mavlink::dialects::ardupilotmega::{
        AdsbAltitudeType, AdsbEmitterType, AdsbFlags, ADSB_VEHICLE_DATA,
    };
    use num_traits::FromPrimitive;
    let m = MavMessage::ADSB_VEHICLE(ADSB_VEHICLE_DATA {
        ICAO_address: icao,
        lat: -353_600_000,
        lon: 1_491_600_000,
        altitude_type: AdsbAltitudeType::from_u8(altitude_type).unwrap(),
        altitude: 900_000,
        heading: 9_000,
        hor_velocity: 5_000,
        ver_velocity: 300,
        callsign: (*b"TEST1234\0").into(),
        emitter_type: AdsbEmitterType::ADSB_EMITTER_TYPE_LARGE,
        tslc: 1,
        flags: AdsbFlags::from_bits_truncate(flags),
        squawk: 1200,
    });
    frame_v2(50, 1, 0, &m)
}

#[test]
fn adsb_reports_are_read_by_their_flags_and_altitude_type() {
    let mut session = Session::new(None, CollisionConfig::default(), None).unwrap();
    // Coordinates and altitude valid, heading and speeds too: a moving aircraft.
    feed(&mut session, 1.0, &adsb_frame(0x10, 0x1FF, 1));
    // No valid coordinates: not a position (Mode S relays).
    feed(&mut session, 1.0, &adsb_frame(0x11, 0x1FE, 1));
    // Coordinates but no altitude: not placed.
    feed(&mut session, 1.0, &adsb_frame(0x12, 0x1FD, 1));
    // Valid position, heading and velocity not: held still, not extrapolated.
    feed(&mut session, 1.0, &adsb_frame(0x13, 0x03, 1));
    // QNH barometric altitude: kept, and counted apart.
    feed(&mut session, 1.0, &adsb_frame(0x14, 0x1FF, 0));
    let traffic: std::collections::BTreeMap<u32, &savsim::world::TrafficTrack> =
        session.world().traffic().map(|(k, v)| (*k, v)).collect();
    assert_eq!(
        traffic.keys().copied().collect::<Vec<_>>(),
        [0x10, 0x13, 0x14]
    );
    let v = |icao: u32| traffic[&icao].history.latest().unwrap().velocity_enu_mps;
    assert!(
        (v(0x10).truncate().length() - 50.0).abs() < 0.01 && v(0x10).z > 2.9,
        "{}",
        v(0x10)
    );
    assert_eq!(v(0x13), DVec3::ZERO);
    assert!(traffic[&0x14].pressure_altitude && !traffic[&0x10].pressure_altitude);
    let rejected = &session.stats().rejected;
    assert_eq!(
        rejected.get(&savsim::codec::decode::Rejection::AdsbNoPosition),
        Some(&2)
    );
}
