//! The stress settings of issue 14, shared by the accuracy tests (short
//! sessions) and `examples/track_stress.rs` (the full sweep behind the
//! README's table): a 70-tip tree captured at 240 Hz, swaying in the
//! tree-like model at 0.3–3 Hz, each stress alone and all combined.

use super::SynthOptions;

/// One named stress setting.
pub struct Stress {
    /// Short name (the table's first column).
    pub name: &'static str,
    /// What it stresses, for a reader.
    pub what: &'static str,
    /// The session's options.
    pub options: SynthOptions,
}

/// The base session: 70 tips, 240 Hz, `still_s` still then `wind_s` wind,
/// moderate sway (about 35 mm), 0.2 mm noise, 5 % occlusion, 1 ghost/s.
pub fn base(seed: u64, tips: usize, still_s: f64, wind_s: f64) -> SynthOptions {
    SynthOptions {
        seed,
        tips,
        frame_rate: 240.0,
        still_s,
        wind_s,
        sway_hz: vec![0.3, 3.0],
        spurious_per_s: 1.0,
        ..SynthOptions::default()
    }
}

/// Every stress at its issue-14 maximum, alone and combined, on `base`.
pub fn all(base: &SynthOptions) -> Vec<Stress> {
    let b = || base.clone();
    vec![
        Stress {
            name: "base",
            what: "sway ~35 mm, noise 0.2 mm, 5 % occluded, 1 ghost/s",
            options: b(),
        },
        Stress {
            name: "sway",
            what: "sway up to 150 mm (sway_scale 5)",
            options: SynthOptions {
                sway_scale: 5.0,
                ..b()
            },
        },
        Stress {
            name: "gusts",
            what: "12 gusts/min on sway_scale 2",
            options: SynthOptions {
                gusts_per_min: 12.0,
                sway_scale: 2.0,
                ..b()
            },
        },
        Stress {
            name: "ghosts",
            what: "10 ghost reflections/s",
            options: SynthOptions {
                spurious_per_s: 10.0,
                ..b()
            },
        },
        Stress {
            name: "noise",
            what: "noise σ 1 mm",
            options: SynthOptions {
                noise_mm: 1.0,
                ..b()
            },
        },
        Stress {
            name: "occlusion",
            what: "25 % of samples occluded",
            options: SynthOptions {
                gap_fraction: 0.25,
                ..b()
            },
        },
        Stress {
            name: "close",
            what: "10 pairs passing within ~15 mm",
            options: SynthOptions {
                close_pairs: 10,
                close_mm: 15.0,
                ..b()
            },
        },
        Stress {
            name: "all",
            what: "all of the above at once",
            options: SynthOptions {
                sway_scale: 5.0,
                gusts_per_min: 12.0,
                spurious_per_s: 10.0,
                noise_mm: 1.0,
                gap_fraction: 0.25,
                close_pairs: 10,
                close_mm: 15.0,
                ..b()
            },
        },
    ]
}
