//! Who a row's vehicles are: the SITL instance each runs on (so its ports and folder) and its
//! MAVLink system id, for up to [`MAX_VEHICLES`] vehicles a row and [`MAX_JOBS`] rows at once.

use crate::study::sitl::px4_autopilot;
use crate::world::SenderId;

/// The most SITLs at once.
pub const MAX_JOBS: usize = 64;

/// A row's vehicle `k` (from 0) runs on SITL instance `instance + k x INSTANCE_OFFSET` (its
/// own ports): past the instances `--jobs` can take.
pub const INSTANCE_OFFSET: u16 = MAX_JOBS as u16;

/// The most vehicles a row may fly: PX4 SITL's system id is its instance + 1, so a third
/// vehicle's (instance under `3 x INSTANCE_OFFSET`) is at most 192, and a fourth's would not
/// fit in MAVLink's 255 beside the ArduCopters' ([`arducopter_sysid`]).
pub const MAX_VEHICLES: usize = 3;

/// The SYSID_THISMAV of a row's vehicle `k` (from 1) after its first when it is an
/// ArduCopter: 200 + k (201 for the second). No PX4 vehicle of a row has it (PX4 SITL's system
/// id is its instance + 1, at most `MAX_VEHICLES x INSTANCE_OFFSET`).
pub fn arducopter_sysid(k: usize) -> u8 {
    200 + k.min(MAX_VEHICLES) as u8
}

/// The identity of a row's vehicle `k` (from 0): ArduCopter SITL's default SYSID_THISMAV 1
/// for the first (whatever its instance), [`arducopter_sysid`] for the others; PX4 SITL sets
/// MAV_SYS_ID to its instance + 1. Component 1, the autopilot.
pub(super) fn autopilot_id(px4: bool, instance: u16, k: usize) -> SenderId {
    if px4 {
        px4_autopilot(instance)
    } else {
        SenderId {
            system_id: if k == 0 { 1 } else { arducopter_sysid(k) },
            component_id: 1,
        }
    }
}
