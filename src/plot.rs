//! Shared plotting setup: plotters renders text with an embedded font (DejaVu Sans, see
//! `assets/DejaVuSans.LICENSE`) so figures render the same on any machine, with no system fonts.

use std::sync::OnceLock;

use plotters::style::FontStyle;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Register the embedded font with plotters (idempotent). Call before drawing any text.
pub fn init_fonts() -> anyhow::Result<()> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        for style in [
            FontStyle::Normal,
            FontStyle::Bold,
            FontStyle::Italic,
            FontStyle::Oblique,
        ] {
            plotters::style::register_font("sans-serif", style, FONT)
                .map_err(|_| "embedded font is not a valid TrueType font".to_string())?;
        }
        Ok(())
    })
    .clone()
    .map_err(anyhow::Error::msg)
}
