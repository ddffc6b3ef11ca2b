//! Which recorded frames become the animation's keys: the frame nearest to
//! every `start + j / rate` in the window, so that a key is a captured
//! instant (its tips are exactly the tracked ones), never an interpolation
//! between frames.

use super::AnimateSettings;
use crate::error::{Error, Result};

/// The keys of an animation.
#[derive(Debug, Clone, PartialEq)]
pub struct Keys {
    /// Internal frame of each key, increasing.
    pub frames: Vec<i64>,
    /// Recording time of each key (s), strictly increasing, also in f32
    /// (the glTF stores key times as f32).
    pub times: Vec<f64>,
    /// The window asked for was longer than `max_duration_s` and was cut.
    pub cut: bool,
}

/// The keys of `settings.window_s` (or the whole recording) at
/// `settings.rate_hz`, among frames at `times` (s, not decreasing).
pub fn choose_keys(times: &[f64], settings: &AnimateSettings) -> Result<Keys> {
    let (Some(&first), Some(&last)) = (times.first(), times.last()) else {
        return Err(Error::Runtime("no frames to animate".into()));
    };
    let (mut start, mut end) = settings.window().unwrap_or((first, last));
    if !(start.is_finite() && end.is_finite() && start < end && start <= last && end >= first) {
        return Err(Error::config(
            "animate.window_s",
            format!(
                "[{start}, {end}] does not overlap the recording ({first:.3} s to {last:.3} s)"
            ),
        ));
    }
    start = start.max(first);
    end = end.min(last);
    let cut = end - start > settings.max_duration_s;
    if cut {
        end = start + settings.max_duration_s;
    }
    let step = 1.0 / settings.rate_hz;
    let mut keys = Keys {
        frames: Vec::new(),
        times: Vec::new(),
        cut,
    };
    let mut j = 0u64;
    loop {
        let t = start + j as f64 * step;
        if t > end + 1e-9 {
            break;
        }
        j += 1;
        let frame = nearest(times, t);
        let time = times[frame];
        let prev = keys.times.last().copied();
        // Strictly increasing, in f32 too (rates above the frame rate, or
        // frames with equal times, give the same frame twice).
        if prev.is_some_and(|p| time <= p || (time - start) as f32 <= (p - start) as f32) {
            continue;
        }
        keys.frames.push(frame as i64);
        keys.times.push(time);
    }
    if keys.frames.is_empty() {
        return Err(Error::Runtime("the animation window holds no frame".into()));
    }
    Ok(keys)
}

/// Index of the time nearest to `t` in the increasing `times` (ties to the
/// earlier frame).
fn nearest(times: &[f64], t: f64) -> usize {
    let i = times.partition_point(|&x| x < t);
    if i == 0 {
        return 0;
    }
    if i >= times.len() {
        return times.len() - 1;
    }
    if t - times[i - 1] <= times[i] - t {
        i - 1
    } else {
        i
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn timeline(n: usize, rate: f64, t0: f64) -> Vec<f64> {
        (0..n).map(|i| t0 + i as f64 / rate).collect()
    }

    #[test]
    fn keys_are_the_nearest_frames_at_the_rate() {
        // 100 Hz, 2 s from t = 5: 30 Hz keys at frames 0, 3, 7, 10, 13, 17, ...
        let tl = timeline(201, 100.0, 5.0);
        let k = choose_keys(&tl, &AnimateSettings::default()).unwrap();
        assert_eq!(&k.frames[..6], &[0, 3, 7, 10, 13, 17]);
        assert_eq!(k.frames.len(), 61);
        assert_eq!(*k.frames.last().unwrap(), 200);
        assert!(!k.cut);
        for (f, t) in k.frames.iter().zip(&k.times) {
            assert_eq!(*t, tl[*f as usize]);
        }
    }

    #[test]
    fn windows_are_clamped_cut_and_checked() {
        let tl = timeline(1001, 100.0, 0.0);
        let s = AnimateSettings {
            window_s: vec![2.0, 4.0],
            ..AnimateSettings::default()
        };
        let k = choose_keys(&tl, &s).unwrap();
        assert_eq!(k.frames.first(), Some(&200));
        assert_eq!(k.frames.last(), Some(&400));
        let s = AnimateSettings {
            window_s: vec![-3.0, 4.0],
            max_duration_s: 1.0,
            ..AnimateSettings::default()
        };
        let k = choose_keys(&tl, &s).unwrap();
        assert!(k.cut);
        assert_eq!((k.frames[0], *k.frames.last().unwrap()), (0, 100));
        let s = AnimateSettings {
            window_s: vec![20.0, 30.0],
            ..AnimateSettings::default()
        };
        let e = choose_keys(&tl, &s).unwrap_err().to_string();
        assert!(e.contains("animate.window_s"), "{e}");
        assert!(choose_keys(&[], &AnimateSettings::default()).is_err());
    }

    #[test]
    fn a_rate_above_the_frame_rate_never_repeats_a_frame() {
        let tl = timeline(11, 10.0, 0.0);
        let s = AnimateSettings {
            rate_hz: 240.0,
            ..AnimateSettings::default()
        };
        let k = choose_keys(&tl, &s).unwrap();
        assert_eq!(k.frames, (0..11).collect::<Vec<i64>>());
    }
}
