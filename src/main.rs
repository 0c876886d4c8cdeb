//! `waam`: the command-line front end of waam-planner.
//!
//! Each subcommand lives in its own module under `src/cli/`; this file only parses the
//! command line, sets up logging and turns results into exit codes.

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
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
