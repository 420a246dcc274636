//! Progress of a long run on the terminal: an indicatif bar, or a line every ~5 % when the output
//! is not a terminal (logs, CI).

use std::time::Instant;

/// A progress display: an indicatif bar on a terminal, a line every ~5 % otherwise.
pub(super) struct Progress {
    bar: Option<indicatif::ProgressBar>,
    total: u64,
    quiet: bool,
    start: Instant,
    last_line: u64,
}

impl Progress {
    pub(super) fn new(total: u64, start_step: u64, quiet: bool) -> Self {
        use std::io::IsTerminal;
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let b = indicatif::ProgressBar::new(total);
            b.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:28}] {pos}/{len} {msg} eta {eta}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            b.set_position(start_step);
            b
        });
        Self {
            bar,
            total,
            quiet,
            start: Instant::now(),
            last_line: start_step,
        }
    }

    pub(super) fn update(&mut self, step: u64, msg: String) {
        if let Some(b) = &self.bar {
            b.set_position(step);
            b.set_message(msg);
        } else if !self.quiet
            && (step - self.last_line >= (self.total / 20).max(1) || step == self.total)
        {
            self.last_line = step;
            eprintln!(
                "step {step}/{} {msg} ({:.0} s)",
                self.total,
                self.start.elapsed().as_secs_f64()
            );
        }
    }

    pub(super) fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
