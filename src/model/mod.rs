//! Plain data shared by every layer: frames, traces, tips, the tree, the
//! wind and what a recording says about itself. It imports no other module
//! of treemocap but the error type.

pub mod frame;
pub mod motion;
pub mod recording;
pub mod tips;
pub mod tips_traces;
pub mod trace;
pub mod tree;
pub mod wind;
