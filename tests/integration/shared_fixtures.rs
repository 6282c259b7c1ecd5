//! The real tlogs of ../shared/fixtures (skipped when absent): savsim's per-message counts
//! against pymavlink 2.4.50's (fixtures/expected/*.json).
//!
//! One known difference, in pymavlink: after a MAVLink 2 frame its parser expects the next
//! frame to be at least 12 bytes, so a following MAVLink 1 frame of 10 or 11 bytes (HWSTATUS,
//! MISSION_CURRENT) is over-read into the next record's timestamp and reported as "Bad
//! prefix". savsim reads those records. So where pymavlink reported bad prefixes, savsim may
//! count up to that many messages more, never fewer.

use std::collections::BTreeMap;

use crate::common::shared_fixtures;

#[derive(serde::Deserialize)]
struct Expected {
    msg_counts: BTreeMap<String, u64>,
    #[serde(default)]
    bad_data: BTreeMap<String, u64>,
    sys_comp_ids: BTreeMap<String, u64>,
}

#[test]
fn message_counts_equal_pymavlink_on_every_real_tlog() {
    let Some(dir) = shared_fixtures() else { return };
    let mut checked = 0;
    for entry in std::fs::read_dir(dir.join("tlogs")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let expected: Expected = serde_json::from_str(
            &std::fs::read_to_string(dir.join("expected").join(format!("{name}.json"))).unwrap(),
        )
        .unwrap();
        let session = crate::common::replay_into_session(&path, None);
        let stats = &session.stats();
        let got = stats.messages_by_name();
        let bad_prefix = expected.bad_data.get("Bad prefix").copied().unwrap_or(0);
        let mut extra = 0;
        for (msg, &want) in &expected.msg_counts {
            let n = got.get(msg.as_str()).copied().unwrap_or(0);
            assert!(n >= want, "{name}: {msg} {n} < pymavlink's {want}");
            extra += n - want;
        }
        for (msg, n) in &got {
            assert!(
                expected.msg_counts.contains_key(*msg),
                "{name}: {msg} x{n} pymavlink did not see"
            );
        }
        assert!(
            extra <= bad_prefix,
            "{name}: {extra} more than pymavlink, which had {bad_prefix} bad prefixes"
        );
        if bad_prefix == 0 {
            let senders: BTreeMap<String, u64> = stats
                .by_sender
                .iter()
                .map(|(k, v)| (k.to_string(), *v))
                .collect();
            assert_eq!(senders, expected.sys_comp_ids, "{name}: per sender");
        }
        checked += 1;
    }
    assert!(checked >= 12, "only {checked} tlogs");
}

#[test]
fn bad_crc_frames_of_other_dialects_are_skipped_by_length() {
    let Some(dir) = shared_fixtures() else { return };
    let path = dir.join("tlogs/ardusub_log_tools__pymavlink_bug_2023-04-18_11-03-34.tlog");
    let session = crate::common::replay_into_session(&path, None);
    assert_eq!(session.stats().bad_crc, 1967);
    assert_eq!(session.stats().garbage_bytes, 0, "stayed aligned");
}
