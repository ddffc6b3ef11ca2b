//! C3D files from an independent writer (py-c3d, tests/peers/c3d_variants.py)
//! read back through `replay::open`, plus damaged copies of them.
//!
//! Needs python3 with the packages of tests/peers/requirements.txt.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use glam::DVec3;
use serde_json::Value;
use treemocap::app::open::{self as replay, ReplayOptions};
use treemocap::format::c3d::{C3dOptions, C3dReader};
use treemocap::model::recording::Format;
use treemocap::rng::Rng;

fn python() -> String {
    std::env::var("TREEMOCAP_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// The py-c3d files, written once per test run into cargo's scratch folder.
fn variants() -> &'static Value {
    static MANIFEST: OnceLock<Value> = OnceLock::new();
    MANIFEST.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("c3d_variants");
        std::fs::create_dir_all(&dir).unwrap();
        write_variants(&dir)
    })
}

/// Runs the py-c3d writer into `dir` and returns its manifest.
fn write_variants(dir: &Path) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers/c3d_variants.py");
    let out = Command::new(python())
        .arg(&script)
        .arg(dir)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {} ({e}); install python3 and `pip install -r tests/peers/requirements.txt`", python()));
    assert!(
        out.status.success(),
        "{} failed (install the peers: pip install -r tests/peers/requirements.txt):\n{}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("manifest is JSON")
}

fn fixtures() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/c3d");
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "c3d"))
        .collect();
    files.sort();
    files
}

/// py-c3d's counts for `files` (tests/peers/c3d_counts.py).
fn py_c3d_counts(files: &[PathBuf]) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers/c3d_counts.py");
    let out = Command::new(python())
        .arg(&script)
        .args(files)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run {} ({e}); install python3 and the peers",
                python()
            )
        });
    assert!(
        out.status.success(),
        "{} failed (install the peers: pip install -r tests/peers/requirements.txt):\n{}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("py-c3d counts are JSON")
}

fn xyz(v: &Value) -> DVec3 {
    let a: Vec<f64> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    DVec3::new(a[0], a[1], a[2])
}

#[test]
fn every_processor_and_storage_from_py_c3d_reads_back_exactly() {
    let manifest = variants();
    let files = manifest["files"].as_array().unwrap();
    assert_eq!(files.len(), 6);
    for file in files {
        let path = PathBuf::from(file["path"].as_str().unwrap());
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        assert_eq!(replay::detect(&path).unwrap(), Format::C3d);
        // By content, not by name.
        let renamed = path.with_extension("csv");
        std::fs::copy(&path, &renamed).unwrap();
        assert_eq!(replay::detect(&renamed).unwrap(), Format::C3d);
        let mut rec = replay::open(&path).unwrap_or_else(|e| panic!("{e}"));
        let info = rec.info().clone();
        assert_eq!(
            info.version,
            format!(
                "{} {}",
                file["processor"].as_str().unwrap(),
                file["storage"].as_str().unwrap()
            )
        );
        assert_eq!(info.frame_rate, 100.0);
        assert_eq!(info.units, "mm");
        // The writer set POINT:Y_SCREEN = +Z.
        assert_eq!(info.up_axis, "Z");
        let float = file["storage"] == "float32";
        // int16 files hold multiples of 0.1 mm; float32 ~1e-4 mm at 1 m.
        let tol = if float { 1e-7 } else { 0.05e-3 + 1e-9 };
        let expected = file["frames"].as_array().unwrap();
        let mut n = 0;
        for (f, frame) in rec.by_ref().enumerate() {
            let frame = frame.unwrap_or_else(|e| panic!("{e}"));
            n += 1;
            assert_eq!(frame.frame, f as i64 + 1);
            assert!((frame.time_s - f as f64 / 100.0).abs() < 1e-12);
            let want: Vec<(i64, DVec3)> = expected[f]
                .as_array()
                .unwrap()
                .iter()
                .enumerate()
                .filter(|(_, p)| !p.is_null())
                .map(|(i, p)| {
                    // mm, Z up in the file -> metres, Y up: (x, z, -y).
                    let p = xyz(p) / 1000.0;
                    (i as i64, DVec3::new(p.x, p.z, -p.y))
                })
                .collect();
            assert_eq!(
                frame
                    .markers
                    .iter()
                    .map(|m| m.id.unwrap())
                    .collect::<Vec<_>>(),
                want.iter().map(|w| w.0).collect::<Vec<_>>(),
                "{name} frame {f}"
            );
            for (m, (_, w)) in frame.markers.iter().zip(&want) {
                assert!(
                    (m.position - *w).abs().max_element() <= tol,
                    "{name} frame {f}: {} vs {w}",
                    m.position
                );
            }
        }
        assert_eq!(n, expected.len(), "{name}");
        let labels: Vec<&str> = file["labels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_str().unwrap())
            .collect();
        let channels = rec.channels();
        assert_eq!(
            channels.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(),
            labels
        );
        for (i, c) in channels.iter().enumerate() {
            let missing = expected.iter().filter(|fr| fr[i].is_null()).count() as u64;
            assert_eq!(
                (c.present, c.empty_cells),
                (n as u64 - missing, missing),
                "{name} {}",
                c.name
            );
        }
        assert!(rec.warnings().is_empty(), "{name}: {:?}", rec.warnings());
    }

    // Past 65535 frames: py-c3d writes TRIAL:ACTUAL_END_FIELD and POINT:LONG_FRAMES.
    let long = &manifest["long"];
    let path = Path::new(long["path"].as_str().unwrap());
    let mut rec = replay::open(path).unwrap();
    let (mut frames, mut empty, mut last) = (0u64, 0u64, Vec::new());
    for f in rec.by_ref() {
        let f = f.unwrap();
        frames += 1;
        empty += f.markers.is_empty() as u64;
        last.push(f);
        if last.len() > 2 {
            last.remove(0);
        }
    }
    assert_eq!(frames, long["frames"].as_u64().unwrap());
    assert_eq!(empty, long["missing"].as_u64().unwrap());
    assert_eq!(rec.channels()[0].empty_cells, empty);
    // The last frame (index 69999) is a gap; the one before is
    // (998, 0, 69) mm with no Y_SCREEN, so Z up.
    assert_eq!(last[1].frame, 70_000);
    assert!(last[1].markers.is_empty());
    assert!((last[0].markers[0].position - DVec3::new(0.998, 0.069, 0.0)).length() < 1e-12);
}

#[test]
fn real_files_agree_with_py_c3d() {
    let files = fixtures();
    assert!(files.len() >= 3, "{files:?}");
    let oracle = py_c3d_counts(&files);
    for (path, want) in files.iter().zip(oracle.as_array().unwrap()) {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let mut rec = replay::open(path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(rec.info().format, Format::C3d);
        assert_eq!(
            rec.info().frame_rate,
            want["rate"].as_f64().unwrap(),
            "{name}"
        );
        // Vicon files are Z up (POINT:Y_SCREEN +Z, or no screen axes).
        assert_eq!(rec.info().up_axis, "Z");
        let (mut frames, mut first, mut sums) = (0u64, None, [0.0f64; 3]);
        for f in rec.by_ref() {
            let f = f.unwrap_or_else(|e| panic!("{e}"));
            first.get_or_insert(f.frame);
            frames += 1;
            for m in &f.markers {
                // Back to the file's mm, Z up: x, y = -z', z = y'.
                let p = m.position * 1000.0;
                sums[0] += p.x;
                sums[1] -= p.z;
                sums[2] += p.y;
            }
        }
        assert_eq!(frames, want["frames"].as_u64().unwrap(), "{name}");
        assert_eq!(first, Some(want["first_frame"].as_i64().unwrap()), "{name}");
        let channels = rec.channels();
        assert_eq!(
            channels.len() as u64,
            want["points"].as_u64().unwrap(),
            "{name}"
        );
        let missing: Vec<u64> = channels.iter().map(|c| c.empty_cells).collect();
        let want_missing: Vec<u64> = want["missing"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        assert_eq!(missing, want_missing, "{name}");
        assert!(channels.iter().all(|c| c.present + c.empty_cells == frames));
        assert!(rec.warnings().is_empty(), "{name}: {:?}", rec.warnings());
        let labels: Vec<&str> = want["labels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_str().unwrap())
            .collect();
        if !labels.is_empty() {
            assert_eq!(
                channels.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(),
                labels,
                "{name}"
            );
        }
        for (k, w) in want["sums"].as_array().unwrap().iter().enumerate() {
            let w = w.as_f64().unwrap();
            assert!(
                (sums[k] - w).abs() <= 1e-9 * w.abs() + 1e-6,
                "{name} axis {k}: {} vs {w}",
                sums[k]
            );
        }
    }
}

#[test]
fn up_axis_setting_overrides_the_file() {
    let manifest = variants();
    let path = PathBuf::from(manifest["files"][0]["path"].as_str().unwrap());
    let config = treemocap::config::Config::load(None, &["c3d.up_axis=y".into()]).unwrap();
    let mut rec = replay::open_with(&path, &ReplayOptions::from_config(&config)).unwrap();
    assert_eq!(rec.info().up_axis, "Y");
    let first = rec.next().unwrap().unwrap();
    let want = xyz(&manifest["files"][0]["frames"][0][1]) / 1000.0;
    assert!((first.markers[0].position - want).abs().max_element() <= 0.05e-3 + 1e-9);
    let e = treemocap::config::Config::load(None, &["c3d.up_axis=x".into()]).unwrap_err();
    assert!(
        e.to_string().contains("up_axis") || e.to_string().contains("variant"),
        "{e}"
    );
}

#[test]
fn damaged_files_give_errors_naming_file_and_byte_never_panics() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = variants();
    let originals: Vec<Vec<u8>> = manifest["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| PathBuf::from(f["path"].as_str().unwrap()))
        .chain(fixtures())
        .map(|p| std::fs::read(p).unwrap())
        .collect();
    let bad = dir.path().join("damaged.c3d");

    // Cut inside the data: every complete frame, and no error after them.
    let intel_int = &originals[0];
    let data_block = u16::from_le_bytes([intel_int[16], intel_int[17]]) as usize;
    let frame_bytes = 5 * 8 + 4 * 2;
    std::fs::write(
        &bad,
        &intel_int[..(data_block - 1) * 512 + 7 * frame_bytes + 3],
    )
    .unwrap();
    let rec = replay::open(&bad).unwrap();
    assert!(rec.warnings()[0].contains("holds 7 complete ones"));
    let results: Vec<_> = rec.collect();
    assert_eq!(results.len(), 7);
    assert!(results.iter().all(|r| r.is_ok()));

    // A data block pointer beyond the file, in header and parameter alike.
    let mut b = intel_int.clone();
    b[16..18].copy_from_slice(&5000u16.to_le_bytes());
    let ds = b.windows(10).position(|w| w == b"DATA_START").unwrap();
    b[ds + 14..ds + 16].copy_from_slice(&5000u16.to_le_bytes());
    std::fs::write(&bad, &b).unwrap();
    let e = replay::open(&bad).err().unwrap().to_string();
    assert!(
        e.contains("damaged.c3d: byte 16") && e.contains("5000"),
        "{e}"
    );

    // Seeded random mutations of every variant and every real file: errors
    // are fine, panics are not.
    let mut rng = Rng::new(20_241_107);
    let mut errors = 0;
    for round in 0..900 {
        let mut b = originals[round % originals.len()].clone();
        // Most damage goes where the structure is: header and parameters.
        let hot = if rng.chance(0.7) {
            b.len().min(8192)
        } else {
            b.len()
        };
        for _ in 0..rng.int(1, 6) {
            let at = rng.int(0, hot as i64 - 1) as usize;
            b[at] = rng.int(0, 255) as u8;
        }
        if rng.chance(0.15) {
            b.truncate(rng.int(0, b.len() as i64) as usize);
        }
        match C3dReader::from_bytes(Path::new("mutant.c3d"), b, &C3dOptions::default()) {
            Ok(rec) => {
                for f in rec.take(200_000) {
                    if let Err(e) = f {
                        assert!(e.to_string().starts_with("mutant.c3d: byte "), "{e}");
                        errors += 1;
                        break;
                    }
                }
            }
            Err(e) => {
                assert!(e.to_string().starts_with("mutant.c3d: byte "), "{e}");
                errors += 1;
            }
        }
    }
    assert!(errors > 0);
}

/// A real capture cut short, as a full disk or an interrupted copy leaves
/// it: `inspect` reads the frames py-c3d reads, warns once with both counts,
/// and `--strict` refuses the file.
#[test]
fn a_capture_cut_short_reads_like_py_c3d_and_strict_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let original = fixtures().into_iter().next().unwrap();
    let bytes = std::fs::read(&original).unwrap();
    // Keep the header, the parameters and a third of the data, cut mid-frame.
    let data_block = u16::from_le_bytes([bytes[16], bytes[17]]) as usize;
    let data_start = (data_block - 1) * 512;
    let cut_at = data_start + (bytes.len() - data_start) / 3 + 5;
    let cut = dir.path().join("cut short.c3d");
    std::fs::write(&cut, &bytes[..cut_at]).unwrap();

    let declared = py_c3d_counts(&[original])[0]["frames"].as_u64().unwrap();
    let holds = py_c3d_counts(std::slice::from_ref(&cut))[0]["frames"]
        .as_u64()
        .unwrap();
    assert!(holds > 0 && holds < declared, "{holds} of {declared}");

    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_treemocap"))
            .args(args)
            .arg(&cut)
            .output()
            .unwrap()
    };
    let out = run(&["inspect", "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frames"].as_u64(), Some(holds), "the frames py-c3d reads");
    let both = format!("declares {declared} frames but holds {holds} complete ones");
    assert_eq!(stderr.lines().count(), 1, "warned once: {stderr}");
    assert!(stderr.contains(&both), "{stderr}");

    let out = run(&["inspect", "--strict"]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.starts_with("treemocap: ") && stderr.contains(&both) && stderr.contains("--strict"),
        "{stderr}"
    );
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
}
