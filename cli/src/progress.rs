//! Progress bars on stderr (indicatif), drawn only when stderr is a terminal: a run whose
//! stderr goes to a file or a pipe shows nothing.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A bar of `len` steps drawn with `template` (indicatif's syntax) at most `hz` times a second,
/// hidden when stderr is not a terminal.
pub(crate) fn bar(len: u64, template: &str, hz: u8) -> ProgressBar {
    let target = if std::io::stderr().is_terminal() {
        ProgressDrawTarget::stderr_with_hz(hz)
    } else {
        ProgressDrawTarget::hidden()
    };
    let style = ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar());
    ProgressBar::with_draw_target(Some(len), target).with_style(style.progress_chars("#-"))
}
