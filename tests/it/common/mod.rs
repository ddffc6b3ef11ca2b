pub mod crowns;
pub mod natnet;
pub mod running;
