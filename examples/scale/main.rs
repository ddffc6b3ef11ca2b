//! Issue 15's measured run: makes the long and wide sessions and runs every
//! scale target, then prints one table, the peers (pandas, py-c3d, ezc3d,
//! OptiTrack's natnetsdk) measured in the same run beside treemocap.
//!
//! ```text
//! cargo build --release && cargo run --release --example scale -- [--quick] [PARTS]
//! ```
//! PARTS: any of `csv daemon replay picture history peers` (default: all). `--quick`
//! shortens everything (30 s daemon runs, a 10-minute replay) for a smoke
//! run; the README's figures come from the full run. `SCALE_DAEMON_RATE=360`
//! (or `1000`) runs only that one of the two daemon runs. Python peers are
//! skipped with a note when not installed (`pip install -r
//! tests/peers/requirements.txt`). Nothing here is a test: the figures
//! depend on the machine and its load.

mod csv;
mod daemon;
mod history;
mod peers;
mod picture;
mod replay;
mod util;

use util::{Row, Scale};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let wanted: Vec<&str> = args
        .iter()
        .filter(|a| !a.starts_with("--"))
        .map(String::as_str)
        .collect();
    let want = |p: &str| wanted.is_empty() || wanted.contains(&p);
    let scale = Scale::new(quick);
    let mut rows: Vec<Row> = Vec::new();
    if want("csv") {
        rows.extend(csv::reading(&scale));
    }
    if want("daemon") {
        rows.extend(daemon::runs(&scale));
    }
    if want("replay") {
        rows.extend(replay::memory(&scale));
    }
    if want("picture") {
        rows.extend(picture::share(&scale));
    }
    if want("history") {
        rows.extend(history::growth(&scale));
    }
    if want("peers") {
        rows.extend(peers::c3d_and_natnet(&scale));
    }
    println!();
    println!("| what | target | treemocap | peers (same run) |");
    println!("|---|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {} | {} | {} |",
            r.what, r.target, r.measured, r.peers
        );
    }
}
