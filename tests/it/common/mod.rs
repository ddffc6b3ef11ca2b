pub mod crowns;
pub mod fills;
pub mod gltf;
pub mod natnet;
pub mod running;
pub mod tracked;
