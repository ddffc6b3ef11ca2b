//! The daemon: sources → bounded channel → marker pipeline → analysis and
//! triggers → reconstruction → outputs. The only module that knows about
//! threads, sockets and timing; every stage it runs is the plain library code
//! that `treemocap replay` runs too.

pub mod follow;
pub mod player;
pub mod run;
pub mod status;
pub mod triggers;
pub mod window;

pub use run::run;
