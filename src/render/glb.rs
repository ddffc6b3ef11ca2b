//! The glTF document builder: accessors, buffer views, meshes, materials
//! and nodes in one binary chunk, written as a GLB container. `gltf.rs`
//! says what goes into a tree's file; the skin (`animation.rs`) adds its
//! joints and keys through this builder, and the builder asks the skin only
//! through [`Skinning`], so neither file needs the other's internals.

use gltf_json as json;
use json::accessor::{ComponentType, GenericComponentType, Type};
use json::validation::{Checked::Valid, USize64};

use crate::error::Result;
use crate::model::tree::Tree;
use crate::reconstruct::mesh::{Bind, Mesh};
use crate::render::error::RenderError;

const GLB_MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A; // "JSON"
const CHUNK_BIN: u32 = 0x004E_4942; // "BIN\0"

/// A mesh's vertex attributes by semantic, as glTF keeps them.
pub(super) type Attributes = std::collections::BTreeMap<
    json::validation::Checked<json::mesh::Semantic>,
    json::Index<json::Accessor>,
>;

/// What the builder needs of a skin: the joints and weights of a mesh's
/// vertices, and the skin's index for the mesh nodes. A trait so that the
/// builder does not depend on the animation that writes through it.
pub(super) trait Skinning {
    /// Adds `JOINTS_0` and `WEIGHTS_0` for vertices that follow `binds`.
    fn bind(&self, b: &mut Builder, binds: &[Bind], attributes: &mut Attributes) -> Result<()>;
    /// The skin's index, for the skinned mesh nodes.
    fn index(&self) -> json::Index<json::Skin>;
}

/// The glTF document being built and its binary chunk.
pub(super) struct Builder {
    pub(super) root: json::Root,
    pub(super) bin: Vec<u8>,
    /// Shared by every tree's branches, made before the first mesh.
    bark: Option<json::Index<json::Material>>,
    /// Shared by every tree's leaves, made with the first leaves.
    leaf: Option<json::Index<json::Material>>,
    /// Shared by every tree's skeleton, made with the first skeleton.
    skeleton: Option<json::Index<json::Material>>,
}

impl Default for Builder {
    fn default() -> Self {
        let root = json::Root {
            asset: json::Asset {
                copyright: None,
                extensions: None,
                extras: Default::default(),
                generator: Some(format!("treemocap {}", env!("CARGO_PKG_VERSION"))),
                min_version: None,
                version: "2.0".into(),
            },
            ..Default::default()
        };
        Builder {
            root,
            bin: Vec::new(),
            bark: None,
            leaf: None,
            skeleton: None,
        }
    }
}

impl Builder {
    /// The nodes of one tree: branches, leaves (when any), skeleton; with
    /// `skin`, skinned to it and named after the tree (`tree-1 branches`),
    /// since they then stand at the scene's root (glTF ignores the
    /// transforms above a skinned mesh, and the validator warns of one
    /// that is not a root).
    pub(super) fn tree_nodes(
        &mut self,
        tree: &Tree,
        branches: &Mesh,
        leaves: Option<&Mesh>,
        skin: Option<(&dyn Skinning, &str)>,
    ) -> Result<Vec<json::Index<json::Node>>> {
        let skinning = skin.map(|s| s.0);
        let name = |part: &str| match skin {
            Some((_, tree_name)) => format!("{tree_name} {part}"),
            None => part.to_string(),
        };
        let bark = match self.bark {
            Some(m) => m,
            None => {
                let m = self.material("bark", [0.40, 0.29, 0.20, 1.0], false);
                self.bark = Some(m);
                m
            }
        };
        let mut nodes = Vec::new();
        if let Some(mesh) = self.triangle_mesh("branches", branches, bark, skinning)? {
            nodes.push(self.node(&name("branches"), mesh, skinning));
        }
        if let Some(leaves) = leaves.filter(|m| !m.indices.is_empty()) {
            let leaf = match self.leaf {
                Some(m) => m,
                None => {
                    let m = self.material("leaf", [0.27, 0.52, 0.16, 1.0], true);
                    self.leaf = Some(m);
                    m
                }
            };
            if let Some(mesh) = self.triangle_mesh("leaves", leaves, leaf, skinning)? {
                nodes.push(self.node(&name("leaves"), mesh, skinning));
            }
        }
        if let Some(mesh) = self.skeleton(tree, skinning)? {
            nodes.push(self.node(&name("skeleton"), mesh, skinning));
        }
        Ok(nodes)
    }

    /// The scene of `nodes`, then the file.
    pub(super) fn finish_scene(
        mut self,
        name: &str,
        nodes: Vec<json::Index<json::Node>>,
    ) -> Result<Vec<u8>> {
        let scene = self.root.push(json::Scene {
            extensions: None,
            extras: Default::default(),
            name: Some(name.into()),
            nodes,
        });
        self.root.scene = Some(scene);
        self.finish()
    }

    pub(super) fn material(
        &mut self,
        name: &str,
        rgba: [f32; 4],
        double_sided: bool,
    ) -> json::Index<json::Material> {
        self.root.push(json::Material {
            name: Some(name.into()),
            double_sided,
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor(rgba),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(0.9),
                ..Default::default()
            },
            ..Default::default()
        })
    }

    /// Appends `bytes` (4-byte aligned) as a buffer view.
    pub(super) fn view(
        &mut self,
        bytes: Vec<u8>,
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        let len = bytes.len();
        self.bin.extend(bytes);
        self.push_view(offset, len, target)
    }

    /// A buffer view of what `write` appends to the binary chunk (4-byte
    /// aligned), written there directly: the animation's keys are most of
    /// an animated file, and building them apart first would hold them
    /// twice. `None`, and the chunk as it was, when `write` appends nothing
    /// (a glTF buffer view may not be empty).
    pub(super) fn view_written(
        &mut self,
        target: Option<json::buffer::Target>,
        write: impl FnOnce(&mut Vec<u8>),
    ) -> Option<json::Index<json::buffer::View>> {
        let before = self.bin.len();
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        write(&mut self.bin);
        let len = self.bin.len() - offset;
        if len == 0 {
            self.bin.truncate(before);
            return None;
        }
        Some(self.push_view(offset, len, target))
    }

    /// Records the view of `len` bytes at `offset` in the binary chunk.
    fn push_view(
        &mut self,
        offset: usize,
        len: usize,
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(len),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        })
    }

    /// An accessor of `count` elements at `offset` in `view`; `bounds` adds
    /// min/max (required for POSITION and animation inputs).
    pub(super) fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        offset: usize,
        count: usize,
        component: ComponentType,
        type_: Type,
        bounds: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
        let (min, max) = match bounds {
            Some((lo, hi)) => (Some(json::Value::from(lo)), Some(json::Value::from(hi))),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: (offset > 0).then(|| USize64::from(offset)),
            count: USize64::from(count),
            component_type: Valid(GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A VEC3 float accessor; `bounds` adds min/max (required for POSITION).
    fn vec3(&mut self, data: &[[f32; 3]], bounds: bool) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = data
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let view = self.view(bytes, Some(json::buffer::Target::ArrayBuffer));
        let bounds = bounds.then(|| {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for p in data {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            (lo.to_vec(), hi.to_vec())
        });
        self.accessor(view, 0, data.len(), ComponentType::F32, Type::Vec3, bounds)
    }

    pub(super) fn indices(&mut self, data: &[u32]) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(bytes, Some(json::buffer::Target::ElementArrayBuffer));
        self.accessor(view, 0, data.len(), ComponentType::U32, Type::Scalar, None)
    }

    pub(super) fn triangle_mesh(
        &mut self,
        name: &str,
        mesh: &Mesh,
        material: json::Index<json::Material>,
        skin: Option<&dyn Skinning>,
    ) -> Result<Option<json::Index<json::Mesh>>> {
        if mesh.indices.is_empty() {
            return Ok(None);
        }
        if mesh.normals.len() != mesh.positions.len() {
            return Err(RenderError::Inconsistent(format!(
                "{name}: normals and positions differ in count"
            ))
            .into());
        }
        let positions = self.vec3(&mesh.positions, true);
        let normals = self.vec3(&mesh.normals, false);
        let indices = self.indices(&mesh.indices);
        let mut attributes = std::collections::BTreeMap::new();
        attributes.insert(Valid(json::mesh::Semantic::Positions), positions);
        attributes.insert(Valid(json::mesh::Semantic::Normals), normals);
        if let Some(skin) = skin {
            skin.bind(self, &mesh.binds, &mut attributes)?;
        }
        Ok(Some(self.mesh(
            name,
            attributes,
            indices,
            material,
            json::mesh::Mode::Triangles,
        )))
    }

    pub(super) fn skeleton(
        &mut self,
        tree: &Tree,
        skin: Option<&dyn Skinning>,
    ) -> Result<Option<json::Index<json::Mesh>>> {
        let positions: Vec<[f32; 3]> = tree
            .nodes
            .iter()
            .map(|n| n.position.as_vec3().to_array())
            .collect();
        let mut lines = Vec::with_capacity(2 * tree.nodes.len());
        for (i, n) in tree.nodes.iter().enumerate() {
            if let Some(p) = n.parent {
                let (a, b) = (u32::try_from(i), u32::try_from(p));
                let (Ok(a), Ok(b)) = (a, b) else {
                    return Err(RenderError::TooLarge("skeleton has more than 2^32 nodes").into());
                };
                lines.extend_from_slice(&[a, b]);
            }
        }
        if lines.is_empty() {
            return Ok(None);
        }
        let material = match self.skeleton {
            Some(m) => m,
            None => {
                let m = self.material("skeleton", [0.85, 0.12, 0.10, 1.0], false);
                self.skeleton = Some(m);
                m
            }
        };
        let pos = self.vec3(&positions, true);
        let idx = self.indices(&lines);
        let mut attributes = std::collections::BTreeMap::new();
        attributes.insert(Valid(json::mesh::Semantic::Positions), pos);
        if let Some(skin) = skin {
            // Each skeleton vertex is its node.
            let binds = (0..tree.nodes.len())
                .map(crate::reconstruct::mesh::Bind::node)
                .collect::<Result<Vec<_>>>()?;
            skin.bind(self, &binds, &mut attributes)?;
        }
        Ok(Some(self.mesh(
            "skeleton",
            attributes,
            idx,
            material,
            json::mesh::Mode::Lines,
        )))
    }

    pub(super) fn mesh(
        &mut self,
        name: &str,
        attributes: std::collections::BTreeMap<
            json::validation::Checked<json::mesh::Semantic>,
            json::Index<json::Accessor>,
        >,
        indices: json::Index<json::Accessor>,
        material: json::Index<json::Material>,
        mode: json::mesh::Mode,
    ) -> json::Index<json::Mesh> {
        self.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(name.into()),
            primitives: vec![json::mesh::Primitive {
                attributes,
                extensions: None,
                extras: Default::default(),
                indices: Some(indices),
                material: Some(material),
                mode: Valid(mode),
                targets: None,
            }],
            weights: None,
        })
    }

    pub(super) fn node(
        &mut self,
        name: &str,
        mesh: json::Index<json::Mesh>,
        skin: Option<&dyn Skinning>,
    ) -> json::Index<json::Node> {
        self.root.push(json::Node {
            mesh: Some(mesh),
            name: Some(name.into()),
            skin: skin.map(|s| s.index()),
            ..Default::default()
        })
    }

    pub(super) fn finish(mut self) -> Result<Vec<u8>> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.root.push(json::Buffer {
            byte_length: USize64::from(self.bin.len()),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        let mut text = self
            .root
            .to_vec()
            .map_err(|e| RenderError::Gltf(e.to_string()))?;
        while !text.len().is_multiple_of(4) {
            text.push(b' ');
        }
        let total = 12 + 8 + text.len() + 8 + self.bin.len();
        let total = u32::try_from(total).map_err(|_| {
            RenderError::TooLarge("the tree is too large for one .glb file (4 GiB)")
        })?;
        let mut head = Vec::with_capacity(total as usize - self.bin.len());
        head.extend_from_slice(&GLB_MAGIC.to_le_bytes());
        head.extend_from_slice(&2u32.to_le_bytes());
        head.extend_from_slice(&total.to_le_bytes());
        head.extend_from_slice(&(text.len() as u32).to_le_bytes());
        head.extend_from_slice(&CHUNK_JSON.to_le_bytes());
        head.extend_from_slice(&text);
        head.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
        head.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        // The header and JSON go in front of the binary chunk where it
        // lies (moved up in place), not into a copy of it: an animated
        // file's chunk is tens of megabytes.
        let mut out = std::mem::take(&mut self.bin);
        out.splice(0..0, head);
        Ok(out)
    }
}
