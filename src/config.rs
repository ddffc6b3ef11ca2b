//! The TOML configuration. `config/default.toml` is compiled in and is the one
//! list of valid keys: a user's file and `--set` overrides are merged over it
//! key by key, so a key the defaults do not have is an error, and a user names
//! only what they change.

use std::net::SocketAddr;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::animate::AnimateSettings;
use crate::error::{check_range, excerpt, Error, Result};
use crate::reconstruct::forest::{ConfiguredTree, ForestSettings};
use crate::reconstruct::ReconstructSettings;
use crate::source::natnet::settings::NatNetSettings;
use crate::source::osc::OscSettings;
use crate::track::TrackingSettings;
use crate::wind::WindSettings;

/// The shipped defaults, every key commented with its unit and range.
pub const DEFAULT_TOML: &str = include_str!("../config/default.toml");

/// Every setting of treemocap, one section per stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// `[[trees]]`: trunk bases the operator pinned (docs/forest.md).
    pub trees: Vec<ConfiguredTree>,
    /// `[replay]`: reading recorded sessions.
    pub replay: ReplayConfig,
    /// `[record]`: writing our log format.
    pub record: RecordConfig,
    /// `[osc]`: the OSC source.
    pub osc: OscSettings,
    /// `[output]`: where results are written.
    pub output: OutputConfig,
    /// `[natnet]`: the NatNet client.
    pub natnet: NatNetSettings,
    /// `[tracking]`: the marker stage.
    pub tracking: TrackingSettings,
    /// `[wind]`: the wind sources and their priority.
    pub wind: WindSettings,
    /// `[daemon]`: `treemocap run`.
    pub daemon: DaemonConfig,
    /// `[c3d]`: reading C3D files.
    pub c3d: C3dConfig,
    /// `[reconstruct]`: the particle flow (docs/particle-flow.md).
    pub reconstruct: ReconstructSettings,
    /// `[forest]`: several trees in one capture (docs/forest.md).
    pub forest: ForestSettings,
    /// `[animate]`: the captured motion on the tree (docs/animation.md).
    pub animate: AnimateSettings,
}

/// Reading recorded sessions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplayConfig {
    /// Allowed disagreement between a file's Time column and frame / rate (s).
    pub time_tolerance_s: f64,
    /// The NatNet bitstream of a capture that holds no SERVERINFO (it
    /// started after the client connected); `""` (None): from the capture.
    #[serde(with = "crate::protocol::natnet::version::unset_if_empty")]
    pub natnet_version: Option<crate::protocol::natnet::Version>,
    /// Refuse recordings readable only in part (`--strict`).
    pub strict: bool,
}

/// Writing our own recording format.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordConfig {
    /// Longest time between flushes (s): what a crash may lose.
    pub flush_interval_s: f64,
    /// Frames queued between a live source and the writer: the slack for a
    /// stalled disk before the oldest frames are dropped.
    pub queue_frames: u64,
}

/// Where results go.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    /// Output folder for replay results and the daemon's files.
    pub dir: String,
}

/// `treemocap run`: sources, triggers and outputs of the daemon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DaemonConfig {
    /// Where frames come from.
    pub source: DaemonSource,
    /// The recording played when `source = "replay"`.
    pub replay_file: String,
    /// Playback speed of that recording; 0 plays as fast as possible.
    pub replay_speed: f64,
    /// Start the recording again at its end, times continuing.
    pub replay_loop: bool,
    /// NatNet server, `ADDRESS` or `ADDRESS:COMMAND_PORT`, when
    /// `source = "natnet"`.
    pub natnet_server: String,
    /// How NatNet frames travel; `auto` takes what the server says.
    pub natnet_transport: TransportSetting,
    /// Seconds of frames kept for analysis.
    pub window_s: f64,
    /// Seconds of capture time between analyses.
    pub analysis_interval_s: f64,
    /// Still phase (s) needed before the first tree is built.
    pub rest_min_s: f64,
    /// How long (s) the tips must differ from the last tree's before a new
    /// tree is built, so a marker hidden for a moment does not trigger one.
    pub tip_change_s: f64,
    /// Distance (mm) beyond which a tip counts as moved.
    pub moved_mm: f64,
    /// Wind turn (degrees) that triggers a new tree.
    pub wind_turn_deg: f64,
    /// 0 disables the periodic rebuild.
    pub period_s: f64,
    /// Radius matching a tracked marker to the tree's tip (mm); see
    /// `track::live`.
    pub follow_gate_mm: f64,
    /// Frames queued between the sources and the pipeline; when full, the
    /// oldest is dropped and counted, so a slow pipeline never blocks a socket.
    pub channel_frames: u32,
    /// Record every frame to `OUT/session.log.csv`.
    pub record: bool,
    /// CPU the pipeline thread is pinned to, with the analysis, builder and
    /// live-sway threads kept off it; -1 leaves them all to the kernel
    /// (`daemon::affinity`).
    pub pipeline_cpu: i32,
    /// Microseconds before the next frame is due at which the pipeline
    /// prefetches the live tracker's state (`track::warm`); 0 = never.
    pub warm_us: u32,
    /// Run the analysis, the tree builder and the live sway under Linux's
    /// `SCHED_IDLE` instead of nice +10: they then never delay the
    /// pipeline's wake-up (at nice +10 a waking pipeline can wait for a
    /// background thread's slice), but they only get CPU no other thread of
    /// the machine wants.
    pub background_idle: bool,
    /// HTTP and WebSocket address; `""` in the config (None) turns it off.
    #[serde(with = "optional_addr")]
    pub http: Option<SocketAddr>,
    /// IP addresses or CIDR ranges HTTP accepts.
    pub http_allow: Vec<String>,
    /// HTTP connections open at once.
    pub http_max_connections: u32,
    /// `/live` WebSocket sessions open at once.
    pub http_max_websockets: u32,
    /// Longest wait for a request's headers (s).
    pub http_header_timeout_s: f64,
    /// Longest time a connection may move no byte (s).
    pub http_idle_timeout_s: f64,
    /// Where the tree, tips and wind are sent as OSC.
    pub osc_targets: Vec<SocketAddr>,
    /// Keep every tree as `tree-0001.glb`, `tree-0001.json`, … as well.
    pub history: bool,
    /// UDP address for `/treemocap/rebuild`; `""` (None) turns it off.
    #[serde(with = "optional_addr")]
    pub osc_control: Option<SocketAddr>,
}

/// `daemon.source`: where `treemocap run` gets its frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DaemonSource {
    /// A recording played at its recorded speed (a stand-in for the rig).
    Replay,
    /// Motive over NatNet.
    Natnet,
    /// A NatNet→OSC bridge, or anything sending our OSC messages.
    Osc,
}

/// `daemon.natnet_transport`: how NatNet frames reach the client.
pub use crate::source::natnet::settings::TransportSetting;

/// An address that the config may leave empty (`""`) to turn a listener off.
mod optional_addr {
    use std::net::SocketAddr;

    use serde::{Deserialize, Deserializer, Serializer};

    pub(super) fn serialize<S: Serializer>(
        v: &Option<SocketAddr>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        match v {
            Some(a) => s.collect_str(a),
            None => s.serialize_str(""),
        }
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<SocketAddr>, D::Error> {
        let text = String::deserialize(d)?;
        if text.is_empty() {
            return Ok(None);
        }
        text.parse().map(Some).map_err(|_| {
            serde::de::Error::custom(format!("'{text}' is not ADDRESS:PORT (or \"\" for off)"))
        })
    }
}

/// Reading C3D files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct C3dConfig {
    /// Which axis of a C3D file points up: "auto" (from POINT:Y_SCREEN,
    /// Z when absent), "y" or "z". Frames are always turned to Y up.
    pub up_axis: crate::format::c3d::UpAxisSetting,
}

impl Default for TrackingSettings {
    fn default() -> Self {
        Config::default().tracking
    }
}

impl Default for ReconstructSettings {
    fn default() -> Self {
        Config::default().reconstruct
    }
}

impl Default for ForestSettings {
    fn default() -> Self {
        Config::default().forest
    }
}

impl Default for Config {
    fn default() -> Self {
        Config::from_table(default_table()).expect("config/default.toml is valid")
    }
}

fn default_table() -> toml::Table {
    DEFAULT_TOML
        .parse::<toml::Table>()
        .expect("config/default.toml parses")
}

impl Config {
    /// Defaults, then the user's file (if any), then `key=value` overrides.
    pub fn load(path: Option<&Path>, sets: &[String]) -> Result<Config> {
        let mut table = default_table();
        if let Some(path) = path {
            // A config that cannot be read is a usage error (exit 2), like
            // one that does not parse.
            let name = path.display().to_string();
            let bytes = std::fs::read(path).map_err(|e| {
                Error::config("--config", format!("cannot read {}: {e}", excerpt(&name)))
            })?;
            let text = String::from_utf8(bytes).map_err(|e| {
                let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
                let (line, column) = line_column(&String::from_utf8_lossy(valid), valid.len());
                Error::config(
                    name.clone(),
                    format!("line {line}, column {column}: not UTF-8 text"),
                )
            })?;
            let user: toml::Table = text
                .parse()
                .map_err(|e: toml::de::Error| toml_error(&name, &text, &e))?;
            merge(&mut table, user, "")?;
        }
        for set in sets {
            merge(&mut table, parse_set(set)?, "")?;
        }
        Config::from_table(table)
    }

    /// Parses a whole config text merged over the defaults (used by tests and
    /// by the daemon's reload).
    pub fn from_toml_str(text: &str) -> Result<Config> {
        let user: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| toml_error("<text>", text, &e))?;
        let mut table = default_table();
        merge(&mut table, user, "")?;
        Config::from_table(table)
    }

    fn from_table(table: toml::Table) -> Result<Config> {
        let config: Config = match toml::Value::Table(table.clone()).try_into() {
            Ok(c) => c,
            Err(e) => return Err(type_error(&table, e)),
        };
        config.validate()?;
        Ok(config)
    }

    /// Range checks, each naming the key and its allowed range.
    pub fn validate(&self) -> Result<()> {
        self.validate_io()?;
        validate_wind(&self.wind)?;
        validate_daemon(&self.daemon)?;
        if self.output.dir.is_empty() {
            return Err(Error::config("output.dir", "must not be empty"));
        }
        self.tracking.validate()?;
        self.reconstruct.validate()?;
        self.forest.validate()?;
        crate::reconstruct::forest::settings::validate_trees(&self.trees)?;
        self.animate.validate()?;
        Ok(())
    }

    /// `[replay]`, `[record]`, `[osc]`, `[natnet]`.
    fn validate_io(&self) -> Result<()> {
        check_range(
            "replay.time_tolerance_s",
            self.replay.time_tolerance_s,
            0.0,
            1.0,
        )?;
        check_range(
            "record.flush_interval_s",
            self.record.flush_interval_s,
            0.01,
            1.0,
        )?;
        check_range(
            "record.queue_frames",
            self.record.queue_frames as f64,
            1.0,
            1e6,
        )?;
        check_range("osc.frame_rate", self.osc.frame_rate, 1.0, 10000.0)?;
        crate::source::osc::OscOptions::from_settings(&self.osc)?;
        self.natnet.validate()?;
        let d = &self.daemon;
        crate::source::allow::AllowList::parse("daemon.http_allow", &d.http_allow)?;
        check_range(
            "daemon.http_max_connections",
            f64::from(d.http_max_connections),
            1.0,
            100_000.0,
        )?;
        check_range(
            "daemon.http_max_websockets",
            f64::from(d.http_max_websockets),
            1.0,
            100_000.0,
        )?;
        check_range(
            "daemon.http_header_timeout_s",
            d.http_header_timeout_s,
            0.1,
            600.0,
        )?;
        check_range(
            "daemon.http_idle_timeout_s",
            d.http_idle_timeout_s,
            1.0,
            3600.0,
        )?;
        Ok(())
    }
}

/// `[wind]`: no source twice in the priority, a fan position of three
/// numbers or none, numbers in range.
fn validate_wind(w: &WindSettings) -> Result<()> {
    let mut seen = Vec::new();
    for name in &w.priority {
        if seen.contains(&name) {
            return Err(Error::config(
                "wind.priority",
                format!("'{}' is repeated", name.name()),
            ));
        }
        seen.push(name);
    }
    check_range("wind.max_age_s", w.max_age_s, 0.5, 600.0)?;
    if !(w.fan_position.is_empty()
        || (w.fan_position.len() == 3 && w.fan_position.iter().all(|v| v.is_finite())))
    {
        return Err(Error::config(
            "wind.fan_position",
            "must be [] or three numbers [x, y, z] in metres",
        ));
    }
    check_range("wind.fan_speed_m_s", w.fan_speed_m_s, 0.0, 50.0)?;
    check_range("wind.sensor_baud", w.sensor_baud as f64, 300.0, 921_600.0)?;
    check_range("wind.sensor_heading_deg", w.sensor_heading_deg, 0.0, 360.0)?;
    check_range("wind.pca_window_s", w.pca_window_s, 1.0, 120.0)?;
    check_range("wind.pca_min_sway_mm", w.pca_min_sway_mm, 0.1, 100.0)?;
    Ok(())
}

/// `[daemon]`: numbers in range (addresses and enums are checked when the
/// table is read).
fn validate_daemon(d: &DaemonConfig) -> Result<()> {
    check_range("daemon.replay_speed", d.replay_speed, 0.0, 100.0)?;
    check_range("daemon.window_s", d.window_s, 5.0, 600.0)?;
    check_range(
        "daemon.analysis_interval_s",
        d.analysis_interval_s,
        0.1,
        60.0,
    )?;
    check_range("daemon.rest_min_s", d.rest_min_s, 1.0, 600.0)?;
    check_range("daemon.tip_change_s", d.tip_change_s, 0.0, 600.0)?;
    check_range("daemon.moved_mm", d.moved_mm, 1.0, 1000.0)?;
    check_range("daemon.wind_turn_deg", d.wind_turn_deg, 1.0, 180.0)?;
    check_range("daemon.period_s", d.period_s, 0.0, 86_400.0)?;
    check_range("daemon.follow_gate_mm", d.follow_gate_mm, 5.0, 500.0)?;
    check_range(
        "daemon.pipeline_cpu",
        f64::from(d.pipeline_cpu),
        -1.0,
        1023.0,
    )?;
    check_range("daemon.warm_us", f64::from(d.warm_us), 0.0, 100_000.0)?;
    check_range(
        "daemon.channel_frames",
        d.channel_frames as f64,
        16.0,
        1_000_000.0,
    )?;
    Ok(())
}

/// A value of the wrong type (`-5` for a count, `"x"` for a list) names its
/// key: deserialising a table loses the path, so the merged table is written
/// out as text and parsed again, and the key is read off the error's line.
fn type_error(table: &toml::Table, first: toml::de::Error) -> Error {
    let Ok(text) = toml::to_string(table) else {
        return Error::config("<config>", first.message().to_string());
    };
    let Err(e) = toml::from_str::<Config>(&text) else {
        return Error::config("<config>", first.message().to_string());
    };
    let key = e
        .span()
        .and_then(|span| {
            let before = text.get(..span.start)?;
            let line = before.rsplit('\n').next()?;
            let key = line.split('=').next()?.trim();
            let section = before
                .lines()
                .rev()
                .find(|l| l.starts_with('['))
                .map(|l| l.trim_matches(['[', ']']).to_string());
            Some(match section {
                Some(s) if !key.is_empty() => format!("{s}.{key}"),
                _ => key.to_string(),
            })
        })
        .filter(|k| !k.is_empty())
        .unwrap_or_else(|| "<config>".into());
    Error::config(key, e.message().to_string())
}

/// Merges `over` into `base`; every key of `over` must exist in `base` with a
/// value of the same kind (an integer may stand for a float).
fn merge(base: &mut toml::Table, over: toml::Table, prefix: &str) -> Result<()> {
    for (key, value) in over {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        let Some(slot) = base.get_mut(&key) else {
            let known: Vec<&str> = base.keys().map(String::as_str).collect();
            return Err(Error::config(
                &path,
                format!("unknown key; known keys here: {}", known.join(", ")),
            ));
        };
        match (slot, value) {
            (toml::Value::Table(b), toml::Value::Table(o)) => merge(b, o, &path)?,
            (toml::Value::Table(_), _) => {
                return Err(Error::config(&path, "is a section, not a value"))
            }
            (slot @ toml::Value::Float(_), toml::Value::Integer(i)) => {
                *slot = toml::Value::Float(i as f64)
            }
            (slot @ toml::Value::Array(_), toml::Value::Array(items)) => {
                // `[1, 2, 3]` for a list of floats: integers stand for floats
                // unless the default list holds integers.
                let ints_wanted = matches!(
                    slot.as_array().and_then(|a| a.first()),
                    Some(toml::Value::Integer(_))
                );
                *slot = toml::Value::Array(
                    items
                        .into_iter()
                        .map(|v| match v {
                            toml::Value::Integer(i) if !ints_wanted => toml::Value::Float(i as f64),
                            v => v,
                        })
                        .collect(),
                );
            }
            (slot, value) => {
                if std::mem::discriminant(slot) != std::mem::discriminant(&value) {
                    return Err(Error::config(
                        &path,
                        format!("expected {}, got {}", slot.type_str(), value.type_str()),
                    ));
                }
                *slot = value;
            }
        }
    }
    Ok(())
}

/// `section.key=value` as a one-key table. The value is read as TOML
/// (`3`, `0.2`, `true`, `"box"`); a bare word is taken as a string.
/// A TOML syntax error as one line: where (line and column, 1-based), what
/// the parser says, and an excerpt of the line.
fn toml_error(name: &str, text: &str, e: &toml::de::Error) -> Error {
    let message = e.message().trim().replace('\n', " ");
    let Some(span) = e.span() else {
        return Error::config(name, format!("not valid TOML: {message}"));
    };
    let (line, column) = line_column(text, span.start);
    let line_text = text.lines().nth(line as usize - 1).unwrap_or("");
    Error::config(
        name,
        format!(
            "line {line}, column {column}: not valid TOML: {message} (line: \"{}\")",
            excerpt(line_text.trim())
        ),
    )
}

/// 1-based line and column (in characters) of byte `at` of `text`.
fn line_column(text: &str, at: usize) -> (u64, u64) {
    let before = text.get(..at.min(text.len())).unwrap_or(text);
    let line = before.matches('\n').count() as u64 + 1;
    let column = before.rsplit('\n').next().unwrap_or("").chars().count() as u64 + 1;
    (line, column)
}

fn parse_set(set: &str) -> Result<toml::Table> {
    let Some((key, value)) = set.split_once('=') else {
        return Err(Error::config(set, "--set takes key=value"));
    };
    let key = key.trim();
    let value = value.trim();
    let parsed = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    let mut parts: Vec<&str> = key.split('.').collect();
    let last = parts.pop().filter(|s| !s.is_empty());
    let Some(last) = last else {
        return Err(Error::config(key, "empty key in --set"));
    };
    let mut table = toml::Table::new();
    table.insert(last.to_string(), parsed);
    for part in parts.into_iter().rev() {
        let mut outer = toml::Table::new();
        outer.insert(part.to_string(), toml::Value::Table(table));
        table = outer;
    }
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_parse_and_validate() {
        let c = Config::default();
        assert_eq!(c.output.dir, "out");
        assert_eq!(c.record.flush_interval_s, 1.0);
    }

    #[test]
    fn user_file_overrides_only_what_it_names() {
        let c = Config::from_toml_str("[record]\nflush_interval_s = 0.5\n").unwrap();
        assert_eq!(c.record.flush_interval_s, 0.5);
        assert_eq!(c.output.dir, Config::default().output.dir);
    }

    #[test]
    fn unknown_key_names_the_key() {
        let e = Config::from_toml_str("[record]\nflush_every = 1\n").unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("record.flush_every"), "{msg}");
        assert_eq!(e.exit_code(), 2);
        let e = Config::from_toml_str("[nope]\nx = 1\n").unwrap_err();
        assert!(e.to_string().contains("nope"));
    }

    #[test]
    fn out_of_range_names_key_and_range() {
        let e = Config::from_toml_str("[record]\nflush_interval_s = 5\n").unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("record.flush_interval_s") && msg.contains("0.01 to 1"),
            "{msg}"
        );
    }

    #[test]
    fn negative_count_names_its_key() {
        let e = Config::from_toml_str("[reconstruct]\ntotal_tips = -5\n").unwrap_err();
        assert!(e.to_string().contains("reconstruct.total_tips"), "{e}");
    }

    #[test]
    fn wrong_type_is_an_error() {
        let e = Config::from_toml_str("[output]\ndir = 3\n").unwrap_err();
        assert!(e.to_string().contains("output.dir"), "{e}");
    }

    #[test]
    fn natnet_marker_selection_is_checked() {
        use crate::protocol::natnet::select::MarkerSelection;
        assert_eq!(Config::default().natnet.markers, MarkerSelection::Unlabeled);
        let c = Config::from_toml_str("[natnet]\nmarkers = \"all\"\n").unwrap();
        assert_eq!(c.natnet.markers, MarkerSelection::All);
        let e = Config::from_toml_str("[natnet]\nmarkers = \"some\"\n").unwrap_err();
        assert!(e.to_string().contains("some"), "{e}");
    }

    #[test]
    fn tracking_section_checks_ranges_and_rest_window() {
        let c = Config::default();
        assert_eq!(c.tracking.gate_mm, 25.0);
        assert!(c.tracking.rest_window_s.is_empty());
        let c = Config::from_toml_str("[tracking]\nrest_window_s = [1, 5.5]\n").unwrap();
        assert_eq!(c.tracking.rest_window_s, vec![1.0, 5.5]);
        let e = Config::from_toml_str("[tracking]\nrest_window_s = [5, 1]\n").unwrap_err();
        assert!(e.to_string().contains("tracking.rest_window_s"), "{e}");
        let e = Config::from_toml_str("[tracking]\nnoise_fraction = 2\n").unwrap_err();
        assert!(e.to_string().contains("tracking.noise_fraction"), "{e}");
    }

    #[test]
    fn wind_settings() {
        let c =
            Config::from_toml_str("[wind]\nfan_position = [-3, 1.2, 0]\npriority = [\"fan\"]\n")
                .unwrap();
        assert_eq!(c.wind.fan(), Some(glam::DVec3::new(-3.0, 1.2, 0.0)));
        assert_eq!(c.wind.priority, vec![crate::model::wind::WindSource::Fan]);
        let e = Config::from_toml_str("[wind]\nfan_position = [1, 2]\n").unwrap_err();
        assert!(e.to_string().contains("wind.fan_position"), "{e}");
        let e = Config::from_toml_str("[wind]\npriority = [\"fan\", \"moon\"]\n").unwrap_err();
        assert!(e.to_string().contains("moon"), "{e}");
    }

    #[test]
    fn reconstruct_section_is_settable_and_checked() {
        let c = Config::load(
            None,
            &[
                "reconstruct.volume=hull".into(),
                "reconstruct.gravity_weight=-0.2".into(),
            ],
        )
        .unwrap();
        assert_eq!(c.reconstruct.volume, crate::reconstruct::VolumeKind::Hull);
        assert_eq!(c.reconstruct.gravity_weight, -0.2);
        let e = Config::load(None, &["reconstruct.beta=2".into()]).unwrap_err();
        assert!(e.to_string().contains("reconstruct.beta"), "{e}");
        let e = Config::load(None, &["reconstruct.attractor_node=10".into()]).unwrap_err();
        assert!(e.to_string().contains("reconstruct.attractor_node"), "{e}");
        assert!(Config::load(None, &["reconstruct.volume=sphere".into()]).is_err());
    }

    #[test]
    fn set_overrides() {
        let c = Config::load(
            None,
            &[
                "record.flush_interval_s=0.25".into(),
                "output.dir=res".into(),
            ],
        )
        .unwrap();
        assert_eq!(c.record.flush_interval_s, 0.25);
        assert_eq!(c.output.dir, "res");
        assert!(Config::load(None, &["record".into()]).is_err());
    }
}
