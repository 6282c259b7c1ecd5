//! DAIDALUS files through savsim's readers: the input split at its first NUL byte into a
//! configuration and a state file, both parsed, and, when both read, the alerting run and its
//! CSV written (every number a file can hold is bounded before it sizes anything).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let (conf, daa) = text.split_once('\0').unwrap_or((text, text));
    let config = savsim::daa::conf::Config::parse(conf);
    let steps = savsim::daa::scenario::parse(daa);
    if let (Ok(config), Ok(steps)) = (config, steps) {
        let rows = savsim::daa::alerting_run::alert_rows(&steps, &config);
        let _ = savsim::daa_csv::csv(&config, &rows, 6);
    }
});
