//! Branch thickness (spec §7, ours after Xu et al. 2007 and Livny et al.
//! 2010): every tip has `tip_radius`, and a node carries the pipes of all
//! its children, r_parent = (Σ r_child^γ)^(1/γ). γ = 2 keeps the summed
//! cross-section area (the pipe model).

use crate::model::tree::Tree;

/// Fills every node's radius from the tips down to the root.
pub fn assign(tree: &mut Tree, tip_radius: f64, gamma: f64) {
    let children = tree.children();
    let order = tree.root_first_order();
    for &n in order.iter().rev() {
        let kids = &children[n];
        let radius = match kids.as_slice() {
            [] => tip_radius,
            // One child: the same pipe (no rounding through powf).
            [only] => tree.nodes[*only].radius,
            many => {
                let sum: f64 = many.iter().map(|&k| tree.nodes[k].radius.powf(gamma)).sum();
                let widest = many
                    .iter()
                    .map(|&k| tree.nodes[k].radius)
                    .fold(0.0, f64::max);
                // (Σ r^γ)^(1/γ) ≥ max r in exact arithmetic; keep that
                // promise under rounding too.
                sum.powf(1.0 / gamma).max(widest)
            }
        };
        tree.nodes[n].radius = radius;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tree::{Kind, Node};
    use glam::DVec3;

    fn node(parent: Option<usize>, kind: Kind) -> Node {
        Node {
            position: DVec3::ZERO,
            parent,
            radius: 0.0,
            kind,
        }
    }

    #[test]
    fn pipe_model_by_hand() {
        // root(0) ← trunk(1) ← junction(2) ← tips 3, 4; trunk(1) ← tip 5.
        let mut tree = Tree {
            nodes: vec![
                node(None, Kind::Trunk),
                node(Some(0), Kind::Trunk),
                node(Some(1), Kind::Junction),
                node(Some(2), Kind::Tip),
                node(Some(2), Kind::Captured { marker: 0 }),
                node(Some(1), Kind::Tip),
            ],
            trunk: vec![0, 1],
            attractor: 1,
            forced_joins: 0,
            steps: 0,
            wind: DVec3::ZERO,
        };
        assign(&mut tree, 0.01, 2.0);
        let r: Vec<f64> = tree.nodes.iter().map(|n| n.radius).collect();
        // Junction: sqrt(2) × 0.01; node 1: sqrt(2 + 1) × 0.01; root the same.
        assert!((r[2] - 0.01 * 2f64.sqrt()).abs() < 1e-15);
        assert!((r[1] - 0.01 * 3f64.sqrt()).abs() < 1e-15);
        assert_eq!(r[0], r[1]);
        assert_eq!(r[3], 0.01);
        // γ = 3: junction (2 × 0.01³)^(1/3).
        assign(&mut tree, 0.01, 3.0);
        assert!((tree.nodes[2].radius - 0.01 * 2f64.cbrt()).abs() < 1e-15);
    }
}
