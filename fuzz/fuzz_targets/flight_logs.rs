//! PX4 ULog and ArduPilot DataFlash logs through savsim's readers: the input read as a ULog
//! (formats, subscriptions, dropouts, appended data, resync) and as a DataFlash log (FMT-defined
//! messages, skipped bytes counted), each into the flight log `replay` flies (positions,
//! attitudes, traffic by the documented topic policy). Neither may panic, hang or allocate
//! without bound, whatever the bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = savsim::logs::flightlog::LogKind::of(data);
    if let Ok(log) = savsim::logs::flightlog::read_ulog(data) {
        assert!(log.reports.windows(2).all(|w| w[0].t_us <= w[1].t_us));
    }
    let log = savsim::logs::flightlog::read_dataflash(data);
    assert!(log.reports.windows(2).all(|w| w[0].t_us <= w[1].t_us));
});
