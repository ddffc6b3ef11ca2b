//! The marker stage's tips of a session, with every tip's trajectory.
//!
//! `replay` drops the trajectories once the animation's keys are taken
//! (memory on long takes), so a test that checks the animation against the
//! tracked paths tracks the session itself, with the same settings: the
//! marker stage is deterministic, so these are the replay's own tips.

use std::path::Path;

use treemocap::app::open::open_recording;
use treemocap::config::Config;
use treemocap::model::tips::Tips;

/// The tips `replay` finds in `file` under `config`, trajectories included.
pub fn tracked_tips(file: &Path, config: &Config) -> Tips {
    let mut rec = open_recording(file, config).expect("open the session");
    treemocap::track::process(rec.as_mut(), &config.tracking)
        .expect("track the session")
        .0
}
