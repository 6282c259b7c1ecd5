//! The charts' font: DejaVu Sans Mono, bundled (assets/fonts/DejaVu-LICENSE.txt), registered
//! with plotters as `sans-serif` so that charts are laid out the same on every machine without
//! system fonts (the bench's PNG; the reports' SVG, whose text a browser draws in its own
//! sans-serif at the sizes laid out here).

use std::sync::Once;

use plotters::style::{register_font, FontStyle};

use crate::error::{Error, Result};

static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSansMono.ttf");

/// Register the font (once per process).
pub fn font() -> Result<()> {
    static REGISTER: Once = Once::new();
    let mut failed = false;
    REGISTER.call_once(|| failed = register_font("sans-serif", FontStyle::Normal, FONT).is_err());
    if failed {
        return Err(Error::Usage("the bundled chart font does not load".into()));
    }
    Ok(())
}
