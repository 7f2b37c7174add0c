//! The `ohd` command line ([`ohd::cli`]; the Python package's `ohd` console script runs the same).
//! Exit status: 0 success, 2 bad input (configuration or unreadable file; nothing is written),
//! 1 failure while running or writing, 130 a run stopped by Ctrl-C.

fn main() -> std::process::ExitCode {
    ohd::cli::main()
}
