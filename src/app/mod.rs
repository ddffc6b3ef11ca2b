//! One module per command of `treemocap`. With `daemon`, the only place that
//! names files: the stages below take and return values.

pub mod export;
pub mod files;
pub mod inspect;
pub mod live;
pub mod open;
mod progress;
pub mod reconstruct;
pub mod record;
pub mod recording;
pub mod replay;
pub mod stdout;
pub mod synth;
pub mod tips;
pub mod view;
