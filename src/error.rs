//! One error type for the library, so the CLI can map every failure to a
//! one-line message that names the file and position, and to an exit code.

use std::fmt;
use std::path::PathBuf;

/// Where in an input a problem was found. Text formats have lines, binary
/// formats and packets have byte offsets, configs have dotted keys.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// 1-based line, optionally with a 1-based column (CSV field index).
    Line {
        /// Line as a text editor counts it, from 1.
        line: u64,
        /// Column (CSV field) from 1, when the problem is in one field.
        column: Option<u64>,
    },
    /// Byte offset from the start of the file or packet.
    Offset(u64),
    /// A named field (config key, packet field).
    Field(String),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line { line, column: None } => write!(f, "line {line}"),
            Location::Line {
                line,
                column: Some(c),
            } => write!(f, "line {line}, column {c}"),
            Location::Offset(o) => write!(f, "byte {o}"),
            Location::Field(name) => write!(f, "field {name}"),
        }
    }
}

/// Everything that can go wrong in treemocap, split by what the user must fix.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The OS refused to read or write a file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or device the OS refused.
        path: PathBuf,
        /// What the OS said.
        #[source]
        source: std::io::Error,
    },
    /// An input file is malformed at a known place.
    #[error("{}: {at}: {msg}", path.display())]
    Parse {
        /// The malformed file.
        path: PathBuf,
        /// Where in it: line, byte offset or field.
        at: Location,
        /// What is wrong there, phrased for a user.
        msg: String,
    },
    /// The file is of a kind or version we recognise but do not read.
    #[error("{}: {msg}", path.display())]
    Unsupported {
        /// The file we will not read.
        path: PathBuf,
        /// Which kind or version it is and what we read instead.
        msg: String,
    },
    /// A configuration key is unknown, mistyped or out of range (exit code 2).
    #[error("config {key}: {msg}")]
    Config {
        /// The dotted key (`section.key`) the user must fix.
        key: String,
        /// What is wrong with its value, with the allowed range if any.
        msg: String,
    },
    /// A stage could not do its work on inputs that passed their checks
    /// (a reconstruction that breaks, an encoder at a format's limit); the
    /// stage's own error type says what happened.
    #[error("{stage}: {source}")]
    Stage {
        /// The stage, as the user knows it ("reconstruction", "tree.glb").
        stage: &'static str,
        /// The stage's error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A listener could not start: a port in use, an address this machine
    /// does not have.
    #[error("{what} on {addr}: {source}")]
    Bind {
        /// What was to listen ("HTTP", "OSC control").
        what: &'static str,
        /// Where.
        addr: std::net::SocketAddr,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// Anything else at run time (threads, the async runtime), already
    /// phrased for a user.
    #[error("{0}")]
    Runtime(String),
}

impl Error {
    /// An I/O failure on `path`, so the message names the file.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// Malformed input in `path` at `at`.
    pub fn parse(path: impl Into<PathBuf>, at: Location, msg: impl Into<String>) -> Self {
        Error::Parse {
            path: path.into(),
            at,
            msg: msg.into(),
        }
    }

    /// Malformed input at a 1-based line (and column) of a text file.
    pub fn at_line(
        path: impl Into<PathBuf>,
        line: u64,
        column: Option<u64>,
        msg: impl Into<String>,
    ) -> Self {
        Self::parse(path, Location::Line { line, column }, msg)
    }

    /// A JSON file serde could not read, at the line and column it names.
    pub fn json(path: impl Into<PathBuf>, e: &serde_json::Error) -> Self {
        Self::at_line(
            path,
            e.line() as u64,
            Some(e.column() as u64),
            e.to_string(),
        )
    }

    /// A bad configuration value, named by its dotted key.
    pub fn config(key: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Config {
            key: key.into(),
            msg: msg.into(),
        }
    }

    /// The process exit code the CLI uses: 2 for bad usage or config, 1 otherwise.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Config { .. } => 2,
            _ => 1,
        }
    }
}

/// The library's result type: every fallible function returns [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

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

/// Longest excerpt of an input quoted in a message, in characters: enough to
/// recognise the value, short enough that an error stays one readable line
/// however long the field was (a stray quote can swallow megabytes).
pub const EXCERPT_CHARS: usize = 80;

/// `text` as it may appear inside a one-line message: at most
/// [`EXCERPT_CHARS`] characters, control characters (newlines, tabs, escape
/// codes), quotes and backslashes escaped Rust-style, `…` where it was cut.
pub fn excerpt(text: &str) -> String {
    excerpt_bytes(text.as_bytes())
}

/// [`excerpt`] of bytes that may not be UTF-8; invalid bytes show as `\xNN`.
pub fn excerpt_bytes(bytes: &[u8]) -> String {
    let mut out = String::new();
    let mut shown = 0;
    for chunk in bytes.utf8_chunks() {
        for c in chunk.valid().chars() {
            if shown == EXCERPT_CHARS {
                out.push('…');
                return out;
            }
            if c.is_control() || c == '"' || c == '\\' {
                out.extend(c.escape_default());
            } else {
                out.push(c);
            }
            shown += 1;
        }
        for b in chunk.invalid() {
            if shown == EXCERPT_CHARS {
                out.push('…');
                return out;
            }
            out.push_str(&format!("\\x{b:02X}"));
            shown += 1;
        }
    }
    out
}

/// A message made safe for one line of a terminal or log: control
/// characters (a newline from a file that slipped into a message) escaped.
/// The last guard before an error is printed; excerpts are already short.
pub fn one_line(message: &str) -> String {
    if !message.chars().any(char::is_control) {
        return message.to_string();
    }
    message
        .chars()
        .flat_map(|c| {
            let escaped: Vec<char> = if c.is_control() {
                c.escape_default().collect()
            } else {
                vec![c]
            };
            escaped
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn excerpts_are_short_escaped_and_marked_when_cut() {
        assert_eq!(excerpt("a\"b\nc\\"), "a\\\"b\\nc\\\\");
        let long = "x".repeat(5_000_000);
        let e = excerpt(&long);
        assert_eq!(e.chars().count(), EXCERPT_CHARS + 1);
        assert!(e.ends_with('…'));
        assert_eq!(excerpt_bytes(b"ok\xFF\xFEz"), "ok\\xFF\\xFEz");
        assert_eq!(one_line("two\nlines\t!"), "two\\nlines\\t!");
    }
}
