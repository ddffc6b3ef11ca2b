//! Everything that yields `MarkerFrame`s: recorded files (`replay`) and, later,
//! live network sources.

pub mod replay;
