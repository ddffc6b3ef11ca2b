//! OSC out: the tree after each reconstruction, the live tips every frame,
//! and the wind. Encoding is pure (snapshot in, datagrams out); [`OscSender`]
//! only sends.
//!
//! Address space (all floats are float32, metres, Y up):
//!
//! | address | arguments |
//! |---|---|
//! | `/treemocap/tree/begin` | `i` version, `i` node count |
//! | `/treemocap/tree/node` | `i` id, `i` parent (−1 for the root), `f` x, `f` y, `f` z, `f` radius |
//! | `/treemocap/tree/end` | `i` version, `i` node count |
//! | `/treemocap/tips` | `i` frame, `f` time (s), then per tip seen in the frame `i` marker, `f` x, `f` y, `f` z |
//! | `/treemocap/wind` | `s` source, `f` azimuth (deg, downwind, 0 = +Z, 90 = +X), `f` x, `f` y, `f` z, `f` speed (m/s, −1 unknown) |
//!
//! With several trees (docs/forest.md) every tree rebuilt goes out as its
//! own run, and its `begin`, `node` and `end` messages end with one more
//! argument, `i` tree id; node ids count from 0 in every tree.
//!
//! A tree goes out as a run of bundles of at most `NODES_PER_BUNDLE` nodes
//! each (about 3.5 kB, safe for any UDP path), `begin` in the first and `end`
//! in the last, so a receiver knows when it has the whole tree; the node
//! count in `end` lets it check.

use std::net::{SocketAddr, UdpSocket};
use std::time::Duration;

use glam::DVec3;
use rosc::{encoder, OscBundle, OscMessage, OscPacket, OscTime, OscType};

use super::snapshot::{SnapshotNode, TreeSnapshot};
use crate::error::{Error, Result};
use crate::model::wind::WindEstimate;

/// Nodes per bundle: 60 × ~56 bytes keeps a datagram near 3.5 kB.
pub const NODES_PER_BUNDLE: usize = 60;

fn msg(addr: &str, args: Vec<OscType>) -> OscPacket {
    OscPacket::Message(OscMessage {
        addr: addr.to_string(),
        args,
    })
}

fn bundle(content: Vec<OscPacket>) -> OscPacket {
    // "Immediately" (1): the tree is not scheduled for later.
    OscPacket::Bundle(OscBundle {
        timetag: OscTime {
            seconds: 0,
            fractional: 1,
        },
        content,
    })
}

fn encode(p: &OscPacket) -> Vec<u8> {
    // rosc only fails to encode on addresses or types we never produce.
    encoder::encode(p).unwrap_or_default()
}

/// The datagrams that carry one tree.
pub fn tree_datagrams(tree: &TreeSnapshot) -> Vec<Vec<u8>> {
    if tree.trees.is_empty() {
        return run(tree.version, &tree.nodes, None);
    }
    // Several trees: a run per tree rebuilt, each message ending with the
    // tree's id; a receiver keeps the trees not sent.
    tree.trees
        .iter()
        .filter(|t| t.rebuilt)
        .flat_map(|t| run(tree.version, &t.nodes, Some(t.id)))
        .collect()
}

/// The bundles of one skeleton: `begin` in the first, `end` in the last,
/// every message with a trailing `i tree` when `tree` is given.
fn run(version: u64, nodes: &[SnapshotNode], tree: Option<usize>) -> Vec<Vec<u8>> {
    let count = nodes.len() as i32;
    let version = version as i32;
    let with_tree = |mut args: Vec<OscType>| {
        if let Some(t) = tree {
            args.push(OscType::Int(t as i32));
        }
        args
    };
    let mut out = Vec::new();
    let chunks: Vec<_> = nodes.chunks(NODES_PER_BUNDLE).collect();
    let n_chunks = chunks.len().max(1);
    for k in 0..n_chunks {
        let mut content = Vec::new();
        if k == 0 {
            content.push(msg(
                "/treemocap/tree/begin",
                with_tree(vec![OscType::Int(version), OscType::Int(count)]),
            ));
        }
        if let Some(chunk) = chunks.get(k) {
            let first = (k * NODES_PER_BUNDLE) as i32;
            for (j, n) in chunk.iter().enumerate() {
                content.push(msg(
                    "/treemocap/tree/node",
                    with_tree(vec![
                        OscType::Int(first + j as i32),
                        OscType::Int(n.parent.map_or(-1, |p| p as i32)),
                        OscType::Float(n.position.x as f32),
                        OscType::Float(n.position.y as f32),
                        OscType::Float(n.position.z as f32),
                        OscType::Float(n.radius as f32),
                    ]),
                ));
            }
        }
        if k == n_chunks - 1 {
            content.push(msg(
                "/treemocap/tree/end",
                with_tree(vec![OscType::Int(version), OscType::Int(count)]),
            ));
        }
        out.push(encode(&bundle(content)));
    }
    out
}

/// The live tips of one frame: `(marker index, position)` pairs.
pub fn tips_datagram(frame: i64, time_s: f64, tips: &[(usize, DVec3)]) -> Vec<u8> {
    let mut args = Vec::with_capacity(2 + tips.len() * 4);
    args.push(OscType::Int(frame as i32));
    args.push(OscType::Float(time_s as f32));
    for (i, p) in tips {
        args.push(OscType::Int(*i as i32));
        args.push(OscType::Float(p.x as f32));
        args.push(OscType::Float(p.y as f32));
        args.push(OscType::Float(p.z as f32));
    }
    encode(&msg("/treemocap/tips", args))
}

/// One wind estimate.
pub fn wind_datagram(w: &WindEstimate) -> Vec<u8> {
    encode(&msg(
        "/treemocap/wind",
        vec![
            OscType::String(w.source.name().into()),
            OscType::Float(w.azimuth_deg() as f32),
            OscType::Float(w.direction.x as f32),
            OscType::Float(w.direction.y as f32),
            OscType::Float(w.direction.z as f32),
            OscType::Float(w.speed_m_s.map_or(-1.0, |s| s as f32)),
        ],
    ))
}

/// Sends datagrams to every configured target.
pub struct OscSender {
    socket: UdpSocket,
    targets: Vec<SocketAddr>,
    /// Datagrams that could not be sent (counted, never fatal).
    pub errors: u64,
}

/// Pause between the datagrams of one tree. A 10 000-node tree is ~170
/// datagrams (~600 kB), about three times what a receiver's default socket
/// buffer (~200 kB on Linux) holds; sent back to back, a receiver that is
/// busy for a moment loses the rest. 1 ms each sends that tree in ~0.17 s.
const PAUSE: Duration = Duration::from_millis(1);

impl OscSender {
    /// A sender on an ephemeral UDP port for the `daemon.osc_targets`.
    pub fn new(targets: Vec<SocketAddr>) -> Result<Self> {
        let socket = UdpSocket::bind(("0.0.0.0", 0))
            .map_err(|e| Error::Runtime(format!("OSC out: cannot open a UDP socket: {e}")))?;
        Ok(OscSender {
            socket,
            targets,
            errors: 0,
        })
    }

    /// Sends one datagram to every target. A target that refuses is
    /// counted, not fatal: a viewer that is not running must not stop the
    /// daemon.
    pub fn send(&mut self, datagram: &[u8]) {
        for t in &self.targets {
            if let Err(e) = self.socket.send_to(datagram, t) {
                self.errors += 1;
                tracing::debug!("OSC out to {t}: {e}");
            }
        }
    }

    /// Sends a run of datagrams, pacing bursts so none is lost to a full
    /// receive buffer on the other side.
    pub fn send_paced(&mut self, datagrams: &[Vec<u8>]) {
        for (k, d) in datagrams.iter().enumerate() {
            if k > 0 {
                std::thread::sleep(PAUSE);
            }
            self.send(d);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(d: &[u8]) -> OscPacket {
        rosc::decoder::decode_udp(d).unwrap().1
    }

    #[test]
    fn tree_of_any_size_is_split_and_bracketed() {
        for n in [0usize, 1, 60, 61, 10_000] {
            let tree = TreeSnapshot {
                version: 7,
                nodes: (0..n)
                    .map(|i| SnapshotNode {
                        parent: i.checked_sub(1).map(|p| p as u32),
                        position: DVec3::new(i as f64, 1.0, 2.0),
                        radius: 0.01,
                    })
                    .collect(),
                ..TreeSnapshot::default()
            };
            let grams = tree_datagrams(&tree);
            assert_eq!(grams.len(), n.div_ceil(NODES_PER_BUNDLE).max(1));
            assert!(grams.iter().all(|g| g.len() < 4096));
            let mut ids = Vec::new();
            let mut begin = 0;
            let mut end = 0;
            for g in &grams {
                let OscPacket::Bundle(b) = decode(g) else {
                    panic!()
                };
                for p in b.content {
                    let OscPacket::Message(m) = p else { panic!() };
                    match m.addr.as_str() {
                        "/treemocap/tree/begin" => begin += 1,
                        "/treemocap/tree/end" => {
                            end += 1;
                            assert_eq!(m.args[1], OscType::Int(n as i32));
                        }
                        _ => ids.push(m.args[0].clone().int().unwrap()),
                    }
                }
            }
            assert_eq!((begin, end), (1, 1));
            assert_eq!(ids, (0..n as i32).collect::<Vec<_>>());
        }
    }
}
