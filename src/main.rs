//! The `neus-aug` command line. Library errors are typed; this binary is the only place that turns
//! them into `anyhow` reports.

mod cli;

/// Cache-line-aligned large buffers with a huge-page hint: the hash table's neighbouring corners
/// then share cache lines (training is ~25-30 % faster; results are identical). See
/// `neus_aug::field::alloc`.
#[global_allocator]
static ALLOC: neus_aug::field::alloc::LargeAligned = neus_aug::field::alloc::LargeAligned;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // A reader that stops early (`neus-aug study table2 --dry-run | head`) ends this program
    // quietly, as it ends `ls` or `cat`: Rust ignores SIGPIPE by default, so every later
    // `println!` would panic on the closed pipe instead.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to its default before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            // Each cause once (see `error_chain`), not anyhow's `{:#}`, which repeats a cause
            // that an error both shows in its message and returns as its source.
            let err: &(dyn std::error::Error + 'static) = err.as_ref();
            eprintln!("error: {}", dtu_eval::error::error_chain(err));
            ExitCode::FAILURE
        }
    }
}
