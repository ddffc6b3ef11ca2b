pub mod crowns;
pub mod natnet;
