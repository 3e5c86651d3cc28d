//! `lavatube`: starts, supervises, swaps and stops the simulator, learner and estimator
//! processes of a run, and manages the shared-memory resources runs leave behind. It links
//! only `common`; the processes are the binaries built beside it. [`runtime`] is the engine;
//! [`commands`] are the subcommands over it. A library as well as a binary so the
//! end-to-end tests can drive the runtime with fixture processes.

// The launcher is a terminal program: printing is its job.
#![allow(clippy::print_stdout, clippy::print_stderr)]

pub mod commands;
pub mod error;
pub mod onnx;
pub mod runtime;
