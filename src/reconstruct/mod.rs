//! Reconstruction of the branching structure from the captured tips by
//! particle flow (Long & Jones 2013 §5–6; spec §6–8).
//!
//! [`reconstruct`] turns captured tips and the wind into a [`Tree`]; turning
//! the tree into files is `render`'s business.

pub mod error;
pub mod flow;
pub mod forest;
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
    reconstruct_placed(tips, wind, cfg, seed, &Placement::default())
}

/// Where one tree of several stands and how far it may grow
/// (docs/forest.md). The default is a tree alone: the trunk under the
/// crown's centre, nothing but the crown's own bounds around it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Placement {
    /// The trunk's base, when a configured `[[trees]]` entry pins it;
    /// `None` puts it at the ground under the crown's centre.
    pub base: Option<DVec3>,
    /// The tree's side of the planes between it and its neighbours: random
    /// tips are drawn inside, and the flow stays inside.
    pub cell: forest::cell::Cell,
}

/// `reconstruct_with_volume` for a tree placed among others.
pub fn reconstruct_placed(
    tips: &[CapturedTip],
    wind: DVec3,
    cfg: &ReconstructSettings,
    seed: u64,
    place: &Placement,
) -> Result<(Tree, volume::Volume)> {
    cfg.validate()?;
    check_inputs(tips, wind)?;
    let positions: Vec<DVec3> = tips.iter().map(|t| t.position).collect();
    let crown = trunk::Bounds::of(positions.iter().copied()).ok_or(ReconstructError::NoTips)?;
    let mut trunk_rng = Rng::new(seed).fork(TRUNK_STREAM);
    let trunk = match place.base {
        None => trunk::Trunk::build(crown, cfg, &mut trunk_rng)?,
        Some(b) => {
            let at = ReconstructSettings {
                ground_height: b.y,
                ..cfg.clone()
            };
            trunk::Trunk::build_at(b.x, b.z, crown, &at, &mut trunk_rng)?
        }
    };
    let cell = &place.cell;
    let (volume, random) = volume::random_tips_where(
        &positions,
        cfg,
        &mut Rng::new(seed).fork(VOLUME_STREAM),
        &|p| cell.contains(p),
    )?;

    let mut starts: Vec<(DVec3, Kind)> = tips
        .iter()
        .map(|t| (t.position, Kind::Captured { marker: t.marker }))
        .collect();
    starts.extend(random.into_iter().map(|p| (p, Kind::Tip)));
    let flow_cfg = match place.base {
        // The shape-format force's scale is the height above this tree's
        // own ground.
        Some(b) => ReconstructSettings {
            ground_height: b.y,
            ..cfg.clone()
        },
        None => cfg.clone(),
    };
    let mut tree = flow::run_in(&starts, &trunk, wind, &flow_cfg, cell)?;
    // Cheap (linear) and every output relies on it: fail loudly rather than
    // write a broken tree.
    tree.check().map_err(ReconstructError::BrokenTree)?;
    radii::assign(&mut tree, cfg.tip_radius, cfg.gamma);
    Ok((tree, volume))
}

/// Tips and wind a capture volume can hold: none beyond 10 km (a unit or
/// file error, which would only overflow the geometry further down).
fn check_inputs(tips: &[CapturedTip], wind: DVec3) -> Result<()> {
    if tips.is_empty() {
        return Err(ReconstructError::NoTips.into());
    }
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
    Ok(())
}
