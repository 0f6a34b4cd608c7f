//! The `arpa` command-line tool; see [`arpa::cli`].

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // Argument errors print clap's message and exit with status 2.
    let cli = arpa::cli::Cli::parse();
    match arpa::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
