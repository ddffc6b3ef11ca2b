//! A small tree for the unit tests of the animation.

use glam::DVec3;

use crate::model::tree::{Kind, Node, Tree};

/// A trunk 0 → 1, a junction 2 with captured tips 3 (marker 5) and 4
/// (marker 2), and a random tip 5 on the trunk top.
pub(crate) fn small_tree() -> Tree {
    let node = |x: f64, y: f64, parent: Option<usize>, kind| Node {
        position: DVec3::new(x, y, 0.0),
        parent,
        radius: 0.01,
        kind,
    };
    Tree {
        nodes: vec![
            node(0.0, 0.0, None, Kind::Trunk),
            node(0.0, 1.0, Some(0), Kind::Trunk),
            node(0.2, 1.5, Some(1), Kind::Junction),
            node(0.6, 2.0, Some(2), Kind::Captured { marker: 5 }),
            node(-0.1, 2.1, Some(2), Kind::Captured { marker: 2 }),
            node(0.3, 1.2, Some(1), Kind::Tip),
        ],
        trunk: vec![0, 1],
        attractor: 0,
        forced_joins: 0,
        steps: 1,
        wind: DVec3::ZERO,
    }
}
