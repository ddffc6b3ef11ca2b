//! The operator's console: what `treemocap run` prints on stderr without
//! `-v`. One line at start (source and the page's URL), a line when the
//! source starts sending or goes silent, the still-phase progress until the
//! first tree, a line per new tree. Colour only when stderr is a terminal.
//!
//! It reads the daemon's [`Status`] a few times a second on its own thread:
//! the pipeline never waits for the console.

use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use super::progress::Connection;
use super::status::Status;

/// How often the console looks at the status.
const POLL: Duration = Duration::from_millis(100);

/// What the console has already said, so each line is said once.
#[derive(Debug, Default)]
pub(crate) struct Console {
    /// Connection state last reported.
    connection: Option<Connection>,
    /// Whole seconds of still phase last reported.
    still_s: Option<u64>,
    /// Trees already reported.
    trees: u64,
}

/// A line of the console, before colouring.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Line {
    /// The source started or resumed sending.
    Receiving(String),
    /// The source went quiet.
    Silent(String),
    /// Still-phase progress.
    Still(String),
    /// A new tree.
    Tree(String),
}

impl Console {
    /// The lines due since the last call (pure: no clock, no output).
    pub(crate) fn lines(&mut self, s: &Status) -> Vec<Line> {
        let mut out = Vec::new();
        let p = &s.progress;
        let conn = p.connection();
        if Some(conn) != self.connection {
            match conn {
                Connection::Receiving => out.push(Line::Receiving(format!(
                    "source: receiving frames ({} markers in the first)",
                    s.markers.load(Ordering::Relaxed)
                ))),
                Connection::Silent => out.push(Line::Silent(format!(
                    "source: silent (no frame for {:.1} s; last frame {})",
                    p.silent_s().unwrap_or(0.0),
                    s.last_frame.load(Ordering::Relaxed)
                ))),
                Connection::Waiting => {}
            }
            self.connection = Some(conn);
        }
        let trees = s.trees.load(Ordering::Relaxed);
        if trees == 0 {
            if let Some(still) = p.still_s() {
                let needed = p.needed_s();
                let whole = still.floor() as u64;
                if self.still_s != Some(whole) && still < needed {
                    out.push(Line::Still(format!(
                        "still for {still:.1} s of {needed} s needed"
                    )));
                }
                self.still_s = Some(whole);
            }
        }
        if trees > self.trees {
            self.trees = trees;
            if let Some(t) = s.last_tree.lock().ok().and_then(|t| t.clone()) {
                out.push(Line::Tree(format!(
                    "tree {}: {} — {} nodes, {} tips, built in {:.0} ms",
                    t["version"],
                    t["reason_text"].as_str().unwrap_or("?"),
                    t["nodes"],
                    t["tips"],
                    t["build_ms"].as_f64().unwrap_or(0.0)
                )));
            }
        }
        out
    }
}

/// The line printed at start: the source and where the page is.
pub(crate) fn start_line(status: &Status, http: Option<std::net::SocketAddr>) -> String {
    let source = status.source.lock().map(|s| s.clone()).unwrap_or_default();
    match http {
        Some(addr) => format!("treemocap run: {source}; live view at http://{addr}/"),
        None => format!("treemocap run: {source}; no HTTP server (daemon.http is empty)"),
    }
}

/// Colours a line for a terminal; plain text otherwise.
pub(crate) fn paint(line: &Line, colour: bool) -> String {
    let (code, text) = match line {
        Line::Receiving(t) => ("32", t),
        Line::Silent(t) => ("33", t),
        Line::Still(t) => ("36", t),
        Line::Tree(t) => ("1;32", t),
    };
    if colour {
        format!("\x1b[{code}m{text}\x1b[0m")
    } else {
        text.clone()
    }
}

/// Prints the start line and then the console's lines until `stop`.
pub(crate) fn spawn(
    start: String,
    status: Arc<Status>,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<()> {
    let colour = std::io::stderr().is_terminal();
    eprintln!("{start}");
    std::thread::Builder::new()
        .name("treemocap-console".into())
        .spawn(move || {
            let mut console = Console::default();
            while !stop.load(Ordering::Relaxed) {
                let lines = console.lines(&status);
                let mut err = std::io::stderr().lock();
                for l in &lines {
                    let _ = writeln!(err, "{}", paint(l, colour));
                }
                drop(err);
                std::thread::sleep(POLL);
            }
        })
        .expect("spawn the console thread")
}
