pub mod crowns;
