//! `waam`: the command-line front end of waam-planner.
//!
//! Each subcommand lives in its own module under `src/cli/`; this file only parses the
//! command line, sets up logging and turns results into exit codes.

mod cli;

use std::process::ExitCode;

use clap::Parser;

/// The planner allocates and frees a snapshot per simulated deposit, many per second on
/// every core; mimalloc's thread-local free lists make that cheap (glibc's malloc and
/// free had been 6 % of an enumeration).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    restore_sigpipe();
    let args = cli::Cli::parse();
    cli::init_logging(&args.global);
    match cli::run(args) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::from(cli::EXIT_BAD_INPUT)
        }
    }
}

/// `waam check ... | head` should end quietly like any Unix tool, not panic on a closed
/// pipe: Rust ignores SIGPIPE by default, so put the default action back.
fn restore_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any thread exists; SIG_DFL is a valid action.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
