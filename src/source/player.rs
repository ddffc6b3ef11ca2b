//! Plays a recording into the pipeline at its recorded speed (or faster), as
//! a stand-in for a live rig: the daemon's default source, and how tests and
//! users drive the daemon without a rig.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::error::Result;
use crate::model::recording::Recording;
use crate::source::channel::FrameSink;

/// What a playback did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlayReport {
    /// Frames handed to the sink.
    pub frames: u64,
    /// Passes started again at the recording's end (`repeat`).
    pub loops: u64,
}

/// Pushes every frame of `rec` into `sink`, timed by the frames' own times
/// divided by `speed` (`speed <= 0` plays as fast as possible). With `repeat`,
/// `reopen` is called for each further pass and frame numbers and times
/// continue from the previous pass, as a rig that keeps running would.
pub fn play(
    mut rec: Box<dyn Recording>,
    reopen: &dyn Fn() -> Result<Box<dyn Recording>>,
    sink: &FrameSink,
    speed: f64,
    repeat: bool,
    shutdown: &AtomicBool,
) -> Result<PlayReport> {
    let mut report = PlayReport::default();
    let start = Instant::now();
    let mut first_time: Option<f64> = None;
    // Where the previous pass ended, so the next one continues after it.
    let mut previous_end: Option<(i64, f64)> = None;
    loop {
        let period = 1.0 / rec.info().frame_rate.max(1e-9);
        let mut offset: Option<(i64, f64)> = None;
        for frame in &mut *rec {
            if shutdown.load(Ordering::Relaxed) {
                return Ok(report);
            }
            let mut frame = frame?;
            let (df, dt) = *offset.get_or_insert_with(|| match previous_end {
                Some((f, t)) => (f + 1 - frame.frame, t + period - frame.time_s),
                None => (0, 0.0),
            });
            frame.frame += df;
            frame.time_s += dt;
            let t0 = *first_time.get_or_insert(frame.time_s);
            if speed > 0.0 {
                let due = Duration::from_secs_f64(((frame.time_s - t0) / speed).max(0.0));
                let elapsed = start.elapsed();
                if due > elapsed {
                    std::thread::sleep(due - elapsed);
                }
            }
            previous_end = Some((frame.frame, frame.time_s));
            report.frames += 1;
            if !sink.push(frame) {
                return Ok(report); // the pipeline is gone
            }
        }
        if !repeat || previous_end.is_none() {
            return Ok(report);
        }
        report.loops += 1;
        rec = reopen()?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::source::channel::frame_channel;
    use std::path::Path;

    fn open() -> Result<Box<dyn Recording>> {
        let p = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures/motive/quirks/v1.23_centimeters_jumps.csv");
        Ok(Box::new(crate::app::open::motive_csv(&p)?))
    }

    #[test]
    fn loops_continue_numbering_and_time() {
        let (sink, rx) = frame_channel(100);
        let stop = AtomicBool::new(false);
        let _ = play(open().unwrap(), &|| open(), &sink, 0.0, false, &stop).unwrap();
        let one: Vec<i64> = rx.try_iter().map(|f| f.frame).collect();
        assert_eq!(one, [72210, 72211, 72215, 72300]);

        // Repeat: the second pass starts right after the first. The third
        // reopen raises the shutdown flag, so exactly two passes go out.
        let (sink, rx) = frame_channel(100);
        let stop = AtomicBool::new(false);
        let reopened = std::sync::atomic::AtomicUsize::new(0);
        let reopen = || {
            if reopened.fetch_add(1, Ordering::SeqCst) == 1 {
                stop.store(true, Ordering::SeqCst);
            }
            open()
        };
        let report = play(open().unwrap(), &reopen, &sink, 0.0, true, &stop).unwrap();
        assert_eq!(
            report,
            PlayReport {
                frames: 8,
                loops: 2
            }
        );
        let got: Vec<(i64, f64)> = rx.try_iter().map(|f| (f.frame, f.time_s)).collect();
        let frames: Vec<i64> = got.iter().map(|g| g.0).collect();
        assert_eq!(
            frames,
            [72210, 72211, 72215, 72300, 72301, 72302, 72306, 72391]
        );
        assert!((got[4].1 - 723.01).abs() < 1e-9);
    }
}
