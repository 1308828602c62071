//! Progress bars on the terminal, for long preparation (the compliance
//! precompute, a study's runs, a replay's frames).
//!
//! In: a length, a message and a template. Out: an indicatif bar on stderr,
//! hidden when stderr is not a terminal (CI logs, pipes). Stays true: never
//! panics on a bad template (falls back to the plain bar).

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressStyle};

/// `{msg} [bar] pos/len (eta)` with the message right-aligned in 12 columns.
pub const DEFAULT_TEMPLATE: &str = "{msg:>12} [{bar:40}] {pos}/{len} ({eta})";

/// A bar of `len` steps on stderr showing `message`, drawn with `template`.
pub fn terminal_bar(len: u64, message: &str, template: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    bar.set_style(ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar()));
    bar.set_message(message.to_string());
    bar
}
