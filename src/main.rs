//! The `ohd` command line. No physics here: argument parsing, progress and exit codes.
//! Exit status: 0 success, 2 bad input (configuration or unreadable file; nothing is written),
//! 1 failure while running or writing.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
