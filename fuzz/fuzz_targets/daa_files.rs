//! DAIDALUS files through savsim's readers: the input split at its first NUL byte into a
//! configuration and a state file, both parsed, and, when both read, the alerting run and its
//! CSV written (every number a file can hold is bounded before it sizes anything). The whole
//! input is also read as an MIT LL encounter model and, when it reads, a track sampled.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(model) = savsim::daa::encounter_model::Model::parse(text) {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let _ = savsim::daa::encounter_model::track(&model, 30, &mut rng);
    }
    let (conf, daa) = text.split_once('\0').unwrap_or((text, text));
    let config = savsim::daa::conf::Config::parse(conf);
    let steps = savsim::daa::scenario::parse(daa);
    if let (Ok(config), Ok(steps)) = (config, steps) {
        let rows = savsim::daa::alerting_run::alert_rows(&steps, &config);
        let _ = savsim::daa_csv::csv(&config, &rows, 6);
    }
});
