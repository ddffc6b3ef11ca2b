//! The daemon recording onto a disk that fills up and then frees space
//! again: a real (tiny) tmpfs, filled by another file, as happens when a
//! capture PC's disk runs full. The recording must end at its last whole
//! frame, count what it loses on `/status`, `/metrics` and in the log, and
//! go on in a new numbered file with its own header once space returns.
//!
//! Mounting needs root (as CI runs); elsewhere the test says so and fails.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use treemocap::app::open as replay;

use crate::common::running::Daemon;

/// A tmpfs of `size` mounted on `dir`, unmounted when dropped.
struct Tmpfs(PathBuf);

impl Tmpfs {
    fn mount(dir: &Path, size: &str) -> Tmpfs {
        std::fs::create_dir_all(dir).unwrap();
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "this test mounts a small tmpfs and needs root (CI runs as root): {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Tmpfs(dir.to_path_buf())
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// Writes zeros to `path` until the file system is full.
fn fill(path: &Path) {
    use std::io::Write;
    let mut f = std::fs::File::create(path).unwrap();
    let block = vec![0u8; 64 << 10];
    loop {
        match f.write(&block) {
            Ok(0) | Err(_) => break,
            Ok(_) => {}
        }
    }
    let _ = f.sync_all();
}

/// Frame number → markers in it, over a whole recording.
fn markers_per_frame(path: &Path) -> Vec<(i64, usize)> {
    let rec = replay::open(path).unwrap_or_else(|e| panic!("{e}"));
    let warnings = rec.warnings().to_vec();
    let frames: Vec<(i64, usize)> = rec
        .map(|f| {
            let f = f.unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            (f.frame, f.markers.len())
        })
        .collect();
    assert!(warnings.is_empty(), "{warnings:?}");
    frames
}

#[test]
fn a_full_disk_ends_the_file_at_a_whole_frame_counts_losses_and_resumes_in_a_new_file() {
    let dir = tempfile::tempdir().unwrap();
    let _fs = Tmpfs::mount(&dir.path().join("disk"), "8m");
    let out = dir.path().join("disk/out");
    let d = Daemon::start(
        &out,
        &[
            "daemon.record=true".into(),
            "daemon.replay_speed=2".into(),
            "daemon.replay_loop=true".into(),
            "record.flush_interval_s=0.1".into(),
        ],
    );
    let first = out.join("session.log.csv");
    let second = out.join("session-2.log.csv");
    d.wait_status(20, "recording", |s| {
        s["recording"]["frames_written"].as_u64() > Some(100)
    });

    // The disk fills up.
    let filler = dir.path().join("disk/filler");
    fill(&filler);
    let s = d.wait_status(20, "frames lost", |s| {
        s["recording"]["failing"] == true && s["recording"]["frames_lost"].as_u64() > Some(50)
    });
    assert!(
        s["recording"]["error"]
            .as_str()
            .unwrap()
            .contains("No space left"),
        "{s:#}"
    );
    let metrics = d.get("/metrics").unwrap();
    assert!(
        metrics.contains("treemocap_recording_failing 1"),
        "{metrics}"
    );
    let lost: u64 = metrics
        .lines()
        .find_map(|l| l.strip_prefix("treemocap_recording_frames_lost_total "))
        .unwrap()
        .parse()
        .unwrap();
    assert!(lost > 50, "{metrics}");
    assert!(!second.exists(), "no second file while the disk is full");

    // Space returns: a new numbered file with its own header.
    std::fs::remove_file(&filler).unwrap();
    let t0 = Instant::now();
    let s = d.wait_status(20, "a second file", |s| {
        s["recording"]["files"] == 2 && s["recording"]["failing"] == false
    });
    assert!(t0.elapsed() < Duration::from_secs(5), "{s:#}");
    d.wait_status(20, "frames in the second file", |_| {
        second.metadata().is_ok_and(|m| m.len() > 10_000)
    });
    let (status, log) = d.stop();
    assert!(status.success(), "{status}\n{log}");

    // The log said it once, then that it went on, then the summary.
    let errors = log.lines().filter(|l| l.contains("No space left")).count();
    assert!((1..=3).contains(&errors), "{log}");
    assert!(log.contains("continuing in"), "{log}");
    let summary = log
        .lines()
        .find(|l| l.contains("frames written in 2 files"))
        .unwrap_or_else(|| panic!("no summary:\n{log}"));
    assert!(
        summary.contains("frames lost while writes failed"),
        "{summary}"
    );

    // Both files read back whole, every frame with the markers of the source.
    let source: std::collections::HashMap<i64, usize> =
        markers_per_frame(&Path::new(env!("CARGO_MANIFEST_DIR")).join("replays/maple-24.csv"))
            .into_iter()
            .collect();
    let a = markers_per_frame(&first);
    let b = markers_per_frame(&second);
    assert!(a.len() > 100 && b.len() > 10, "{} {}", a.len(), b.len());
    for (frame, n) in a.iter().chain(&b) {
        assert_eq!(source.get(frame), Some(n), "frame {frame}");
    }
    assert!(std::fs::read(&first).unwrap().ends_with(b"\n"));
    let written: u64 = summary
        .split("recording: ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap();
    assert_eq!(written, (a.len() + b.len()) as u64, "{summary}");
}
