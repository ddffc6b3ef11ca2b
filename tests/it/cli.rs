//! The command line as a user meets it: inspect a real export, get JSON for a
//! script, and get one clear line and the right exit code when something is wrong.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn treemocap(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run treemocap")
}

fn fixture(name: &str) -> PathBuf {
    Path::new("tests/fixtures/motive").join(name)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn inspect_prints_the_take_summary() {
    let f = fixture("ha5dzs_test_markers_enabled_v1.23_unlabeled.csv");
    let out = treemocap(&["inspect", f.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let s = text(&out.stdout);
    assert!(s.contains("Motive CSV 1.23"), "{s}");
    assert!(s.contains("360 Hz"), "{s}");
    assert!(s.contains("frames      1353  (numbers 0 to 1352"), "{s}");
    assert!(s.contains("min 15 / median 17 / max 18"), "{s}");
    assert!(s.contains("gap cells   6147"), "{s}");
}

#[test]
fn inspect_json_is_one_object_for_scripts() {
    let f = fixture("cmuphyscomp_sample_take_v1.21.csv");
    let out = treemocap(&["inspect", "--json", f.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["format"], "motive_csv");
    assert_eq!(v["version"], "1.21");
    assert_eq!(v["frames"], 250);
    assert_eq!(v["first_frame"], 0);
    assert_eq!(v["last_frame"], 249);
    assert_eq!(v["markers_per_frame"]["median"], 6);
    assert_eq!(v["marker_columns"].as_array().unwrap().len(), 9);
    assert_eq!(v["empty_columns"], 3);
    assert_eq!(v["gap_cells"], 2250);
    assert_eq!(v["other_channels"]["rigid_body"], 1);
}

#[test]
fn bad_input_is_one_line_naming_the_file_exit_1() {
    let f = fixture("quirks/bad_not_a_number.csv");
    let out = treemocap(&["inspect", f.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let e = text(&out.stderr);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.contains("bad_not_a_number.csv: line 9, column 4"), "{e}");

    let out = treemocap(&["inspect", "no/such/file.csv"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("no/such/file.csv"));
}

#[test]
fn bad_usage_and_bad_config_exit_2() {
    let out = treemocap(&["inspect"]);
    assert_eq!(out.status.code(), Some(2));
    let out = treemocap(&["frobnicate"]);
    assert_eq!(out.status.code(), Some(2));

    let f = fixture("quirks/v1.24_timecode.csv");
    let out = treemocap(&[
        "replay",
        f.to_str().unwrap(),
        "--set",
        "record.flush_interval_s=9",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let e = text(&out.stderr);
    assert!(
        e.contains("record.flush_interval_s") && e.contains("0.01 to 1"),
        "{e}"
    );

    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("rig.toml");
    std::fs::write(&cfg, "[replay]\ntime_tolerance = 1\n").unwrap();
    let out = treemocap(&[
        "replay",
        f.to_str().unwrap(),
        "--config",
        cfg.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("replay.time_tolerance"));
}

#[test]
fn help_explains_the_commands() {
    let out = treemocap(&["--help"]);
    assert!(out.status.success());
    let s = text(&out.stdout);
    assert!(s.contains("replay") && s.contains("inspect"), "{s}");
}

#[test]
fn shipped_rig_configs_are_valid() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("config");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            treemocap::config::Config::load(Some(&path), &[])
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            n += 1;
        }
    }
    assert!(n >= 4, "default.toml and the rig examples");
}

/// The one-line rule for every error: `treemocap: ` then one line, quoting
/// at most ~80 characters of the input.
fn assert_one_short_line(out: &Output, code: i32, must: &[&str]) -> String {
    let e = text(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{e}");
    assert_eq!(e.lines().count(), 1, "one line: {e}");
    assert!(e.starts_with("treemocap: "), "{e}");
    assert!(e.len() < 400, "{} bytes: {e}", e.len());
    for m in must {
        assert!(e.contains(m), "missing {m:?}: {e}");
    }
    e
}

#[test]
fn config_files_that_are_missing_or_not_toml_are_usage_errors_with_a_place() {
    let f = fixture("quirks/v1.24_timecode.csv");
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.toml");
    let out = treemocap(&[
        "replay",
        f.to_str().unwrap(),
        "--config",
        missing.to_str().unwrap(),
    ]);
    assert_one_short_line(&out, 2, &["--config", "nope.toml"]);

    let cfg = dir.path().join("rig.toml");
    std::fs::write(&cfg, "[daemon]\nsource = \"osc\"\nhttp = 127.0.0.1:8080\n").unwrap();
    let out = treemocap(&[
        "replay",
        f.to_str().unwrap(),
        "--config",
        cfg.to_str().unwrap(),
    ]);
    assert_one_short_line(
        &out,
        2,
        &["rig.toml", "line 3, column 13", "http = 127.0.0.1:8080"],
    );

    std::fs::write(&cfg, b"[daemon]\nsource = \"os\xFFc\"\n").unwrap();
    let out = treemocap(&[
        "replay",
        f.to_str().unwrap(),
        "--config",
        cfg.to_str().unwrap(),
    ]);
    assert_one_short_line(&out, 2, &["rig.toml", "line 2", "UTF-8"]);
}

#[test]
fn stray_quotes_in_a_motive_csv_give_one_short_line() {
    // Two stray quotes 1 200 lines apart: the field between them used to be
    // read as one quoted field of megabytes and printed whole.
    let dir = tempfile::tempdir().unwrap();
    let text_in =
        std::fs::read_to_string(fixture("ha5dzs_test_markers_enabled_v1.23_unlabeled.csv"))
            .unwrap();
    let mut lines: Vec<String> = text_in.lines().map(str::to_string).collect();
    lines[100] = lines[100].replacen(',', ",\"", 3);
    lines[1300] = lines[1300].replacen(',', "\",", 1);
    let f = dir.path().join("quotes.csv");
    std::fs::write(&f, lines.join("\n")).unwrap();
    let out = treemocap(&["inspect", f.to_str().unwrap()]);
    assert_one_short_line(&out, 1, &["quotes.csv: line 101, column"]);
}

#[test]
fn invalid_utf8_in_a_log_names_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("bad.log.csv");
    std::fs::write(
        &f,
        b"# treemocap log 1\n# source: x\n# frame_rate: 100\n# units: m\n# up_axis: Y\n\
          frame,time_s,id,x,y,z\n0,0,,1,2,3\n1,0.01,,1,2\xFF,3\n",
    )
    .unwrap();
    let out = treemocap(&["inspect", f.to_str().unwrap()]);
    assert_one_short_line(&out, 1, &["bad.log.csv: line 8, column 5", "UTF-8"]);
}

#[test]
fn c3d_names_with_newlines_are_escaped() {
    use treemocap::format::c3d::encode::{encode, WriteSpec};
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("names.c3d");
    let spec = WriteSpec {
        labels: vec!["TIP\nONE".into(), "TIP\u{1b}[31mTWO".into()],
        ..WriteSpec::default()
    };
    std::fs::write(&f, encode(&spec)).unwrap();
    let out = treemocap(&["inspect", f.to_str().unwrap()]);
    let s = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        s.contains("TIP\\nONE") && s.contains("TIP\\u{1b}[31mTWO"),
        "{s}"
    );
    assert!(!s.contains('\u{1b}'), "{s}");
}

/// `treemocap inspect --json replays/pine-35.csv | head -c 800`: the reader
/// goes away; the command ends quietly instead of panicking (exit 101).
#[test]
fn a_closed_stdout_ends_the_command_quietly() {
    use std::io::Read;
    use std::process::Stdio;
    for read_first in [800usize, 0] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_treemocap"))
            .args(["inspect", "--json", "replays/pine-35.csv"])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut stdout = child.stdout.take().unwrap();
        let mut head = vec![0u8; read_first];
        stdout.read_exact(&mut head).unwrap();
        drop(stdout);
        let out = child.wait_with_output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
        assert!(out.stderr.is_empty(), "{}", text(&out.stderr));
    }
}

/// Loopback by default everywhere: the defaults and every shipped rig
/// config listen on loopback, or list who may connect.
#[test]
fn shipped_configs_listen_on_loopback_or_name_their_clients() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("config");
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let c = treemocap::config::Config::load(Some(&path), &[]).unwrap();
        let loopback =
            |addr: Option<std::net::SocketAddr>| addr.is_none_or(|a| a.ip().is_loopback());
        let d = &c.daemon;
        assert!(loopback(d.http), "{}: http {:?}", path.display(), d.http);
        assert!(
            loopback(d.osc_control),
            "{}: {:?}",
            path.display(),
            d.osc_control
        );
        let narrow = |allow: &[String]| allow.iter().all(|a| !a.ends_with("/0"));
        assert!(
            narrow(&d.http_allow) && narrow(&c.osc.allow),
            "{}",
            path.display()
        );
        assert!(
            loopback(Some(c.osc.bind)) || !c.osc.allow.iter().any(|a| a.starts_with("127.")),
            "{}: osc.bind {} off loopback must name its senders",
            path.display(),
            c.osc.bind
        );
    }
    // `treemocap serve` (a NatNet server that streams to whoever asks)
    // listens on loopback unless told otherwise.
    let out = treemocap(&["serve", "--help"]);
    let help = text(&out.stdout);
    let bind = help.split("--bind").nth(1).unwrap_or("");
    let bind = bind.split("\n      --").next().unwrap_or("");
    assert!(bind.contains("[default: 127.0.0.1]"), "{help}");
}

/// A long replay shows a progress bar on a terminal (here a pseudo-terminal
/// made by util-linux's `script`), and never in a pipe or a log.
#[test]
fn a_progress_bar_on_a_terminal_only() {
    let exe = env!("CARGO_BIN_EXE_treemocap");
    let on_tty = Command::new("script")
        .args(["-qec"])
        .arg(format!("{exe} tips replays/maple-24.csv > /dev/null"))
        .arg("/dev/null")
        .env("TREEMOCAP_PROGRESS", "1")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("util-linux script (bsdutils) for a pseudo-terminal");
    assert!(on_tty.status.success(), "{}", text(&on_tty.stdout));
    let seen = text(&on_tty.stdout);
    assert!(seen.contains("reading maple-24.csv ["), "{seen:?}");
    assert!(seen.contains("5.58 MiB"), "the file's length: {seen:?}");
    // The bar is cleared at the end: nothing is drawn after the last erase.
    let after = seen.rsplit("\u{1b}[2K").next().unwrap_or_default();
    assert!(!after.contains("reading"), "{seen:?}");

    let piped = Command::new(exe)
        .args(["tips", "replays/maple-24.csv"])
        .env("TREEMOCAP_PROGRESS", "1")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(piped.status.success());
    assert!(
        !text(&piped.stderr).contains("reading"),
        "{}",
        text(&piped.stderr)
    );
}
