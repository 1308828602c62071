//! The `fissure` command line: scenario checks and mesh tools (the simulator's
//! `run`, `replay`, `study` and `screenshot` join the same subcommand enum).
//!
//! In: arguments. Out: the command's output on stdout, and on error the whole
//! cause chain on stderr with exit code 1 (2 for usage errors, from clap).
//! `anyhow` lives only here; the library returns typed errors.

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match cli::dispatch(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error}");
            for cause in error.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::FAILURE
        }
    }
}
