//! What treemocap produces: pictures (a small rasterizer of our own), and
//! later glTF, JSON, OSC and HTTP outputs.

pub mod plot;
pub mod raster;
