//! Progress bars on standard error for the stages' long loops.

use coarsen_stage::Progress;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Duration;

/// Draws one bar per step a stage begins; hidden when standard error is not a terminal
/// or with `--quiet`, and never written to standard output.
pub struct Bars {
    visible: bool,
    current: Mutex<Option<ProgressBar>>,
}

impl Bars {
    /// Bars that show only when `!quiet` and standard error is a terminal.
    pub fn new(quiet: bool) -> Self {
        Bars {
            visible: !quiet && std::io::stderr().is_terminal(),
            current: Mutex::new(None),
        }
    }

    fn with(&self, f: impl FnOnce(&mut Option<ProgressBar>)) {
        if self.visible
            && let Ok(mut guard) = self.current.lock()
        {
            f(&mut guard);
        }
    }
}

impl Progress for Bars {
    fn begin(&self, label: &str, total: u64) {
        self.with(|slot| {
            if let Some(old) = slot.take() {
                old.finish_and_clear();
            }
            let bar = if total > 0 {
                let style = ProgressStyle::with_template(
                    "{prefix:>16} [{bar:30}] {pos}/{len} {msg} ({eta})",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> ");
                ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr())
                    .with_style(style)
            } else {
                let style = ProgressStyle::with_template("{prefix:>16} {spinner} {pos} {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner());
                ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr()).with_style(style)
            };
            bar.set_prefix(label.to_string());
            bar.enable_steady_tick(Duration::from_millis(120));
            *slot = Some(bar);
        });
    }

    fn advance(&self, done: u64, message: &str) {
        self.with(|slot| {
            if let Some(bar) = slot {
                bar.set_position(done);
                if !message.is_empty() {
                    bar.set_message(message.to_string());
                }
            }
        });
    }

    fn end(&self) {
        self.with(|slot| {
            if let Some(bar) = slot.take() {
                bar.finish_and_clear();
            }
        });
    }
}

/// Sets up leveled logs on standard error: off by default, `-v` info, `-vv` debug, `-vvv` trace.
pub fn init_logs(verbosity: u8) {
    let level = match verbosity {
        0 => return,
        1 => tracing::Level::INFO,
        2 => tracing::Level::DEBUG,
        _ => tracing::Level::TRACE,
    };
    let _ = tracing_subscriber::fmt()
        .with_max_level(level)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false)
        .try_init();
}
