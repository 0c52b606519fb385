//! Progress of a run or an experiment: a bar on a terminal, a line now and then
//! elsewhere (logs, CI), and notes that do not break the bar.

use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// A progress bar of `len` with `template` when stderr is a terminal (None elsewhere:
/// callers print a line now and then instead).
pub fn terminal_bar(len: u64, template: &str) -> Option<indicatif::ProgressBar> {
    std::io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::new(len);
        b.set_style(
            indicatif::ProgressStyle::with_template(template)
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        b
    })
}

/// Progress towards `total`, reported as `who: note` lines and a bar or periodic lines.
#[derive(Debug)]
pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    who: &'static str,
    total: u64,
    /// Without a terminal: at most one line per this interval (and one at the end).
    every: Duration,
    last_line: Option<Instant>,
    /// Whether the bar stays on screen when finished.
    keep: bool,
}

impl Progress {
    /// A progress display for `who` (e.g. `fulcrum train`) towards `total`, drawn with
    /// `template` on a terminal.
    pub fn new(who: &'static str, total: u64, template: &str, every: Duration) -> Progress {
        Progress {
            bar: terminal_bar(total, template),
            who,
            total,
            every,
            last_line: None,
            keep: true,
        }
    }

    /// The bar disappears when finished.
    pub fn clear_when_finished(mut self) -> Progress {
        self.keep = false;
        self
    }

    /// The total this progress counts towards.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// A new total (a run whose plan changes as hosts come and go).
    pub fn set_total(&mut self, total: u64) {
        self.total = total;
        if let Some(b) = &self.bar {
            b.set_length(total);
        }
    }

    /// Position `pos` with `msg`; without a terminal, `line` is printed when the
    /// interval has passed since the last one (or at the end).
    pub fn set(&mut self, pos: u64, msg: String, line: impl FnOnce(&str) -> String) {
        match &self.bar {
            Some(b) => {
                b.set_position(pos);
                b.set_message(msg);
            }
            None => {
                let due = self.last_line.is_none_or(|t| t.elapsed() >= self.every);
                if due || pos == self.total {
                    self.last_line = Some(Instant::now());
                    eprintln!("{}", line(&msg));
                }
            }
        }
    }

    /// A note above the bar: `who: text`.
    pub fn note(&self, text: &str) {
        match &self.bar {
            Some(b) => b.println(format!("{}: {text}", self.who)),
            None => eprintln!("{}: {text}", self.who),
        }
    }

    /// Ends the bar.
    pub fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            if self.keep {
                b.finish();
            } else {
                b.finish_and_clear();
            }
        }
    }
}
