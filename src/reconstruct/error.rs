//! What can stop a reconstruction. Every input has passed the settings'
//! range checks by the time the flow runs, so these name either the tips
//! (which came from a tips.json or the marker stage) or a limit of the
//! geometry.

use glam::DVec3;

use crate::error::Error;

/// Why no tree could be made.
#[derive(Debug, thiserror::Error)]
pub enum ReconstructError {
    /// Nothing to grow from.
    #[error("no captured tips to reconstruct from")]
    NoTips,
    /// A capture volume is metres across; a tip beyond the limit is a unit
    /// or file error, and would only overflow the geometry further down.
    #[error(
        "captured tip of marker {marker} is not a finite position within {limit_m} m: {position}"
    )]
    TipOutOfRange {
        /// The marker's index in tips.json.
        marker: usize,
        /// Where it claims to be (m).
        position: DVec3,
        /// The largest coordinate accepted (m).
        limit_m: f64,
    },
    /// The wind vector (direction × speed) is not finite or absurdly large.
    #[error("the wind vector {0} is not finite or absurdly large")]
    WindOutOfRange(DVec3),
    /// `reconstruct.volume = "hull"` on tips whose hull has no volume.
    #[error("reconstruct.volume = \"hull\": {0}; use volume = \"boxes\" for these tips")]
    Hull(#[from] super::hull::HullError),
    /// The flow produced a tree that breaks the promises every output relies
    /// on (one root, valid parents, no cycle): a bug, reported, never written.
    #[error("reconstruction produced a broken tree: {0}")]
    BrokenTree(String),
    /// More vertices or nodes than the 32-bit indices of the outputs hold.
    #[error("{what} has more than 2^32 elements")]
    TooLarge {
        /// What overflowed.
        what: &'static str,
    },
    /// The spatial index could not be built (the points were not finite).
    #[error("{what} index: {message}")]
    Index {
        /// Which index.
        what: &'static str,
        /// kiddo's words.
        message: String,
    },
}

impl From<ReconstructError> for Error {
    fn from(e: ReconstructError) -> Self {
        Error::Stage {
            stage: "reconstruction",
            source: Box::new(e),
        }
    }
}
