//! The identity floor over the stress sweep's sessions (`sim::floor`):
//! how many samples an oracle that knows every tip's true path is
//! expected to put in the wrong tip where two measured markers pass
//! within their noise, beside what it put there in the sessions' samples,
//! and how often two measured tips came within a marker's diameter.
//!
//! `cargo run --release --example exchange_floor [SEEDS] [STRESS]`
//! (defaults: `100..250`, `all`; 70 tips, 8 s still, 20 s of wind, as
//! `track_stress` runs them). Seeds whose options make no session (too
//! few markers fit) are counted and skipped.

use treemocap::sim::{self, floor, stress};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seeds: std::ops::Range<u64> = match args.get(1).and_then(|s| s.split_once("..")) {
        Some((a, b)) => a.parse().unwrap_or(100)..b.parse().unwrap_or(250),
        None => 100..250,
    };
    let name = args.get(2).map(String::as_str).unwrap_or("all");
    let (mut expected, mut oracle, mut sessions, mut skipped) = (0.0, 0usize, 0usize, 0usize);
    let mut close = [0usize; 4];
    for seed in seeds.clone() {
        let Some(st) = stress::named(&stress::base(seed, 70, 8.0, 20.0), name) else {
            eprintln!("no stress named {name}");
            std::process::exit(2);
        };
        let Ok(syn) = sim::generate(&st.options) else {
            skipped += 1;
            continue;
        };
        let f = floor::floor(&syn.truth);
        expected += f.expected;
        for (c, n) in close.iter_mut().zip(f.close_frames) {
            *c += n;
        }
        oracle += floor::oracle_wrong_samples(&syn);
        sessions += 1;
    }
    println!(
        "{name}, seeds {}..{}: {sessions} sessions ({skipped} skipped)",
        seeds.start, seeds.end
    );
    println!("oracle's wrong samples: {expected:.1} expected, {oracle} in these samples");
    println!(
        "frames × pairs of tips both measured, centres under 3 mm apart: {}, 3–6.4 mm: {}, 6.4–9.5 mm: {}, 9.5–12.7 mm: {}",
        close[0], close[1], close[2], close[3]
    );
}
