//! treemocap's integration tests: one test binary, one module per
//! capability, so the crate and its dependencies are linked once. Each module
//! drives the program as a user would: real files, real UDP sockets on
//! 127.0.0.1, real third-party peers (tests/peers/), pseudo-terminals.

mod common;

mod animate;
mod c3d;
mod cli;
mod daemon;
mod daemon_first_minutes;
mod disk_full;
mod export;
mod forest;
mod gaps_fill;
mod hostile_input;
mod http_limits;
mod live_forest;
mod live_view;
mod log_format;
mod motive_csv;
mod motive_csv_parallel;
mod natnet_bad_input;
mod natnet_loopback;
mod natnet_packet;
mod natnet_pcap;
mod natnet_peers;
mod osc;
mod outputs;
mod reconstruct;
mod record_natnet;
mod replay;
mod run_anywhere;
mod sim;
mod texts;
mod tracking_accuracy;
mod tracking_fixtures;
mod tracking_stress;
mod wind_serial;
