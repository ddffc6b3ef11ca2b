//! tree.png's share of a large reconstruction: 70 captured tips and 50 000
//! tips in all, the flow, radii, mesh and encodings timed against drawing
//! and encoding the picture.

use glam::DVec3;
use treemocap::config::Config;
use treemocap::render::outputs::{build_model, Motion};
use treemocap::render::picture::tree_png;

#[path = "../../tests/it/common/crowns.rs"]
mod crowns;

use crate::util::{best_of, timed, Row, Scale};

/// Reconstruction time against picture time at 50 000 tips.
pub fn share(scale: &Scale) -> Vec<Row> {
    let total = if scale.quick { 20_000 } else { 50_000 };
    let tips = crowns::crown_tips(crowns::Shape::Maple, 70, 2);
    let mut config = Config::default();
    config.reconstruct.total_tips = total;
    let (outputs, build_s) = timed(|| {
        build_model(
            &tips,
            DVec3::new(2.0, 0.0, 0.0),
            &config.reconstruct,
            Motion::Still,
        )
        .expect("reconstruct")
    });
    let picture_s = best_of(3, || {
        timed(|| tree_png(&outputs.tree, None).expect("png")).1
    });
    println!(
        "picture: {} nodes; reconstruction {build_s:.3} s, tree.png {picture_s:.3} s",
        outputs.tree.nodes.len()
    );
    vec![Row::new(
        format!(
            "tree.png at {total} tips ({} nodes)",
            outputs.tree.nodes.len()
        ),
        "≤ 20 % of the reconstruction",
        format!(
            "{:.0} ms = {:.0} % of the reconstruction ({:.0} ms)",
            picture_s * 1e3,
            100.0 * picture_s / build_s,
            build_s * 1e3
        ),
        "—".into(),
    )]
}
