//! rodtrack's evaluation on the built-in simulator, as a library (the `rodtrack` binary's
//! `evaluate`, `score` and `demo` commands are its front end).
//!
//! - [`score`]: measurements against ground truth ([`score::score`], [`score::Stats`]).
//! - [`sim_run`]: the simulator's cameras through an SDK [`rodtrack_sdk::Session`], the
//!   paper's algorithm on the same frames alongside.
//! - [`plan`]: what each scenario runs ([`plan::plan_for`]).
//! - [`quality`]: what a row's quality says about its error, over many random tables
//!   ([`quality::run_table`], [`quality::bands`]).
//! - [`run`]: the scenarios run and scored ([`run::run_plans`]).
//! - [`tables`]: accuracy over random tables as built, worst and median camera
//!   ([`tables::run_tables`]).
//! - [`report`]: the Markdown report, `summary.json` and the plots ([`report::write_report`]),
//!   drawn by [`figures`] with [`plots`].

mod error;
pub mod figures;
pub mod plan;
pub mod plots;
mod progress;
pub mod quality;
pub mod report;
pub mod run;
pub mod score;
pub mod sim_run;
pub mod tables;

pub use error::{error_chain, EvalError};

/// The result type of this crate.
pub type Result<T, E = EvalError> = std::result::Result<T, E>;
