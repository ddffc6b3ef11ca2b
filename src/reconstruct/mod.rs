//! Reconstruction of the branching structure from the captured tips by
//! particle flow (Long & Jones 2013 §5–6; spec §6–8).
//!
//! [`reconstruct`] turns captured tips and the wind into a [`Tree`]; turning
//! the tree into files is `render`'s business.

pub mod error;
pub mod flow;
pub mod hull;
pub mod leaves;
pub mod mesh;
pub mod radii;
pub mod settings;
pub mod trunk;
pub mod volume;

pub use settings::{ReconstructSettings, VolumeKind};

use glam::DVec3;

use crate::error::Result;
use crate::rng::Rng;
pub use error::ReconstructError;

use crate::model::tips::CapturedTip;
use crate::model::tree::{Kind, Tree};

/// Labels of the independent random streams, so that e.g. a change in the
/// number of trunk nodes does not move every random tip.
const TRUNK_STREAM: u64 = 1;
const VOLUME_STREAM: u64 = 2;

/// Reconstructs a tree from captured tips: trunk, random tips
/// in the crown volume, particle flow, pipe-model radii. `wind` is direction
/// × speed (zero when unknown). The same inputs and seed give the same tree.
pub fn reconstruct(
    tips: &[CapturedTip],
    wind: DVec3,
    cfg: &ReconstructSettings,
    seed: u64,
) -> Result<Tree> {
    Ok(reconstruct_with_volume(tips, wind, cfg, seed)?.0)
}

/// `reconstruct`, also returning the crown volume used (for checks and
/// reports).
pub fn reconstruct_with_volume(
    tips: &[CapturedTip],
    wind: DVec3,
    cfg: &ReconstructSettings,
    seed: u64,
) -> Result<(Tree, volume::Volume)> {
    cfg.validate()?;
    if tips.is_empty() {
        return Err(ReconstructError::NoTips.into());
    }
    // A capture volume is metres across; anything beyond 10 km is a unit or
    // file error, and would only overflow the geometry further down.
    const FAR: f64 = 1e4;
    if let Some(t) = tips
        .iter()
        .find(|t| !t.position.is_finite() || t.position.abs().max_element() > FAR)
    {
        return Err(ReconstructError::TipOutOfRange {
            marker: t.marker,
            position: t.position,
            limit_m: FAR,
        }
        .into());
    }
    if !wind.is_finite() || wind.length() > FAR {
        return Err(ReconstructError::WindOutOfRange(wind).into());
    }
    let positions: Vec<DVec3> = tips.iter().map(|t| t.position).collect();
    let crown = trunk::Bounds::of(positions.iter().copied()).ok_or(ReconstructError::NoTips)?;
    let trunk = trunk::Trunk::build(crown, cfg, &mut Rng::new(seed).fork(TRUNK_STREAM))?;
    let (volume, random) =
        volume::random_tips(&positions, cfg, &mut Rng::new(seed).fork(VOLUME_STREAM))?;

    let mut starts: Vec<(DVec3, Kind)> = tips
        .iter()
        .map(|t| (t.position, Kind::Captured { marker: t.marker }))
        .collect();
    starts.extend(random.into_iter().map(|p| (p, Kind::Tip)));
    let mut tree = flow::run(&starts, &trunk, wind, cfg)?;
    // Cheap (linear) and every output relies on it: fail loudly rather than
    // write a broken tree.
    tree.check().map_err(ReconstructError::BrokenTree)?;
    radii::assign(&mut tree, cfg.tip_radius, cfg.gamma);
    Ok((tree, volume))
}
