//! Files as bytes and readers: the recordings treemocap reads.

pub mod pcap;
