//! Peak memory while reading a Motive CSV export, to show it does not grow
//! with the length of the take: `cargo run --release --example read_rss -- FILE`
//! prints frames, samples and the process's peak RSS (VmHWM).

fn main() {
    let path = std::env::args().nth(1).expect("usage: read_rss FILE");
    let rec = treemocap::app::open::open(std::path::Path::new(&path)).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1)
    });
    let (mut frames, mut samples) = (0u64, 0u64);
    for f in rec {
        let f = f.unwrap_or_else(|e| {
            eprintln!("{e}");
            std::process::exit(1)
        });
        frames += 1;
        samples += f.markers.len() as u64;
    }
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let hwm = status
        .lines()
        .find(|l| l.starts_with("VmHWM"))
        .unwrap_or("VmHWM: ?");
    println!(
        "{path}: {frames} frames, {samples} samples, peak {}",
        hwm.trim_start_matches("VmHWM:").trim()
    );
}
