//! The synthetic session generator checked the way a user would: the CSV is
//! read back with the `csv` crate directly (not through our own writer's
//! types) and compared with the truth file; the shipped replays are
//! regenerated with the documented command.

// Index loops over tips and frames read closer to the checks they make.
#![allow(clippy::needless_range_loop)]

use std::path::Path;
use std::process::Command;

use glam::DVec3;
use treemocap::sim::{self, CrownShape, SynthOptions, Truth};

/// A short session, so the suite stays quick.
fn short(seed: u64, tips: usize, shape: CrownShape) -> SynthOptions {
    SynthOptions {
        seed,
        tips,
        shape,
        still_s: 10.0,
        wind_s: 10.0,
        take_name: "test".into(),
        ..SynthOptions::default()
    }
}

fn csv_bytes(syn: &sim::Synthetic) -> Vec<u8> {
    let mut out = Vec::new();
    sim::write_motive_csv(syn, &mut out).unwrap();
    out
}

#[test]
fn same_seed_same_bytes_other_seed_other_bytes() {
    let opts = short(5, 24, CrownShape::Maple);
    let a = sim::generate(&opts).unwrap();
    let b = sim::generate(&opts).unwrap();
    assert_eq!(csv_bytes(&a), csv_bytes(&b));
    assert_eq!(
        serde_json::to_string(&a.truth).unwrap(),
        serde_json::to_string(&b.truth).unwrap()
    );
    let c = sim::generate(&SynthOptions { seed: 6, ..opts }).unwrap();
    assert_ne!(csv_bytes(&a), csv_bytes(&c));
    assert_ne!(a.truth.tree, c.truth.tree);
    assert_ne!(a.truth.wind_direction, c.truth.wind_direction);
}

#[test]
fn one_option_does_not_reshuffle_the_rest() {
    let opts = short(9, 30, CrownShape::Pine);
    let a = sim::generate(&opts).unwrap();
    let b = sim::generate(&SynthOptions {
        gap_fraction: 0.1,
        spurious_per_s: 2.0,
        ..opts.clone()
    })
    .unwrap();
    assert_eq!(a.truth.tree, b.truth.tree);
    assert_eq!(a.truth.tips, b.truth.tips);
    assert_eq!(a.truth.wind_direction, b.truth.wind_direction);
    // The same tree for another marker count.
    let c = sim::generate(&SynthOptions { tips: 50, ..opts }).unwrap();
    assert_eq!(a.truth.tree, c.truth.tree);
}

/// The CSV as read independently: row-1 pairs, column names, and per data
/// row the frame, the time text and each column's triple (None = empty).
struct Parsed {
    header: Vec<(String, String)>,
    names: Vec<String>,
    rows: Vec<(i64, String, Vec<Option<DVec3>>)>,
}

fn parse(bytes: &[u8]) -> Parsed {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(bytes);
    let records: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
    let row1: Vec<&str> = records[0].iter().collect();
    let header = row1
        .chunks(2)
        .map(|kv| (kv[0].to_string(), kv.get(1).unwrap_or(&"").to_string()))
        .collect();
    // Row 2 is empty: the csv crate skips blank lines, so the next record
    // must be the Type row.
    assert_eq!(&records[1][1], "Type");
    assert_eq!(&records[2][1], "Name");
    assert_eq!(&records[3][1], "ID");
    assert_eq!(&records[4][1], "");
    assert_eq!(&records[5][0], "Frame");
    assert_eq!(&records[5][1], "Time (Seconds)");
    let width = records[1].len();
    assert_eq!((width - 2) % 3, 0);
    let ncols = (width - 2) / 3;
    let mut names = Vec::new();
    for c in 0..ncols {
        let f = 2 + 3 * c;
        for k in 0..3 {
            assert_eq!(&records[1][f + k], "Marker");
            assert_eq!(&records[4][f + k], "Position");
            assert_eq!(&records[5][f + k], ["X", "Y", "Z"][k]);
            assert_eq!(records[2][f + k], records[2][f]);
            assert_eq!(records[3][f + k], records[3][f]);
        }
        names.push(records[2][f].to_string());
    }
    let mut rows = Vec::new();
    for r in &records[6..] {
        assert_eq!(r.len(), width, "every data row has the full column count");
        let mut cells = Vec::with_capacity(ncols);
        for c in 0..ncols {
            let f = 2 + 3 * c;
            let t: Vec<&str> = (0..3).map(|k| &r[f + k]).collect();
            if t.iter().all(|s| s.is_empty()) {
                cells.push(None);
            } else {
                for s in &t {
                    let decimals = s.split('.').nth(1).map(str::len);
                    assert_eq!(decimals, Some(6), "'{s}' should have 6 decimals");
                }
                let v: Vec<f64> = t.iter().map(|s| s.parse().unwrap()).collect();
                cells.push(Some(DVec3::new(v[0], v[1], v[2])));
            }
        }
        rows.push((r[0].parse().unwrap(), r[1].to_string(), cells));
    }
    Parsed {
        header,
        names,
        rows,
    }
}

/// Everything a user would check of a session against its truth file.
fn check_session(opts: &SynthOptions, dir: &Path) {
    let csv_path = dir.join(format!("{}-{}.csv", opts.shape, opts.tips));
    let summary = treemocap::app::synth::write_session(opts, &csv_path).unwrap();
    let bytes = std::fs::read(&csv_path).unwrap();
    let truth: Truth =
        serde_json::from_slice(&std::fs::read(sim::truth_path(&csv_path)).unwrap()).unwrap();
    assert_eq!(truth.version, 1);
    assert_eq!(truth.tips.len(), opts.tips);
    assert_eq!(summary.columns, truth.columns.len());

    // CRLF everywhere, no bare LF.
    let lf = bytes.iter().filter(|&&b| b == b'\n').count();
    let crlf = bytes.windows(2).filter(|w| w == b"\r\n").count();
    assert_eq!(lf, crlf);
    assert!(bytes.starts_with(b"Format Version,1.23,Take Name,"));
    assert!(bytes.windows(4).any(|w| w == b"\r\n\r\n"), "row 2 is empty");

    let p = parse(&bytes);
    let rate = format!("{:.6}", opts.frame_rate);
    let frames = truth.frames;
    let expected_header: Vec<(String, String)> = [
        ("Format Version", "1.23"),
        ("Take Name", opts.take_name.as_str()),
        ("Take Notes", ""),
        ("Capture Frame Rate", rate.as_str()),
        ("Export Frame Rate", rate.as_str()),
        ("Capture Start Time", "2013-05-08 10.00.00.000 AM"),
        ("Total Frames in Take", &frames.to_string()),
        ("Total Exported Frames", &frames.to_string()),
        ("Rotation Type", "Quaternion"),
        ("Length Units", "Millimeters"),
        ("Coordinate Space", "Global"),
    ]
    .iter()
    .map(|(k, v)| (k.to_string(), v.to_string()))
    .collect();
    assert_eq!(p.header, expected_header);
    assert_eq!(
        frames,
        ((opts.still_s + opts.wind_s) * opts.frame_rate).round() as usize
    );
    assert_eq!(p.rows.len(), frames);
    for (i, (frame, time, _)) in p.rows.iter().enumerate() {
        assert_eq!(*frame, i as i64);
        assert_eq!(*time, format!("{:.6}", i as f64 / opts.frame_rate));
    }

    // Column names are Motive's, unique, and the truth maps each one.
    assert_eq!(p.names.len(), truth.columns.len());
    let mut seen = std::collections::HashSet::new();
    for (name, col) in p.names.iter().zip(&truth.columns) {
        assert!(name.starts_with("Unlabeled "), "{name}");
        assert_eq!(name, &col.name);
        assert!(seen.insert(name.clone()), "duplicate column {name}");
    }

    // Per tip and frame, the measured position (mm) from whichever column
    // shows it; a column holds one unbroken stretch, and Motive opens a new
    // column after every gap.
    let ntips = truth.tips.len();
    let mut tip_pos: Vec<Vec<Option<DVec3>>> = vec![vec![None; frames]; ntips];
    let mut tip_columns = vec![0usize; ntips];
    let mut spurious = Vec::new();
    for (c, col) in truth.columns.iter().enumerate() {
        let present: Vec<usize> = (0..frames).filter(|&f| p.rows[f].2[c].is_some()).collect();
        assert!(!present.is_empty(), "column {} is empty", col.name);
        let (first, last) = (present[0], *present.last().unwrap());
        assert_eq!(present.len(), last - first + 1, "{} has a hole", col.name);
        assert_eq!(
            (first as i64, last as i64),
            (col.first_frame, col.last_frame)
        );
        match col.tip {
            Some(t) => {
                tip_columns[t] += 1;
                for f in first..=last {
                    assert!(
                        tip_pos[t][f].is_none(),
                        "tip {t} in two columns at frame {f}"
                    );
                    tip_pos[t][f] = p.rows[f].2[c];
                }
            }
            None => spurious.push((c, present.len(), p.rows[first].2[c].unwrap())),
        }
    }

    // Every gap the truth lists is empty in the CSV, and every missing
    // sample is in a listed gap.
    let mut listed = vec![vec![false; frames]; ntips];
    for g in &truth.gaps {
        assert!(g.first_frame <= g.last_frame);
        for f in g.first_frame..=g.last_frame {
            assert!(
                tip_pos[g.tip][f as usize].is_none(),
                "tip {} seen in its gap at {f}",
                g.tip
            );
            listed[g.tip][f as usize] = true;
        }
    }
    let mut missing = 0;
    for t in 0..ntips {
        for f in 0..frames {
            if tip_pos[t][f].is_none() {
                assert!(
                    listed[t][f],
                    "tip {t} missing at frame {f} without a listed gap"
                );
                missing += 1;
            }
        }
        let gaps_of_tip = truth.gaps.iter().filter(|g| g.tip == t).count();
        let starts_hidden = tip_pos[t][0].is_none() as usize;
        let ends_hidden = tip_pos[t][frames - 1].is_none() as usize;
        assert_eq!(
            tip_columns[t],
            gaps_of_tip + 1 - starts_hidden - ends_hidden,
            "tip {t}"
        );
    }
    let fraction = missing as f64 / (ntips * frames) as f64;
    assert!(
        (fraction - opts.gap_fraction).abs() < 0.01,
        "gap fraction {fraction}, asked {}",
        opts.gap_fraction
    );
    // Short bursts are 1–50 frames; long occlusions last seconds.
    let lens: Vec<i64> = truth
        .gaps
        .iter()
        .map(|g| g.last_frame - g.first_frame + 1)
        .collect();
    let long = (opts.long_gap_min_s * opts.frame_rate) as i64;
    assert!(lens.iter().all(|&l| l <= 50 || l >= long), "{lens:?}");
    assert!(
        lens.iter().any(|&l| l >= long),
        "no marker hidden for seconds"
    );
    assert!(lens.iter().filter(|&&l| l <= 50).count() > 2 * ntips);

    // Spurious reflections: a Poisson count near rate × duration (3.5 σ),
    // each living 1–50 frames, away from the tips.
    let expected = opts.spurious_per_s * (opts.still_s + opts.wind_s);
    let n = spurious.len() as f64;
    assert!(
        (n - expected).abs() <= 3.5 * expected.sqrt() + 1.0,
        "{n} spurious, expected {expected}"
    );
    assert_eq!(spurious.len(), truth.spurious.len());
    for &(c, life, at) in &spurious {
        assert!((1..=50).contains(&life), "column {c} lives {life} frames");
        for tip in &truth.tips {
            assert!(at.distance(tip.rest * 1000.0) > 45.0);
        }
    }

    // Still phase: every sample within 5σ + 1 mm of its tip's rest position,
    // and the residual from the noiseless truth has the asked σ.
    let sigma = opts.noise_mm;
    let still_end = (opts.still_s * opts.frame_rate) as usize;
    let (mut sum_sq, mut count) = (0.0, 0usize);
    for t in 0..ntips {
        let rest = truth.tips[t].rest * 1000.0;
        for f in 0..still_end {
            if let Some(x) = tip_pos[t][f] {
                let d = x.distance(rest);
                assert!(
                    d <= 5.0 * sigma + 1.0,
                    "tip {t} frame {f}: {d} mm from rest"
                );
                let r = x - truth.position(t, f as f64 / opts.frame_rate) * 1000.0;
                sum_sq += r.length_squared();
                count += 3;
            }
        }
        // The tiny periodic motion stays within 1 mm.
        for f in 0..still_end {
            let d = truth.position(t, f as f64 / opts.frame_rate) - truth.tips[t].rest;
            assert!(d.length() <= 0.001, "tip {t} wobbles {} m", d.length());
        }
    }
    let measured_sigma = (sum_sq / count as f64).sqrt();
    assert!(
        (measured_sigma - sigma).abs() < 0.1 * sigma,
        "noise σ {measured_sigma} mm"
    );

    // Wind phase: tips bend downwind on average, sway mostly along the wind,
    // by up to a few centimetres.
    let wind = truth.wind_direction;
    assert!((wind.length() - 1.0).abs() < 1e-6 && wind.y == 0.0);
    let cross = DVec3::Y.cross(wind);
    let (mut downwind, mut along_wins, mut peak) = (0, 0, 0.0f64);
    for t in 0..ntips {
        let rest = truth.tips[t].rest * 1000.0;
        let samples: Vec<DVec3> = (still_end..frames)
            .filter_map(|f| tip_pos[t][f])
            .map(|x| x - rest)
            .collect();
        let mean = samples.iter().copied().sum::<DVec3>() / samples.len() as f64;
        if mean.dot(wind) > 0.0 {
            downwind += 1;
        }
        let var = |axis: DVec3| {
            samples
                .iter()
                .map(|d| (d - mean).dot(axis).powi(2))
                .sum::<f64>()
        };
        if var(wind) > var(cross) {
            along_wins += 1;
        }
        for d in &samples {
            peak = peak.max(d.length());
        }
    }
    assert!(
        downwind * 10 >= ntips * 9,
        "{downwind} of {ntips} tips bend downwind"
    );
    assert!(
        along_wins * 10 >= ntips * 8,
        "{along_wins} of {ntips} sway mainly along the wind"
    );
    assert!(
        (10.0..=80.0).contains(&peak),
        "peak wind displacement {peak} mm"
    );

    // Marked tips stay at least the minimum spacing apart (from the CSV's
    // still-phase means, not only from the truth).
    let means: Vec<DVec3> = (0..ntips)
        .map(|t| {
            let xs: Vec<DVec3> = (0..still_end).filter_map(|f| tip_pos[t][f]).collect();
            xs.iter().copied().sum::<DVec3>() / xs.len() as f64
        })
        .collect();
    for a in 0..ntips {
        for b in 0..a {
            let d = means[a].distance(means[b]);
            assert!(
                d >= opts.min_spacing_mm - 1.0,
                "tips {a} and {b} are {d} mm apart"
            );
        }
    }

    // Lab-sized tree.
    assert!(
        (1.5..=3.0).contains(&truth.tree.height),
        "{}",
        truth.tree.height
    );

    // The project's own reader sees exactly the frames the simulator made.
    let syn = sim::generate(&truth.options).unwrap();
    assert_eq!(syn.truth, truth, "the truth file round-trips");
    let rec = treemocap::app::open::open(&csv_path).unwrap();
    let mut n = 0;
    for (got, want) in rec.zip(&syn.frames) {
        let got = got.unwrap();
        assert_eq!(got.frame, want.frame);
        assert_eq!(got.markers, want.markers, "frame {}", want.frame);
        n += 1;
    }
    assert_eq!(n, frames);
}

#[test]
fn maple_csv_agrees_with_truth() {
    let dir = tempfile::tempdir().unwrap();
    check_session(&short(11, 24, CrownShape::Maple), dir.path());
}

#[test]
fn pine_csv_agrees_with_truth() {
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        gap_fraction: 0.08,
        spurious_per_s: 3.0,
        noise_mm: 0.5,
        frame_rate: 120.0,
        ..short(12, 35, CrownShape::Pine)
    };
    check_session(&opts, dir.path());
}

#[test]
fn no_gaps_no_spurious_gives_one_column_per_tip() {
    let syn = sim::generate(&SynthOptions {
        gap_fraction: 0.0,
        spurious_per_s: 0.0,
        ..short(3, 40, CrownShape::Maple)
    })
    .unwrap();
    assert!(syn.truth.gaps.is_empty());
    assert_eq!(syn.columns.len(), 40);
    assert!(syn.frames.iter().all(|f| f.markers.len() == 40));
}

#[test]
fn bad_options_are_config_errors_naming_the_option() {
    for (opts, key) in [
        (
            SynthOptions {
                tips: 0,
                ..SynthOptions::default()
            },
            "tips",
        ),
        (
            SynthOptions {
                tips: 71,
                ..SynthOptions::default()
            },
            "tips",
        ),
        (
            SynthOptions {
                gap_fraction: 0.9,
                ..SynthOptions::default()
            },
            "gap_fraction",
        ),
        (
            SynthOptions {
                frame_rate: f64::NAN,
                ..SynthOptions::default()
            },
            "frame_rate",
        ),
        (
            SynthOptions {
                min_spacing_mm: 900.0,
                ..SynthOptions::default()
            },
            "tips",
        ),
    ] {
        match sim::generate(&opts) {
            Err(e @ treemocap::Error::Config { .. }) => {
                assert_eq!(e.exit_code(), 2);
                assert!(e.to_string().contains(key), "{e}");
            }
            other => panic!(
                "expected a config error for {key}, got {:?}",
                other.map(|_| ())
            ),
        }
    }
}

/// The exact commands the README documents for the shipped replays.
const SHIPPED: [(&str, &[&str]); 2] = [
    (
        "maple-24",
        &["--seed", "24", "--tips", "24", "--shape", "maple"],
    ),
    (
        "pine-35",
        &["--seed", "35", "--tips", "35", "--shape", "pine"],
    ),
];

#[test]
fn shipped_replays_regenerate_byte_identically() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (name, args) in SHIPPED {
        let out = dir.path().join(format!("{name}.csv"));
        let status = Command::new(env!("CARGO_BIN_EXE_treemocap"))
            .arg("synth")
            .args(args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            status.status.success(),
            "{}",
            String::from_utf8_lossy(&status.stderr)
        );
        let shipped = root.join("replays").join(format!("{name}.csv"));
        let shipped_bytes = std::fs::read(&shipped).unwrap();
        assert!(shipped_bytes.len() < 10_000_000, "{name}.csv is too big");
        assert!(
            std::fs::read(&out).unwrap() == shipped_bytes,
            "{name}.csv differs from its synth command"
        );
        let a = std::fs::read(sim::truth_path(&out)).unwrap();
        let b = std::fs::read(sim::truth_path(&shipped)).unwrap();
        assert!(a == b, "{name}.truth.json differs from its synth command");
        let truth: Truth = serde_json::from_slice(&b).unwrap();
        assert_eq!(truth.frame_rate, 100.0);
        assert_eq!((truth.still, truth.wind), ((0.0, 20.0), (20.0, 40.0)));
    }
}

#[test]
fn cli_rejects_bad_options_with_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(["synth", "--tips", "500", "--out"])
        .arg(dir.path().join("x.csv"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("tips") && err.lines().count() == 1, "{err}");
    let out = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(["synth", "--shape", "oak", "--out", "x.csv"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}
