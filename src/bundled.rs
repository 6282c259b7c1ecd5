//! Files that come with savsim: the demo flight and the scenes.

use std::path::{Path, PathBuf};

/// Where bundled files live: the working directory, else the source tree savsim was built from.
pub fn bundled(relative: &str) -> PathBuf {
    let here = PathBuf::from(relative);
    if here.exists() {
        here
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
    }
}

/// The bundled demo flight.
pub const DEMO_FLIGHT: &str = "scenes/flights/copter_square_10ms.tlog";
/// The bundled city.
pub const DEMO_SCENE: &str = "scenes/city.toml";
