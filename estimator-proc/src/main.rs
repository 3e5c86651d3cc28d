//! The `estimator-proc` binary: everything lives in the library.

fn main() -> std::process::ExitCode {
    estimator_proc::main_with_args(std::env::args_os())
}
