//! The `stabilis` command-line runner.
fn main() {
    std::process::exit(sim::cli::main_with_args(std::env::args_os()));
}
