//! What treemocap serves to other programs: the NatNet replay server.

pub mod natnet;
