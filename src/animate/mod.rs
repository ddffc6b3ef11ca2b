//! The captured motion put back on the reconstructed tree (issue 13; the
//! model is documented for users in docs/animation.md).
//!
//! Per frame every captured tip's displacement from its rest position is
//! known (measured or filled, flagged), or borrowed from its neighbours when
//! its marker is missing. Random tips borrow the motion of the captured tips
//! nearest to them in the rest pose. Every node moves by the mean bend of the
//! tips it carries times a bending profile `s^p` of its path length from the
//! trunk base (zero there, growing towards the tips). Segments are then
//! rotated about their parents so that branch lengths are kept, and a last
//! correction puts every tracked tip exactly where it was tracked.
//!
//! - [`Rig`]: what a tree needs for that, computed once per tree.
//! - [`Deformer`]: one frame's deformation, allocation-free (live and
//!   offline use the same code).
//! - [`animate`]: a session's traces → [`TreeMotion`] at the keys of the
//!   animation (`keys`).
//!
//! Pure: no I/O, no clock, no threads; arithmetic in a fixed order (f64,
//! and f32 for the random tips at branch ends, relative to their parents),
//! so the same inputs give the same positions.
//!
//! [`TreeMotion`]: crate::model::motion::TreeMotion

mod deform;
#[cfg(test)]
mod fixture;
mod keys;
mod motion;
mod paths;
mod rig;
mod settings;

pub use deform::{Deformer, TipInput};
pub use keys::{choose_keys, Keys};
pub use motion::animate;
pub use paths::{KeyPaths, Sampled, TipPaths};
pub use rig::Rig;
pub use settings::AnimateSettings;
