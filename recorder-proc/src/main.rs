//! The `recorder-proc` binary: everything lives in the library.

fn main() -> std::process::ExitCode {
    recorder_proc::main_with_args(std::env::args_os())
}
