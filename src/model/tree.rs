//! The reconstructed tree: the single source every output (glTF, JSON, OSC,
//! HTTP, the picture) is made from (spec §8).

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// What a node of the tree is, so outputs can draw and label it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Kind {
    /// A node of the synthetic trunk (paper Figure 4).
    Trunk,
    /// Where two or more particles merged.
    Junction,
    /// A point a particle passed through: it bends the branch between
    /// junctions (the spec's kinds have no name for it; without these points
    /// every branch would be a straight line).
    Branch,
    /// A random tip generated inside the crown volume.
    Tip,
    /// A captured tip: its position is the marker's measured rest position.
    Captured {
        /// Index of the marker (tips.json `marker`) this tip came from.
        marker: usize,
    },
}

impl Kind {
    /// The lower-case name used in tree.json.
    pub fn name(&self) -> &'static str {
        match self {
            Kind::Trunk => "trunk",
            Kind::Junction => "junction",
            Kind::Branch => "branch",
            Kind::Tip => "tip",
            Kind::Captured { .. } => "captured",
        }
    }

    /// True for the two kinds of branch ends.
    pub fn is_tip(&self) -> bool {
        matches!(self, Kind::Tip | Kind::Captured { .. })
    }
}

/// One node of the skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Position (m, Y up).
    pub position: DVec3,
    /// The next node towards the root; `None` only for the root.
    pub parent: Option<usize>,
    /// Branch radius at this node (m), from the pipe model.
    pub radius: f64,
    /// What the node is.
    pub kind: Kind,
}

/// A reconstructed tree. Node 0 is the root (the trunk base); every other
/// node has a parent, and following parents always ends at the root.
#[derive(Debug, Clone, PartialEq)]
pub struct Tree {
    /// All nodes; node 0 is the root.
    pub nodes: Vec<Node>,
    /// Indices of the trunk nodes, base first.
    pub trunk: Vec<usize>,
    /// Trunk node index used as the shape-format attractor S_r.
    pub attractor: usize,
    /// Particles that had not reached the trunk after `max_steps` and were
    /// joined to their nearest trunk node directly (ours; should be 0).
    pub forced_joins: usize,
    /// Flow steps taken until every particle had joined the trunk.
    pub steps: usize,
    /// The wind vector the flow used (direction × speed).
    pub wind: DVec3,
}

impl Tree {
    /// Children of every node, in ascending index order.
    pub fn children(&self) -> Vec<Vec<usize>> {
        let mut children = vec![Vec::new(); self.nodes.len()];
        for (i, node) in self.nodes.iter().enumerate() {
            if let Some(p) = node.parent {
                if let Some(c) = children.get_mut(p) {
                    c.push(i);
                }
            }
        }
        children
    }

    /// Nodes ordered so that every parent comes before its children (a
    /// breadth-first walk from the root). Nodes not reachable from the root
    /// (never in a valid tree) are left out.
    pub fn root_first_order(&self) -> Vec<usize> {
        let children = self.children();
        let mut order = Vec::with_capacity(self.nodes.len());
        if self.nodes.is_empty() {
            return order;
        }
        order.push(0);
        let mut head = 0;
        while let Some(&n) = order.get(head) {
            head += 1;
            order.extend_from_slice(&children[n]);
        }
        order
    }

    /// The tree cut into branches for the mesh and for measurements: a chain
    /// follows the thickest child (the next trunk node along the trunk), and
    /// every other child starts a new chain whose first entry is the node it
    /// grows from. The first chain starts at the root and is the trunk.
    pub fn chains(&self) -> Vec<Vec<usize>> {
        let children = self.children();
        let mut chains = Vec::new();
        if self.nodes.is_empty() {
            return chains;
        }
        // (start node, first node of the chain proper) pairs still to walk.
        let mut pending: Vec<(Option<usize>, usize)> = vec![(None, 0)];
        while let Some((from, first)) = pending.pop() {
            let mut chain = Vec::new();
            if let Some(f) = from {
                chain.push(f);
            }
            let mut at = first;
            loop {
                chain.push(at);
                let kids = &children[at];
                let Some(next) = self.main_child(at, kids) else {
                    break;
                };
                // Reverse so that pop() walks side chains in index order.
                for &k in kids.iter().rev() {
                    if k != next {
                        pending.push((Some(at), k));
                    }
                }
                at = next;
            }
            chains.push(chain);
        }
        chains
    }

    /// The child a chain continues into: along the trunk on the trunk,
    /// elsewhere the thickest child (ties to the lower index).
    fn main_child(&self, at: usize, kids: &[usize]) -> Option<usize> {
        if self.nodes[at].kind == Kind::Trunk {
            if let Some(&k) = kids.iter().find(|&&k| self.nodes[k].kind == Kind::Trunk) {
                return Some(k);
            }
        }
        let mut best: Option<usize> = None;
        for &k in kids {
            match best {
                Some(b) if self.nodes[b].radius >= self.nodes[k].radius => {}
                _ => best = Some(k),
            }
        }
        best
    }

    /// Checks the structural promises every output relies on: exactly one
    /// root (node 0, a trunk node), every parent index valid, no cycles.
    /// Returns a description of the first violation.
    pub fn check(&self) -> std::result::Result<(), String> {
        let n = self.nodes.len();
        let Some(root) = self.nodes.first() else {
            return Err("tree has no nodes".into());
        };
        if root.parent.is_some() || root.kind != Kind::Trunk {
            return Err("node 0 must be the trunk base with no parent".into());
        }
        for (i, node) in self.nodes.iter().enumerate().skip(1) {
            match node.parent {
                None => return Err(format!("node {i} has no parent")),
                Some(p) if p >= n || p == i => {
                    return Err(format!("node {i} has invalid parent {p}"))
                }
                Some(_) => {}
            }
        }
        if self.root_first_order().len() != n {
            return Err("some nodes are not connected to the root (a cycle)".into());
        }
        Ok(())
    }
}
