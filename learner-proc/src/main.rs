//! `learner-proc`: see the library's documentation.

fn main() -> std::process::ExitCode {
    learner_proc::cli::main(std::env::args_os())
}
