//! The daemon: sources → bounded channel → marker pipeline → analysis and
//! triggers → reconstruction → outputs. Wiring only: threads, channels,
//! triggers and shutdown; every stage it runs is the plain library code that
//! `treemocap replay` runs too.

pub mod follow;
pub mod handoff;
pub mod rest_estimate;
pub mod run;
pub mod status;
pub mod triggers;
pub mod wind_log;
pub mod window;

pub use run::run;
