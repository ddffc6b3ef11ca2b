//! The README's pictures of the swaying maple: `replays/maple-24.csv`
//! tracked, reconstructed and animated as `treemocap replay` does, then
//! drawn as frames of the crown at four moments of the wind phase
//! (docs/images/maple-24-sway.png) and as tree.png with the motion
//! (docs/images/maple-24-motion.png).
//!
//! cargo run --release --example sway_frames

use glam::DVec3;
use treemocap::animate::animate;
use treemocap::app::open::open_recording;
use treemocap::app::replay::estimate_wind;
use treemocap::config::Config;
use treemocap::reconstruct::reconstruct;
use treemocap::render::{frames::frames_png, picture::tree_png};

fn main() -> treemocap::Result<()> {
    let config = Config::default();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut rec = open_recording(&root.join("replays/maple-24.csv"), &config)?;
    let (tips, _) = treemocap::track::process(rec.as_mut(), &config.tracking)?;
    let wind = estimate_wind(&tips, &config).map_or(DVec3::ZERO, |w| w.flow_vector());
    let cfg = &config.reconstruct;
    let tree = reconstruct(&tips.captured(), wind, cfg, cfg.seed)?;
    let motion = animate(&tree, &tips, &config.animate)?;
    // Four moments 0.4 s apart late in the wind phase.
    let last = motion.keys() - 1;
    let keys: Vec<usize> = (0..4).map(|i| last - 60 + 12 * i).collect();
    let images = root.join("docs/images");
    std::fs::write(
        images.join("maple-24-sway.png"),
        frames_png(&tree, &motion, &keys)?,
    )
    .map_err(|e| treemocap::Error::io(images.join("maple-24-sway.png"), e))?;
    std::fs::write(
        images.join("maple-24-motion.png"),
        tree_png(&tree, Some(&motion))?,
    )
    .map_err(|e| treemocap::Error::io(images.join("maple-24-motion.png"), e))?;
    println!(
        "{} keys; stretch max {:.3} % mean {:.4} %; wrote docs/images/maple-24-sway.png and maple-24-motion.png",
        motion.keys(),
        motion.stretch.max_pct,
        motion.stretch.mean_pct
    );
    Ok(())
}
