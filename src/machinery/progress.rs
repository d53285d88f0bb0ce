//! The progress bars of the commands that work for more than two seconds: one style, on standard
//! error, hidden when standard error is not a terminal (a pipe, a log file, CI), so captured output
//! holds no bar.

use std::io::IsTerminal as _;

use indicatif::{ProgressBar, ProgressStyle};

/// A bar of `units` steps of `what` (e.g. `"runs"`), hidden with `quiet` or when standard error is
/// not a terminal.
pub fn bar(units: u64, what: &str, quiet: bool) -> ProgressBar {
    styled(
        units,
        &format!("{{bar:30}} {{pos}}/{{len}} {what} [{{elapsed}}, about {{eta}} left]"),
        quiet,
    )
}

/// A bar of `units` steps drawn by the indicatif `template`, hidden with `quiet` or when standard
/// error is not a terminal (a template that does not parse keeps indicatif's default style).
pub fn styled(units: u64, template: &str, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(units);
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style);
    }
    bar
}
