//! Reading our .glb files back in the tests: the container, the Khronos
//! validator (tests/peers/validate_gltf.js), accessors, and the world
//! position of a joint at an animation key, computed here from the file's
//! own data (translation-only joints: a joint's world position is the sum
//! of the translations up its parent chain).

use std::path::Path;
use std::process::Command;

use glam::DVec3;

/// Runs the Khronos glTF validator on a file; returns (errors, warnings,
/// the messages).
pub fn validate(path: &Path) -> (u64, u64, String) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers/validate_gltf.js");
    let out = Command::new("node")
        .arg(&script)
        .arg(path)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run node ({e}): install Node.js, then `npm install --prefix tests/peers`"
            )
        });
    if out.status.code() == Some(3) {
        panic!("the glTF validator is missing: run `npm install --prefix tests/peers`");
    }
    assert!(
        out.status.success(),
        "validator failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("validator JSON");
    (
        report["numErrors"].as_u64().unwrap(),
        report["numWarnings"].as_u64().unwrap(),
        report["messages"].to_string(),
    )
}

/// The JSON chunk of a .glb, parsed here from the container bytes.
pub fn glb_json(bytes: &[u8]) -> serde_json::Value {
    Glb::parse(bytes).json
}

/// A .glb's two chunks.
pub struct Glb {
    pub json: serde_json::Value,
    pub bin: Vec<u8>,
}

impl Glb {
    /// Splits and checks the container.
    pub fn parse(bytes: &[u8]) -> Glb {
        let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as usize;
        assert_eq!(&bytes[0..4], b"glTF");
        assert_eq!(u32_at(4), 2);
        assert_eq!(u32_at(8), bytes.len());
        let len = u32_at(12);
        assert_eq!(&bytes[16..20], b"JSON");
        let json = serde_json::from_slice(&bytes[20..20 + len]).unwrap();
        let bin = if bytes.len() > 20 + len {
            let at = 20 + len;
            let blen = u32_at(at);
            assert_eq!(&bytes[at + 4..at + 8], b"BIN\0");
            bytes[at + 8..at + 8 + blen].to_vec()
        } else {
            Vec::new()
        };
        Glb { json, bin }
    }

    /// The f32 components of float accessor `index` (tightly packed).
    pub fn floats(&self, index: usize) -> Vec<f32> {
        let a = &self.json["accessors"][index];
        assert_eq!(a["componentType"], 5126, "accessor {index} is not float");
        let per = match a["type"].as_str().unwrap() {
            "SCALAR" => 1,
            "VEC3" => 3,
            "VEC4" => 4,
            "MAT4" => 16,
            t => panic!("type {t}"),
        };
        let view = &self.json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
        let start =
            view["byteOffset"].as_u64().unwrap_or(0) + a["byteOffset"].as_u64().unwrap_or(0);
        let count = a["count"].as_u64().unwrap() as usize * per;
        (0..count)
            .map(|i| {
                let o = start as usize + 4 * i;
                f32::from_le_bytes(self.bin[o..o + 4].try_into().unwrap())
            })
            .collect()
    }

    /// Index of the node named `name`.
    pub fn node(&self, name: &str) -> Option<usize> {
        self.json["nodes"]
            .as_array()?
            .iter()
            .position(|n| n["name"] == name)
    }

    /// The first animation's key times (s).
    pub fn key_times(&self) -> Vec<f32> {
        let sampler = &self.json["animations"][0]["samplers"][0];
        self.floats(sampler["input"].as_u64().unwrap() as usize)
    }

    /// World position of node `node` at key `key` of the first animation
    /// (or in the bind pose with `key = None`).
    pub fn world(&self, node: usize, key: Option<usize>) -> DVec3 {
        let nodes = self.json["nodes"].as_array().unwrap();
        let mut parent = vec![None; nodes.len()];
        for (i, n) in nodes.iter().enumerate() {
            for c in n["children"].as_array().into_iter().flatten() {
                parent[c.as_u64().unwrap() as usize] = Some(i);
            }
        }
        let mut animated = std::collections::HashMap::new();
        if let Some(anim) = self.json["animations"].get(0) {
            for ch in anim["channels"].as_array().unwrap() {
                assert_eq!(ch["target"]["path"], "translation");
                let s = &anim["samplers"][ch["sampler"].as_u64().unwrap() as usize];
                animated.insert(
                    ch["target"]["node"].as_u64().unwrap() as usize,
                    s["output"].as_u64().unwrap() as usize,
                );
            }
        }
        let mut at = Some(node);
        let mut sum = DVec3::ZERO;
        while let Some(n) = at {
            let t = match (key, animated.get(&n)) {
                (Some(k), Some(&acc)) => {
                    let v = self.floats(acc);
                    [v[3 * k], v[3 * k + 1], v[3 * k + 2]]
                }
                _ => {
                    let t = &nodes[n]["translation"];
                    [0, 1, 2].map(|i| t[i].as_f64().unwrap_or(0.0) as f32)
                }
            };
            assert!(nodes[n].get("rotation").is_none() && nodes[n].get("scale").is_none());
            sum += DVec3::new(t[0].into(), t[1].into(), t[2].into());
            at = parent[n];
        }
        sum
    }
}
