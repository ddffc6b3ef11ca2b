//! `replay` against `tips` on a one-hour session at 240 Hz × 70 tips: peak
//! RSS of the two programs on the same file (the replay adds wind and
//! reconstruction; the sway PCA keeps running sums, not samples).

use std::process::Command;
use std::time::Duration;

use treemocap::format::log::{LogHeader, LogWriter};

#[path = "../common/hour_session.rs"]
#[allow(dead_code)]
pub mod hour_session;

use crate::util::{peak_rss, treemocap_bin, Row, Scale};

/// Peak RSS of `tips` and `replay` on one long log.
pub fn memory(scale: &Scale) -> Vec<Row> {
    let seconds = if scale.quick { 600.0 } else { 3600.0 };
    let log = scale.path("hour.log.csv");
    let header = LogHeader {
        source: "scale".into(),
        frame_rate: 240.0,
    };
    let mut w = LogWriter::create(&log, &header, Duration::from_secs(1)).expect("log");
    hour_session::for_each_frame(seconds, 240.0, 70, |f| w.write_frame(f).expect("write"));
    w.finish().expect("finish");
    let bin = treemocap_bin();
    let (tips_s, tips_mb) = peak_rss(Command::new(&bin).arg("tips").arg(&log));
    let out = scale.path("replay-out");
    let (replay_s, replay_mb) = peak_rss(
        Command::new(&bin)
            .arg("replay")
            .arg(&log)
            .arg("--out")
            .arg(&out),
    );
    println!(
        "replay vs tips, {seconds} s at 240 Hz × 70: tips {tips_mb:.0} MB in {tips_s:.0} s, replay {replay_mb:.0} MB in {replay_s:.0} s"
    );
    vec![Row::new(
        format!("`replay` of {} min at 240 Hz × 70 tips, peak RSS", seconds / 60.0),
        "≤ 1.2 × `tips`, ≤ 400 MB",
        format!(
            "{replay_mb:.0} MB = {:.2} × `tips` ({tips_mb:.0} MB); {replay_s:.0} s vs {tips_s:.0} s",
            replay_mb / tips_mb
        ),
        "—".into(),
    )]
}
