//! Shared by the crates that draw PNGs (feature `plot`): plotters finds no system fonts on a
//! fresh machine, so the figures use the DejaVu Sans bundled in the `dejavu` crate.

use plotters::style::{FontStyle, register_font};
use std::path::Path;
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

/// Writes the RGB picture of `size` pixels as a PNG beside `path` and renames it into place,
/// so a reader never sees half a figure; a failed write (a full disk) leaves no partial file
/// taking space.
pub fn write_png(path: &Path, size: (u32, u32), rgb: &[u8]) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = std::path::PathBuf::from(tmp);
    let written = encode_png(size, rgb)
        .and_then(|png| std::fs::write(&tmp, png))
        .and_then(|()| std::fs::rename(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

fn encode_png((w, h): (u32, u32), rgb: &[u8]) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(std::io::Error::other)?;
    w.write_image_data(rgb).map_err(std::io::Error::other)?;
    w.finish().map_err(std::io::Error::other)?;
    Ok(out)
}
