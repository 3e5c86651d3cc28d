//! Shared by the crates that draw PNGs (feature `plot`): plotters finds no system fonts on a
//! fresh machine, so the figures use the DejaVu Sans bundled in the `dejavu` crate.

use plotters::style::{FontStyle, register_font};
use std::sync::OnceLock;

/// The family name the figures use; [`register_fonts`] maps it to DejaVu Sans.
pub const FONT: &str = "sans-serif";

/// Registers the bundled regular and bold faces under [`FONT`], once per process; fails
/// when the bundled font cannot be parsed (nothing can be drawn with text then).
pub fn register_fonts() -> Result<(), &'static str> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok()
            && register_font(FONT, FontStyle::Bold, dejavu::sans::bold()).is_ok()
    });
    ok.then_some(())
        .ok_or("the bundled DejaVu font could not be parsed")
}
