//! The `sim-proc` binary: everything lives in the library.

fn main() -> std::process::ExitCode {
    sim_proc::cli::main()
}
