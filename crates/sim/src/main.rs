//! The `stabilis` command-line runner.
fn main() {
    eprintln!("stabilis: no commands yet");
    std::process::exit(2);
}
