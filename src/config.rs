//! The TOML configuration. `config/default.toml` is compiled in and is the one
//! list of valid keys: a user's file and `--set` overrides are merged over it
//! key by key, so a key the defaults do not have is an error, and a user names
//! only what they change.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{excerpt, Error, Result};

/// The shipped defaults, every key commented with its unit and range.
pub const DEFAULT_TOML: &str = include_str!("../config/default.toml");

/// Every setting of treemocap, one section per stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub replay: ReplayConfig,
    pub record: RecordConfig,
    pub osc: OscConfig,
    pub output: OutputConfig,
    pub natnet: NatNetConfig,
    pub tracking: TrackingConfig,
    pub wind: WindConfig,
    pub daemon: DaemonConfig,
    pub c3d: C3dConfig,
    pub reconstruct: ReconstructConfig,
}

/// Reading recorded sessions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplayConfig {
    /// Allowed disagreement between a file's Time column and frame / rate (s).
    pub time_tolerance_s: f64,
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

/// The OSC source (`source::osc`): where it listens, whom it accepts, and
/// how the sender's positions convert to metres, Y up.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OscConfig {
    /// `address:port` to listen on; loopback unless the user widens it.
    pub bind: String,
    /// IP addresses or CIDR ranges accepted as senders.
    pub allow: Vec<String>,
    /// "y" or "z": the sender's up axis.
    pub up_axis: String,
    /// "m", "cm" or "mm": the sender's length unit.
    pub units: String,
    /// Also take `/othermarker` messages.
    pub othermarkers: bool,
    /// Nominal frame rate for recording headers (Hz).
    pub frame_rate: f64,
}

/// Where results go.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    /// Output folder for replay results and the daemon's files.
    pub dir: String,
}

/// The NatNet client (`treemocap record --natnet`, the daemon).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NatNetConfig {
    /// Which markers of a frame are tracked (see `source::natnet::select`).
    pub markers: crate::source::natnet::select::MarkerSelection,
    /// Wait for the server's SERVERINFO before reporting it unreachable (s).
    pub connect_timeout_s: f64,
    /// Silence after which the client reconnects (s).
    pub silence_timeout_s: f64,
    /// Unicast keep-alive period (s).
    pub keepalive_interval_s: f64,
}

/// Marker processing: tracking, gap filling, noise removal, rest phase
/// (spec/pipeline.md sections 2–4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackingConfig {
    /// Gate radius around a trace's prediction (mm).
    pub gate_mm: f64,
    /// Frames a trace survives without a marker before it ends.
    pub max_gap: u32,
    /// Longest gap that is filled by interpolation (s).
    pub max_fill_s: f64,
    /// Largest plausible disagreement between a gap's far end and a linear
    /// extrapolation across it (mm); beyond it the fill (or join) is refused.
    pub max_jump_mm: f64,
    /// Pieces whose rest positions are this close are one marker (mm).
    pub merge_radius_mm: f64,
    /// Traces measured in fewer than this fraction of frames are noise.
    pub noise_fraction: f64,
    /// Motion (standard deviation, mm) below which a marker counts as still.
    pub rest_motion_mm: f64,
    /// A fixed rest window `[start_s, end_s]`, or empty for automatic.
    pub rest_window_s: Vec<f64>,
    /// Markers of one frame closer than this are duplicates (mm).
    pub duplicate_mm: f64,
}

impl Default for TrackingConfig {
    fn default() -> Self {
        Config::default().tracking
    }
}

impl TrackingConfig {
    /// Range checks, each naming the key and its allowed range.
    pub fn validate(&self) -> Result<()> {
        check_range("tracking.gate_mm", self.gate_mm, 1.0, 500.0)?;
        check_range("tracking.max_gap", f64::from(self.max_gap), 0.0, 100_000.0)?;
        check_range("tracking.max_fill_s", self.max_fill_s, 0.0, 10.0)?;
        check_range("tracking.max_jump_mm", self.max_jump_mm, 1.0, 1000.0)?;
        check_range("tracking.merge_radius_mm", self.merge_radius_mm, 0.0, 100.0)?;
        check_range("tracking.noise_fraction", self.noise_fraction, 0.0, 1.0)?;
        check_range("tracking.rest_motion_mm", self.rest_motion_mm, 0.01, 100.0)?;
        check_range("tracking.duplicate_mm", self.duplicate_mm, 0.0, 10.0)?;
        match self.rest_window_s.as_slice() {
            [] => {}
            [a, b] if a.is_finite() && b.is_finite() && *a >= 0.0 && a < b => {}
            _ => {
                return Err(Error::config(
                    "tracking.rest_window_s",
                    "must be [] (automatic) or [start_s, end_s] with 0 <= start_s < end_s",
                ))
            }
        }
        Ok(())
    }
}

/// Where the wind estimate comes from (see `wind`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindConfig {
    /// Source names in order of trust: "sensor", "fan", "pca".
    pub priority: Vec<String>,
    /// Age after which a sensor or PCA estimate is ignored (s).
    pub max_age_s: f64,
    /// The fan's position (m, Y up), or empty for no fan.
    pub fan_position: Vec<f64>,
    /// The fan's wind speed at the tree (m/s), 0 when unknown.
    pub fan_speed_m_s: f64,
    /// Serial device of a wind sensor, empty for none.
    pub sensor_port: String,
    pub sensor_baud: u32,
    /// Capture azimuth of the sensor's 0° mark (degrees).
    pub sensor_heading_deg: f64,
    /// PCA window (s).
    pub pca_window_s: f64,
    /// RMS sway below which PCA gives no estimate (mm).
    pub pca_min_sway_mm: f64,
}

impl WindConfig {
    /// The priority list as sources (validated by `Config::validate`).
    pub fn priority(&self) -> Vec<crate::model::wind::WindSource> {
        self.priority
            .iter()
            .filter_map(|n| crate::model::wind::WindSource::from_name(n))
            .collect()
    }

    /// The fan's position, when one is configured.
    pub fn fan(&self) -> Option<glam::DVec3> {
        match self.fan_position[..] {
            [x, y, z] => Some(glam::DVec3::new(x, y, z)),
            _ => None,
        }
    }
}

/// `treemocap run`: sources, triggers and outputs of the daemon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DaemonConfig {
    /// "replay", "natnet" or "osc".
    pub source: String,
    pub replay_file: String,
    pub replay_speed: f64,
    pub replay_loop: bool,
    pub natnet_server: String,
    /// "auto", "unicast" or "multicast".
    pub natnet_transport: String,
    /// Seconds of frames kept for analysis.
    pub window_s: f64,
    /// Seconds of capture time between analyses.
    pub analysis_interval_s: f64,
    pub rest_min_s: f64,
    pub tip_change_s: f64,
    pub moved_mm: f64,
    pub wind_turn_deg: f64,
    /// 0 disables the periodic rebuild.
    pub period_s: f64,
    /// Gate of the live tip follower (mm).
    pub follow_gate_mm: f64,
    pub channel_frames: u32,
    pub record: bool,
    /// "" disables HTTP.
    pub http: String,
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
    pub osc_targets: Vec<String>,
    pub history: bool,
    /// UDP address for `/treemocap/rebuild`; "" disables.
    pub osc_control: String,
}

/// Reading C3D files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct C3dConfig {
    /// Which axis of a C3D file points up: "auto" (from POINT:Y_SCREEN,
    /// Z when absent), "y" or "z". Frames are always turned to Y up.
    pub up_axis: crate::format::c3d::UpAxisSetting,
}

/// Which crown volume the random tips are placed in (paper §5, Figure 10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VolumeKind {
    /// A vertical stack of bounding boxes; looser, more random crowns.
    Boxes,
    /// The convex hull of the captured tips; follows the crown more closely.
    Hull,
}

/// Particle-flow reconstruction (paper §5–6, spec §6–7). Every flow parameter
/// of the paper is here so that a user can re-run the flow on saved tips.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReconstructConfig {
    /// Seed for every random choice; same tips + config + seed = same bytes.
    pub seed: u64,
    /// Crown volume for the random tips.
    pub volume: VolumeKind,
    /// Boxes in the vertical stack (volume = boxes).
    pub boxes: usize,
    /// Captured + random tips: about the real tree's number of tips.
    pub total_tips: usize,
    /// Nodes on the synthetic trunk (paper: 9–10).
    pub trunk_nodes: usize,
    /// Trunk length as a multiple of the crown height (paper: about 1.2).
    pub height_factor: f64,
    /// Largest random x/z offset of a trunk node (m).
    pub trunk_offset: f64,
    /// Ground height (m): trunk base, zero of the mean particle height.
    pub ground_height: f64,
    /// Shape-format attractor as a trunk node index; -1 = the paper's choice.
    pub attractor_node: i64,
    /// β: step length factor, L = β |S_p − S_t|.
    pub beta: f64,
    /// α: shape-format magnitude factor on the mean particle height.
    pub alpha: f64,
    /// ω1: gravity weight (negative gives a willow).
    pub gravity_weight: f64,
    /// ω2: shape-format weight.
    pub shape_weight: f64,
    /// ω3: wind weight.
    pub wind_weight: f64,
    /// Particles closer than this merge into a junction (m).
    pub merge_distance: f64,
    /// Particles closer than this to a trunk node join the trunk (m).
    pub trunk_distance: f64,
    /// Steps before the remaining particles are joined to the trunk directly.
    pub max_steps: usize,
    /// Radius of a branch tip (m).
    pub tip_radius: f64,
    /// Pipe-model exponent γ.
    pub gamma: f64,
    /// Vertices per cylinder ring.
    pub sides: usize,
    /// Whether to add leaves.
    pub leaves: bool,
    /// Leaves begin at this fraction of a branch's length.
    pub leaf_start: f64,
    /// Leaves per metre of leafy branch.
    pub leaf_density: f64,
    /// Leaf length (m).
    pub leaf_size: f64,
}

impl ReconstructConfig {
    /// Range checks for the `[reconstruct]` section, each naming its key.
    pub fn validate(&self) -> Result<()> {
        let r = |key: &str, v: f64, lo: f64, hi: f64| {
            check_range(&format!("reconstruct.{key}"), v, lo, hi)
        };
        r("boxes", self.boxes as f64, 1.0, 100.0)?;
        r("total_tips", self.total_tips as f64, 1.0, 1_000_000.0)?;
        r("trunk_nodes", self.trunk_nodes as f64, 2.0, 1000.0)?;
        r("height_factor", self.height_factor, 0.1, 10.0)?;
        r("trunk_offset", self.trunk_offset, 0.0, 1.0)?;
        r("ground_height", self.ground_height, -100.0, 100.0)?;
        r(
            "attractor_node",
            self.attractor_node as f64,
            -1.0,
            self.trunk_nodes as f64 - 1.0,
        )?;
        r("beta", self.beta, 0.01, 1.0)?;
        r("alpha", self.alpha, 0.0, 1.0)?;
        r("gravity_weight", self.gravity_weight, -10.0, 10.0)?;
        r("shape_weight", self.shape_weight, 0.0, 10.0)?;
        r("wind_weight", self.wind_weight, -10.0, 10.0)?;
        r("merge_distance", self.merge_distance, 1e-6, 1.0)?;
        r("trunk_distance", self.trunk_distance, 1e-6, 1.0)?;
        r("max_steps", self.max_steps as f64, 1.0, 100_000.0)?;
        r("tip_radius", self.tip_radius, 1e-5, 1.0)?;
        r("gamma", self.gamma, 1.0, 4.0)?;
        r("sides", self.sides as f64, 3.0, 64.0)?;
        r("leaf_start", self.leaf_start, 0.0, 1.0)?;
        r("leaf_density", self.leaf_density, 0.0, 10_000.0)?;
        r("leaf_size", self.leaf_size, 0.001, 1.0)?;
        Ok(())
    }
}

impl Default for ReconstructConfig {
    fn default() -> Self {
        Config::default().reconstruct
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
        crate::source::osc::OscOptions::from_config(&self.osc)?;
        check_range(
            "natnet.connect_timeout_s",
            self.natnet.connect_timeout_s,
            0.1,
            60.0,
        )?;
        check_range(
            "natnet.silence_timeout_s",
            self.natnet.silence_timeout_s,
            0.1,
            60.0,
        )?;
        check_range(
            "natnet.keepalive_interval_s",
            self.natnet.keepalive_interval_s,
            0.05,
            10.0,
        )?;
        let w = &self.wind;
        let mut seen = Vec::new();
        for name in &w.priority {
            if crate::model::wind::WindSource::from_name(name).is_none() || seen.contains(&name) {
                return Err(Error::config(
                    "wind.priority",
                    format!(
                        "'{name}' is unknown or repeated; allowed: \"sensor\", \"fan\", \"pca\""
                    ),
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
        let d = &self.daemon;
        if !matches!(d.source.as_str(), "replay" | "natnet" | "osc") {
            return Err(Error::config(
                "daemon.source",
                format!("'{}': allowed \"replay\", \"natnet\", \"osc\"", d.source),
            ));
        }
        if !matches!(
            d.natnet_transport.as_str(),
            "auto" | "unicast" | "multicast"
        ) {
            return Err(Error::config(
                "daemon.natnet_transport",
                format!(
                    "'{}': allowed \"auto\", \"unicast\", \"multicast\"",
                    d.natnet_transport
                ),
            ));
        }
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
            "daemon.channel_frames",
            d.channel_frames as f64,
            16.0,
            1_000_000.0,
        )?;
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
        if !d.http.is_empty() && d.http.parse::<std::net::SocketAddr>().is_err() {
            return Err(Error::config(
                "daemon.http",
                format!("'{}' is not ADDRESS:PORT", d.http),
            ));
        }
        if !d.osc_control.is_empty() && d.osc_control.parse::<std::net::SocketAddr>().is_err() {
            return Err(Error::config(
                "daemon.osc_control",
                format!("'{}' is not ADDRESS:PORT", d.osc_control),
            ));
        }
        for t in &d.osc_targets {
            if t.parse::<std::net::SocketAddr>().is_err() {
                return Err(Error::config(
                    "daemon.osc_targets",
                    format!("'{t}' is not ADDRESS:PORT"),
                ));
            }
        }
        if self.output.dir.is_empty() {
            return Err(Error::config("output.dir", "must not be empty"));
        }
        self.tracking.validate()?;
        self.reconstruct.validate()?;
        Ok(())
    }
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

/// Fails unless `lo <= value <= hi` (and the value is a number).
pub fn check_range(key: &str, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(Error::config(
            key,
            format!("{value} is out of range; allowed {lo} to {hi}"),
        ))
    }
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
        use crate::source::natnet::select::MarkerSelection;
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
        assert_eq!(c.wind.priority(), vec![crate::model::wind::WindSource::Fan]);
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
        assert_eq!(c.reconstruct.volume, VolumeKind::Hull);
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
