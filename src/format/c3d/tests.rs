//! Round trips through the encoder and the reader's error paths. Files from
//! an independent writer (py-c3d) and real files are tested in tests/c3d.rs.

use super::encode::{encode, Sample, WriteSpec};
use super::*;

fn read_all(
    bytes: Vec<u8>,
    options: &C3dOptions,
) -> (C3dReader<Cursor<Vec<u8>>>, Vec<MarkerFrame>) {
    let mut r = C3dReader::from_bytes(Path::new("t.c3d"), bytes, options).unwrap();
    let frames: Vec<MarkerFrame> = r.by_ref().map(|f| f.unwrap()).collect();
    (r, frames)
}

fn s(x: f64, y: f64, z: f64, r: f32) -> Sample {
    Sample {
        position: [x, y, z],
        residual: r,
    }
}

/// 3 points over 4 frames with every kind of gap the spec lists.
fn gappy(float: bool) -> Vec<Vec<Sample>> {
    let nan = f64::NAN;
    vec![
        vec![
            s(100.0, 200.0, 300.0, 1.0),
            s(-10.5, 0.0, 7.0, 2.0),
            s(1.0, 2.0, 3.0, 0.0),
        ],
        // Motive: −32768 with stale coordinates.
        vec![
            s(529.3, 70.3, 194.9, -32768.0),
            s(-10.5, 0.0, 7.0, 2.0),
            s(1.0, 2.0, 3.0, 0.0),
        ],
        // −1 gap; a residual with the camera byte set (valid).
        vec![
            s(0.0, 0.0, 0.0, -1.0),
            s(-11.0, 1.0, 7.5, 0x7F00 as f32 + 200.0),
            s(1.5, 2.5, 3.5, 3.0),
        ],
        // ezc3d: NaN coordinates, residual 0 (only float files can); BTS: 247.0.
        if float {
            vec![
                s(nan, nan, nan, 0.0),
                s(5.0, 6.0, 7.0, 247.0),
                s(1.0, nan, 3.0, 1.0),
            ]
        } else {
            vec![
                s(1.0, 1.0, 1.0, 0.0),
                s(5.0, 6.0, 7.0, 247.0),
                s(1.0, 2.0, 3.0, -2.0),
            ]
        },
    ]
}

fn valid(smp: &Sample) -> bool {
    smp.residual > -1.0 && smp.position.iter().all(|v| v.is_finite())
}

#[test]
fn every_processor_and_storage_round_trips() {
    for processor in [Processor::Intel, Processor::Dec, Processor::Mips] {
        for float in [false, true] {
            let frames = gappy(float);
            let spec = WriteSpec {
                processor,
                float,
                scale: 0.5,
                labels: vec!["A".into(), "B".into(), "C".into()],
                y_screen: Some("+Y".into()),
                // ezc3d's byte POINT:USED, in one variant per processor.
                used_as_byte: float,
                frames: frames.clone(),
                ..Default::default()
            };
            let (r, got) = read_all(encode(&spec), &C3dOptions::default());
            assert_eq!(
                r.info().version,
                format!(
                    "{} {}",
                    processor.name(),
                    if float { "float32" } else { "int16" }
                )
            );
            assert_eq!(got.len(), 4);
            for (f, (want, have)) in frames.iter().zip(&got).enumerate() {
                assert_eq!(have.frame, 1 + f as i64);
                assert!((have.time_s - f as f64 / 100.0).abs() < 1e-12);
                let expect: Vec<(usize, &Sample)> =
                    want.iter().enumerate().filter(|(_, s)| valid(s)).collect();
                assert_eq!(
                    have.markers.len(),
                    expect.len(),
                    "{processor:?} float={float} frame {f}"
                );
                for (m, (i, smp)) in have.markers.iter().zip(expect) {
                    assert_eq!(m.id, Some(i as i64));
                    // int16 files hold multiples of the scale (0.5 mm).
                    let q = |v: f64| {
                        if float {
                            v as f32 as f64
                        } else {
                            (v / 0.5).round() * 0.5
                        }
                    };
                    let want = glam::DVec3::new(
                        q(smp.position[0]),
                        q(smp.position[1]),
                        q(smp.position[2]),
                    ) / 1000.0;
                    assert!(
                        (m.position - want).length() < 1e-9,
                        "{processor:?} {float} {f}: {} vs {want}",
                        m.position
                    );
                }
            }
            let ch = r.channels();
            assert_eq!(
                ch.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(),
                ["A", "B", "C"]
            );
            for (i, c) in ch.iter().enumerate() {
                let n = frames.iter().filter(|f| valid(&f[i])).count() as u64;
                assert_eq!((c.present, c.empty_cells), (n, 4 - n), "point {i}");
            }
            // Independently of `valid`: Motive, −1 and (float) NaN gaps.
            assert_eq!(ch[0].present, if float { 1 } else { 2 });
        }
    }
}

#[test]
fn z_up_is_turned_to_y_up_and_units_are_metres() {
    let frames = vec![vec![s(1.0, 2.0, 3.0, 0.0)]];
    let base = WriteSpec {
        float: true,
        units: "m".into(),
        frames,
        ..Default::default()
    };
    let read = |spec: &WriteSpec, up: UpAxisSetting| {
        let (r, f) = read_all(
            encode(spec),
            &C3dOptions {
                up_axis: up,
                ..Default::default()
            },
        );
        (r.info().up_axis.clone(), f[0].markers[0].position)
    };
    let z = WriteSpec {
        y_screen: Some("+Z".into()),
        ..base.clone()
    };
    assert_eq!(
        read(&z, UpAxisSetting::Auto),
        ("Z".into(), glam::DVec3::new(1.0, 3.0, -2.0))
    );
    assert_eq!(
        read(&z, UpAxisSetting::Y),
        ("Y".into(), glam::DVec3::new(1.0, 2.0, 3.0))
    );
    let y = WriteSpec {
        y_screen: Some("+Y".into()),
        ..base.clone()
    };
    assert_eq!(
        read(&y, UpAxisSetting::Auto).1,
        glam::DVec3::new(1.0, 2.0, 3.0)
    );
    assert_eq!(
        read(&y, UpAxisSetting::Z).1,
        glam::DVec3::new(1.0, 3.0, -2.0)
    );
    let none = WriteSpec {
        y_screen: None,
        ..base.clone()
    };
    assert_eq!(read(&none, UpAxisSetting::Auto).0, "Z");
    let cm = WriteSpec {
        units: "cm".into(),
        y_screen: None,
        ..base
    };
    assert_eq!(
        read(&cm, UpAxisSetting::Y).1,
        glam::DVec3::new(0.01, 0.02, 0.03)
    );
}

#[test]
fn layout_quirks_of_real_files() {
    // Moved parameter and data blocks, unpadded last block, analog data
    // between frames, more labels than points (and past 255: LABELS2),
    // first frame 0.
    let points = 260;
    let frames: Vec<Vec<Sample>> = (0..5)
        .map(|f| {
            (0..points)
                .map(|i| s(i as f64, f as f64, -(i as f64), 1.0))
                .collect()
        })
        .collect();
    let labels: Vec<String> = (0..300).map(|i| format!("M{i:03}")).collect();
    for processor in [Processor::Intel, Processor::Dec, Processor::Mips] {
        let spec = WriteSpec {
            processor,
            scale: 1.0,
            labels: labels.clone(),
            y_screen: Some("+Y".into()),
            first_frame: 0,
            analog_channels: 3,
            analog_per_channel: 4,
            param_block: 11,
            gap_blocks: 3,
            pad: false,
            frames: frames.clone(),
            ..Default::default()
        };
        let bytes = encode(&spec);
        assert_ne!(bytes.len() % 512, 0);
        let (r, got) = read_all(bytes, &C3dOptions::default());
        assert_eq!(r.layout().analog_values, 12);
        assert_eq!(got.len(), 5);
        assert_eq!(got[0].frame, 0);
        assert_eq!(
            got[4].markers[259].position,
            glam::DVec3::new(0.259, 0.004, -0.259)
        );
        assert_eq!(r.channels()[258].name, "M258");
        assert_eq!(r.channels().len(), 260);
    }
}

#[test]
fn more_than_65535_frames() {
    let frames: Vec<Vec<Sample>> = (0..70_000)
        .map(|f| vec![s((f % 1000) as f64, 0.0, 0.0, 0.0)])
        .collect();
    let spec = WriteSpec {
        y_screen: Some("+Y".into()),
        scale: 1.0,
        frames,
        ..Default::default()
    };
    let bytes = encode(&spec);
    let (r, got) = read_all(bytes, &C3dOptions::default());
    assert_eq!(r.layout().frames, 70_000);
    assert_eq!(got.len(), 70_000);
    assert_eq!(got[69_999].frame, 70_000);
    assert_eq!(got[69_999].markers[0].position.x, 0.999);
}

fn small() -> Vec<u8> {
    encode(&WriteSpec {
        labels: vec!["A".into(), "B".into()],
        frames: (0..10)
            .map(|f| vec![s(f as f64, 1.0, 2.0, 0.0), s(3.0, 4.0, 5.0, 0.0)])
            .collect(),
        ..Default::default()
    })
}

#[track_caller]
fn open_err(bytes: Vec<u8>) -> String {
    match C3dReader::from_bytes(Path::new("bad.c3d"), bytes, &C3dOptions::default()) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_files_get_clear_errors() {
    let good = small();
    // Truncated inside the header and inside the parameters.
    let e = open_err(good[..300].to_vec());
    assert!(
        e.contains("bad.c3d") && e.contains("512-byte header"),
        "{e}"
    );
    let e = open_err(good[..512 + 40].to_vec());
    assert!(
        e.contains("byte 552: file ends inside the parameter section"),
        "{e}"
    );
    // Not C3D.
    let mut b = good.clone();
    b[1] = 0x51;
    assert!(open_err(b).contains("byte 1"));
    // Parameter block pointer past the end.
    let mut b = good.clone();
    b[0] = 200;
    let e = open_err(b);
    assert!(
        e.contains("byte 1536: file ends") && e.contains("parameter section (header byte 0)"),
        "{e}"
    );
    // Unknown processor.
    let mut b = good.clone();
    b[512 + 3] = 99;
    assert!(open_err(b).contains("byte 515: processor type 99"));
    // Data block pointer past the end: POINT:DATA_START is used instead,
    // and when it is wrong too, the error names both.
    let mut b = good.clone();
    b[16..18].copy_from_slice(&9000u16.to_le_bytes());
    let (r, frames) = read_all(b.clone(), &C3dOptions::default());
    assert_eq!(frames.len(), 10);
    assert!(
        r.warnings()
            .iter()
            .any(|w| w.contains("POINT:DATA_START = 3")),
        "{:?}",
        r.warnings()
    );
    let ds = find(&b, b"DATA_START").unwrap();
    b[ds + 14..ds + 16].copy_from_slice(&7000u16.to_le_bytes());
    let e = open_err(b);
    assert!(
        e.contains("byte 16") && e.contains("9000") && e.contains("7000"),
        "{e}"
    );
    // Absurd point count: more than the data section holds.
    let mut b = good.clone();
    b[2..4].copy_from_slice(&60000u16.to_le_bytes());
    let used = find(&b, b"USED").unwrap();
    // POINT:USED's value: name (4) + offset (2) + type (1) + dims (1).
    b[used + 8..used + 10].copy_from_slice(&60000u16.to_le_bytes());
    let e = open_err(b);
    assert!(
        e.contains("less than one frame") && e.contains("60000 points"),
        "{e}"
    );
}

#[test]
fn a_capture_cut_short_reads_its_complete_frames_and_strict_refuses_it() {
    let good = small();
    // Frames are 16 bytes from block 3 (byte 1024) on; cut inside frame 6.
    let cut = 1024 + 6 * 16 + 5;
    let mut r = C3dReader::from_bytes(
        Path::new("cut.c3d"),
        good[..cut].to_vec(),
        &C3dOptions::default(),
    )
    .unwrap();
    assert_eq!(r.warnings().len(), 1, "{:?}", r.warnings());
    assert!(
        r.warnings()[0].contains("declares 10 frames but holds 6 complete ones"),
        "{:?}",
        r.warnings()
    );
    for _ in 0..6 {
        assert!(r.next().unwrap().is_ok());
    }
    assert!(r.next().is_none(), "no error after the complete frames");
    assert_eq!(r.warnings().len(), 1, "warned once");

    let strict = C3dOptions {
        strict: true,
        ..Default::default()
    };
    let e = C3dReader::from_bytes(Path::new("cut.c3d"), good[..cut].to_vec(), &strict)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("cut.c3d")
            && e.contains(&format!("byte {}", 1024 + 96))
            && e.contains("declares 10 frames but holds 6")
            && e.contains("--strict"),
        "{e}"
    );
    // A whole file is read the same with or without strict.
    assert!(C3dReader::from_bytes(Path::new("ok.c3d"), good, &strict).is_ok());
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

#[test]
fn random_mutations_never_panic() {
    let mut rng = crate::rng::Rng::new(7);
    let seeds = [
        small(),
        encode(&WriteSpec {
            processor: Processor::Mips,
            float: true,
            analog_channels: 2,
            analog_per_channel: 2,
            labels: vec!["A".into()],
            frames: gappy(true).into_iter().map(|f| f[..1].to_vec()).collect(),
            ..Default::default()
        }),
    ];
    for i in 0..3000 {
        let mut b = seeds[i % seeds.len()].clone();
        let hits = rng.int(1, 8);
        for _ in 0..hits {
            let at = rng.int(0, b.len() as i64 - 1) as usize;
            b[at] = rng.int(0, 255) as u8;
        }
        if rng.chance(0.2) {
            let cut = rng.int(0, b.len() as i64) as usize;
            b.truncate(cut);
        }
        if let Ok(r) = C3dReader::from_bytes(Path::new("m.c3d"), b, &C3dOptions::default()) {
            for f in r.take(100_000) {
                if f.is_err() {
                    break;
                }
            }
        }
    }
}

#[test]
fn motive_data_start_zero_and_header_frames_that_make_no_sense() {
    // Motive writes POINT:DATA_START = 0 and the right block in the header.
    let mut b = small();
    let ds = find(&b, b"DATA_START").unwrap();
    b[ds + 14..ds + 16].copy_from_slice(&0u16.to_le_bytes());
    let (r, frames) = read_all(b.clone(), &C3dOptions::default());
    assert_eq!(frames.len(), 10);
    assert!(r.warnings().is_empty(), "{:?}", r.warnings());

    // Last frame before the first: POINT:FRAMES (10) is used, with a warning.
    b[8..10].copy_from_slice(&0u16.to_le_bytes());
    let (r, frames) = read_all(b.clone(), &C3dOptions::default());
    assert_eq!(frames.len(), 10);
    assert!(
        r.warnings()[0].contains("POINT:FRAMES = 10"),
        "{:?}",
        r.warnings()
    );

    // And with no usable parameter either, an error naming header word 5.
    let fr = find(&b, b"FRAMES").unwrap();
    b[fr..fr + 6].copy_from_slice(b"FRAMEX");
    let e = open_err(b);
    assert!(
        e.contains("byte 8") && e.contains("last frame 0 is before first frame 1"),
        "{e}"
    );
}
