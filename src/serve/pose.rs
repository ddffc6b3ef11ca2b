//! The live tree's sway, one frame at a time (docs/animation.md, "Live"):
//! every node's displacement from its rest position in the current tree,
//! as the daemon computes it from the live tips. Pure encoders; the daemon
//! sends.
//!
//! - WebSocket `/live`: `{"type":"pose","tree":V,"frame":F,"time_s":T,
//!   "d_um":[dx0,dy0,dz0,dx1,...]}`, displacements in micrometres
//!   (integers), node id = index (tree.json, the joints of tree.glb).
//! - OSC `/treemocap/pose`: `i` tree version, `i` frame, `f` time (s), `i`
//!   first node, `i` node count, then `f dx f dy f dz` (metres) per node;
//!   at most [`NODES_PER_MESSAGE`] nodes a datagram, so a large tree is a
//!   run of datagrams, each complete in itself.
//!
//! With several trees (docs/forest.md) every tree has its own pose of the
//! same frame: the JSON gains `"tree_id":ID,"name":"tree-1"` (node ids count
//! from 0 in every tree) and each OSC datagram ends with one more argument,
//! `i` tree id, as the other OSC messages of several trees do.

use std::sync::Arc;

use glam::DVec3;
use rosc::{encoder, OscMessage, OscPacket, OscType};

/// Nodes per OSC datagram: each costs 12 bytes of floats and 3 of type tags,
/// so 160 keep a datagram under 2.5 kB (about 2.45 kB), which every OSC
/// receiver we know takes whole.
pub const NODES_PER_MESSAGE: usize = 160;

/// One frame of the sway.
#[derive(Debug, Clone, Copy)]
pub struct Pose<'a> {
    /// Version of the tree the displacements belong to.
    pub tree: u64,
    /// With several trees: the id and name of the one this pose moves
    /// (`None` for a tree alone, whose messages are as they always were).
    pub member: Option<(usize, &'a str)>,
    /// The frame of the live tips.
    pub frame: i64,
    /// Its time (s).
    pub time_s: f64,
    /// Every node's displacement from its rest position (m), node order.
    pub displacements: &'a [DVec3],
}

/// The `/live` WebSocket message.
pub fn pose_message(p: &Pose<'_>) -> Arc<str> {
    let mut s = String::with_capacity(64 + p.displacements.len() * 18);
    let mut ints = itoa::Buffer::new();
    s.push_str("{\"type\":\"pose\",\"tree\":");
    s.push_str(ints.format(p.tree));
    if let Some((id, name)) = p.member {
        s.push_str(",\"tree_id\":");
        s.push_str(ints.format(id));
        s.push_str(",\"name\":");
        // A name is plain text from the config: escaped as JSON.
        s.push_str(&serde_json::Value::from(name).to_string());
    }
    s.push_str(",\"frame\":");
    s.push_str(ints.format(p.frame));
    s.push_str(",\"time_s\":");
    let mut floats = ryu::Buffer::new();
    s.push_str(if p.time_s.is_finite() {
        floats.format(p.time_s)
    } else {
        "0"
    });
    s.push_str(",\"d_um\":[");
    for (i, d) in p.displacements.iter().enumerate() {
        for (k, v) in [d.x, d.y, d.z].into_iter().enumerate() {
            if i + k > 0 {
                s.push(',');
            }
            let um = (v * 1e6).round();
            // A non-finite or absurd displacement is sent as 0 rather than
            // breaking the JSON.
            let um = if um.is_finite() && um.abs() < 1e15 {
                um as i64
            } else {
                0
            };
            s.push_str(ints.format(um));
        }
    }
    s.push_str("]}");
    s.into()
}

/// The OSC datagrams of one frame.
pub fn pose_datagrams(p: &Pose<'_>) -> Vec<Vec<u8>> {
    p.displacements
        .chunks(NODES_PER_MESSAGE)
        .enumerate()
        .map(|(k, chunk)| {
            let mut args = Vec::with_capacity(5 + 3 * chunk.len());
            args.push(OscType::Int(p.tree as i32));
            args.push(OscType::Int(p.frame as i32));
            args.push(OscType::Float(p.time_s as f32));
            args.push(OscType::Int((k * NODES_PER_MESSAGE) as i32));
            args.push(OscType::Int(chunk.len() as i32));
            for d in chunk {
                args.extend([d.x, d.y, d.z].map(|v| OscType::Float(v as f32)));
            }
            if let Some((id, _)) = p.member {
                args.push(OscType::Int(id as i32));
            }
            let msg = OscPacket::Message(OscMessage {
                addr: "/treemocap/pose".into(),
                args,
            });
            // rosc only fails on addresses or types we never produce.
            encoder::encode(&msg).unwrap_or_default()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn displacements(n: usize) -> Vec<DVec3> {
        (0..n)
            .map(|i| DVec3::new(i as f64 * 1e-4, -0.0123456, 0.05 * (i as f64).sin()))
            .collect()
    }

    #[test]
    fn json_round_trips_to_the_micrometre() {
        let d = displacements(7);
        let p = Pose {
            tree: 3,
            member: None,
            frame: 1234,
            time_s: 12.5,
            displacements: &d,
        };
        let v: serde_json::Value = serde_json::from_str(&pose_message(&p)).unwrap();
        assert_eq!(v["type"], "pose");
        assert_eq!(v["tree"], 3);
        assert_eq!(v["frame"], 1234);
        assert_eq!(v["time_s"], 12.5);
        let um = v["d_um"].as_array().unwrap();
        assert_eq!(um.len(), 21);
        for (i, d) in d.iter().enumerate() {
            for (k, want) in [d.x, d.y, d.z].into_iter().enumerate() {
                let got = um[3 * i + k].as_i64().unwrap() as f64 * 1e-6;
                assert!((got - want).abs() <= 0.5e-6 + 1e-12, "{got} vs {want}");
            }
        }
        let nan = [DVec3::NAN];
        let v: serde_json::Value = serde_json::from_str(&pose_message(&Pose {
            displacements: &nan,
            ..p
        }))
        .unwrap();
        assert_eq!(v["d_um"][0], 0);
        // A tree alone: no tree id, as before several trees swayed.
        assert!(v.get("tree_id").is_none() && v.get("name").is_none());
    }

    #[test]
    fn a_tree_of_several_is_named_in_json_and_osc() {
        let d = displacements(200);
        let p = Pose {
            tree: 4,
            member: Some((2, "pine \"b\"")),
            frame: 77,
            time_s: 1.0,
            displacements: &d,
        };
        let v: serde_json::Value = serde_json::from_str(&pose_message(&p)).unwrap();
        assert_eq!(
            (v["tree"].as_u64(), v["tree_id"].as_u64()),
            (Some(4), Some(2))
        );
        assert_eq!(v["name"], "pine \"b\"");
        assert_eq!(v["d_um"].as_array().unwrap().len(), 600);
        for g in pose_datagrams(&p) {
            assert!(g.len() <= 2500, "{} bytes", g.len());
            let (_, OscPacket::Message(m)) = rosc::decoder::decode_udp(&g).unwrap() else {
                panic!("not a message")
            };
            let count = m.args[4].clone().int().unwrap() as usize;
            assert_eq!(m.args.len(), 6 + 3 * count);
            assert_eq!(m.args.last(), Some(&OscType::Int(2)));
        }
    }

    #[test]
    fn osc_splits_large_trees_into_complete_datagrams() {
        for n in [0, 1, NODES_PER_MESSAGE, NODES_PER_MESSAGE + 1, 1000] {
            let d = displacements(n);
            let grams = pose_datagrams(&Pose {
                tree: 2,
                member: None,
                frame: 9,
                time_s: 0.5,
                displacements: &d,
            });
            assert_eq!(grams.len(), n.div_ceil(NODES_PER_MESSAGE));
            let mut seen = Vec::new();
            for g in &grams {
                assert!(g.len() <= 2500, "{} bytes", g.len());
                let (_, OscPacket::Message(m)) = rosc::decoder::decode_udp(g).unwrap() else {
                    panic!("not a message")
                };
                assert_eq!(m.addr, "/treemocap/pose");
                assert_eq!(m.args[0], OscType::Int(2));
                let first = m.args[3].clone().int().unwrap() as usize;
                let count = m.args[4].clone().int().unwrap() as usize;
                assert_eq!(m.args.len(), 5 + 3 * count);
                assert_eq!(first, seen.len());
                for j in 0..count {
                    let x = m.args[5 + 3 * j].clone().float().unwrap();
                    seen.push(x);
                    assert!((f64::from(x) - d[first + j].x).abs() < 1e-7);
                }
            }
            assert_eq!(seen.len(), n);
        }
    }
}
