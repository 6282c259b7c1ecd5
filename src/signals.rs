//! SIGINT and SIGTERM: the first sets the shutdown flag (the run stops cleanly and writes its
//! events, summary and recordings); a second SIGINT exits at once.

use std::io;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use signal_hook::consts::{SIGINT, SIGTERM};

/// Install the handlers on `shutdown`.
pub fn install(shutdown: Arc<AtomicBool>) -> io::Result<()> {
    for signal in [SIGINT, SIGTERM] {
        signal_hook::flag::register_conditional_shutdown(signal, 130, shutdown.clone())?;
        signal_hook::flag::register(signal, shutdown.clone())?;
    }
    Ok(())
}
