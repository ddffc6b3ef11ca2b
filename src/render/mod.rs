//! The model as bytes: the tree as binary glTF, JSON and a PNG picture, and
//! the traces as a plot. Pure functions; writing the bytes somewhere is the
//! caller's business (`app`, `daemon`, `serve`).

mod animation;
pub mod error;
pub mod forest;
mod forest_report;
pub mod frames;
mod glb;
pub mod gltf;
pub mod json;
pub mod occlusion;
pub mod outputs;
pub mod picture;
pub mod plot;
pub mod raster;
pub mod trajectories;
