//! Recording a live source to our log format (`replay::log`): the loop
//! behind `treemocap record`, reusable by the daemon.
//!
//! The source runs as a tokio task and pushes into a bounded frame channel;
//! a blocking thread owns the `LogWriter`, so a slow disk never stalls the
//! socket (the channel absorbs it, and drops the oldest frames, counted, if
//! it must). The writer is ticked at least every 20 ms, so whole frames
//! reach the OS within `flush_interval` of arriving: a killed recorder loses
//! at most that much, and the file always ends on a whole row.

use std::path::PathBuf;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::RecvTimeoutError;
use serde::Serialize;
use tokio::sync::watch;

use crate::app::recording::{Recorder, RecordingStats};
use crate::app::stdout::print;
use crate::error::{Error, Result};
use crate::format::log::LogHeader;
use crate::source::channel::{frame_channel, FrameReceiver};
use crate::source::live::{LiveSource, SourceReport};

/// Longest wait of the writer thread before it checks the flush interval:
/// small against the interval, so a crash loses little more than it.
const WRITER_TICK: Duration = Duration::from_millis(20);
/// How often the reporting loop looks at the source's status and counters.
const TICK: Duration = Duration::from_millis(100);

/// How to record.
#[derive(Debug, Clone)]
pub struct RecordOptions {
    /// The log file to create (truncated if it exists).
    pub out: PathBuf,
    /// Stop after this many seconds; `None` runs until the shutdown signal.
    pub seconds: Option<f64>,
    /// Longest time between flushes: what a crash may lose.
    pub flush_interval: Duration,
    /// Frames queued between source and writer before the oldest is dropped.
    pub queue_frames: usize,
    /// Header frame rate when the source does not know its rate.
    pub default_frame_rate: f64,
    /// How often progress is reported.
    pub progress_interval: Duration,
}

impl RecordOptions {
    /// Options for `out` with the `[record]` settings of `config`.
    pub fn from_config(out: PathBuf, seconds: Option<f64>, config: &crate::config::Config) -> Self {
        RecordOptions {
            out,
            seconds,
            flush_interval: Duration::from_secs_f64(config.record.flush_interval_s),
            queue_frames: usize::try_from(config.record.queue_frames).unwrap_or(usize::MAX),
            default_frame_rate: 120.0,
            progress_interval: Duration::from_secs(1),
        }
    }
}

/// Where a recording stands, reported every `progress_interval` and at the end.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Progress {
    /// Seconds since recording started.
    pub elapsed_s: f64,
    /// Frames written to the log.
    pub frames: u64,
    /// Marker samples written.
    pub samples: u64,
    /// The last frame number written.
    pub last_frame: Option<i64>,
    /// Markers in the last frame written.
    pub last_markers: u64,
    /// Frames missing from the source's numbering (lost on the network):
    /// the sum of the gaps between consecutive frame numbers.
    pub missed_frames: u64,
    /// Times the frame number went backwards (the sender restarted).
    pub restarts: u64,
    /// The source's own losses by kind (see `LiveSource::losses`).
    pub losses: Vec<(String, u64)>,
    /// Frames lost because writes failed (a full disk); see
    /// [`crate::app::recording`].
    pub lost_to_disk: u64,
    /// Files written (more than one after a failed write).
    pub files: u64,
}

/// What `record` tells its caller as it goes.
#[derive(Debug, Clone, PartialEq)]
pub enum RecordEvent {
    /// The source's state changed ("listening on …", "connected to …").
    Status(String),
    /// Periodic counts.
    Progress(Progress),
}

/// What a finished recording did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordSummary {
    /// The log file written.
    pub out: PathBuf,
    /// Final counts.
    pub progress: Progress,
    /// The source's own report.
    pub source: SourceReport,
}

/// Counters shared by the writer thread and the reporting loop.
#[derive(Debug, Default)]
struct WriterStats {
    /// The recording's own counters (files, frames lost to the disk).
    recording: Arc<RecordingStats>,
    frames: AtomicU64,
    samples: AtomicU64,
    last_frame: AtomicI64,
    last_markers: AtomicU64,
    missed_frames: AtomicU64,
    restarts: AtomicU64,
}

impl WriterStats {
    fn progress(&self, elapsed_s: f64, losses: Vec<(String, u64)>) -> Progress {
        let frames = self.frames.load(Ordering::Relaxed);
        Progress {
            elapsed_s,
            frames,
            samples: self.samples.load(Ordering::Relaxed),
            last_frame: (frames > 0).then(|| self.last_frame.load(Ordering::Relaxed)),
            last_markers: self.last_markers.load(Ordering::Relaxed),
            missed_frames: self.missed_frames.load(Ordering::Relaxed),
            restarts: self.restarts.load(Ordering::Relaxed),
            losses,
            lost_to_disk: self.recording.frames_lost.load(Ordering::Relaxed),
            files: self.recording.files.load(Ordering::Relaxed),
        }
    }
}

/// Records `source` into `opts.out` until `shutdown` turns true, `opts.seconds`
/// pass, or the source stops by itself. `on_event` sees status changes and
/// progress. Fails when the file cannot be written or the source cannot start
/// (a port in use, a server not answering); the frames written until then stay
/// in the file.
pub async fn record(
    source: Arc<dyn LiveSource>,
    opts: &RecordOptions,
    mut shutdown: watch::Receiver<bool>,
    mut on_event: impl FnMut(RecordEvent) + Send,
) -> Result<RecordSummary> {
    // Fail on an unwritable path before starting anything; the header is
    // written when the first frame tells the source's frame rate.
    std::fs::File::create(&opts.out).map_err(|e| Error::io(&opts.out, e))?;
    let (sink, rx) = frame_channel(opts.queue_frames);
    // Reads the sink's drop counter while the source runs; dropped as soon
    // as the source stops, so the writer then sees the channel close.
    let probe = sink.clone();
    let (stop_tx, stop_rx) = watch::channel(false);
    let started = Instant::now();
    let mut src = tokio::spawn(source.start(sink, stop_rx));
    let stats = Arc::new(WriterStats::default());
    let mut writer = {
        let stats = stats.clone();
        let source = source.clone();
        let opts = opts.clone();
        tokio::task::spawn_blocking(move || write_loop(rx, &opts, source.as_ref(), &stats))
    };
    let deadline = opts
        .seconds
        .map(|s| tokio::time::Instant::from_std(started) + Duration::from_secs_f64(s.max(0.0)));
    let mut reporter = Reporter {
        source: source.as_ref(),
        stats: &stats,
        probe: &probe,
        started,
        next_progress: started + opts.progress_interval,
        interval: opts.progress_interval,
        status: None,
    };
    let (source_done, writer_done) = watch_recording(
        &mut src,
        &mut writer,
        &mut shutdown,
        deadline,
        &mut reporter,
        &mut on_event,
    )
    .await;
    // Stop the source; it delivers what it holds and drops the sink, which
    // ends the writer once the queue is drained.
    let _ = stop_tx.send(true);
    let report = join(src, source_done, "the source task failed").await;
    let dropped = probe.dropped();
    drop(probe);
    let written = join(writer, writer_done, "the writer thread failed").await;
    // A writer error (disk full) matters more than the source's.
    written??;
    let report = match report? {
        Ok(r) => r,
        Err(e) => {
            // A source that never started (port in use, no server) leaves
            // no empty log behind to be mistaken for a recording.
            if stats.frames.load(Ordering::Relaxed) == 0 {
                let _ = std::fs::remove_file(&opts.out);
            }
            return Err(e);
        }
    };
    let progress = stats.progress(
        started.elapsed().as_secs_f64(),
        losses(source.as_ref(), dropped),
    );
    Ok(RecordSummary {
        out: opts.out.clone(),
        progress,
        source: report,
    })
}

/// The outcome of a task that [`watch_recording`] may already have joined.
type Joined<T> = Option<std::result::Result<T, tokio::task::JoinError>>;

/// Reports status and progress while the recording runs, until shutdown,
/// the deadline, or the source or the writer ending by itself (whose
/// outcome is returned, since a task can be joined only once).
async fn watch_recording<S, W>(
    src: &mut tokio::task::JoinHandle<S>,
    writer: &mut tokio::task::JoinHandle<W>,
    shutdown: &mut watch::Receiver<bool>,
    deadline: Option<tokio::time::Instant>,
    reporter: &mut Reporter<'_>,
    on_event: &mut (impl FnMut(RecordEvent) + Send),
) -> (Joined<S>, Joined<W>) {
    let mut ticks = tokio::time::interval(TICK);
    loop {
        if *shutdown.borrow() {
            return (None, None);
        }
        tokio::select! {
            changed = shutdown.changed() => {
                if changed.is_err() {
                    return (None, None);
                }
            }
            _ = sleep_until(deadline) => return (None, None),
            r = &mut *src => return (Some(r), None),
            r = &mut *writer => return (None, Some(r)),
            _ = ticks.tick() => reporter.tick(on_event),
        }
    }
}

/// Waits for a task unless [`watch_recording`] already did; a task that
/// panicked or was cancelled is a runtime error saying `what`.
async fn join<T>(handle: tokio::task::JoinHandle<T>, done: Joined<T>, what: &str) -> Result<T> {
    match done {
        Some(r) => r,
        None => handle.await,
    }
    .map_err(|e| Error::Runtime(format!("{what}: {e}")))
}

/// What the watch loop reports to the caller: the source's status when it
/// changes and the counters every `interval`.
struct Reporter<'a> {
    source: &'a dyn LiveSource,
    stats: &'a WriterStats,
    /// The sink's drop counter.
    probe: &'a crate::source::channel::FrameSink,
    started: Instant,
    next_progress: Instant,
    interval: Duration,
    /// The last status reported, so that only changes are.
    status: Option<String>,
}

impl Reporter<'_> {
    /// One look at the source and the counters (every [`TICK`]).
    fn tick(&mut self, on_event: &mut impl FnMut(RecordEvent)) {
        let now = self.source.status();
        if now.is_some() && now != self.status {
            self.status = now.clone();
            on_event(RecordEvent::Status(now.unwrap_or_default()));
        }
        if Instant::now() >= self.next_progress {
            self.next_progress += self.interval;
            on_event(RecordEvent::Progress(self.stats.progress(
                self.started.elapsed().as_secs_f64(),
                losses(self.source, self.probe.dropped()),
            )));
        }
    }
}

/// The source's losses plus the frames the channel dropped.
fn losses(source: &dyn LiveSource, dropped: u64) -> Vec<(String, u64)> {
    let mut l = source.losses();
    l.push(("dropped".into(), dropped));
    l
}

/// One console line: "12.0 s  1440 frames (last 1439, 30 markers)  missed 0  restarts 0  dropped 0 …".
pub fn progress_line(p: &Progress) -> String {
    let mut line = format!("{:7.1} s  {} frames", p.elapsed_s, p.frames);
    if let Some(last) = p.last_frame {
        line += &format!(" (last {last}, {} markers)", p.last_markers);
    }
    line += &format!(
        "  {} samples  missed {}  restarts {}",
        p.samples, p.missed_frames, p.restarts
    );
    for (kind, n) in &p.losses {
        line += &format!("  {kind} {n}");
    }
    if p.lost_to_disk > 0 || p.files > 1 {
        line += &format!("  lost to the disk {}  files {}", p.lost_to_disk, p.files);
    }
    line
}

async fn sleep_until(deadline: Option<tokio::time::Instant>) {
    match deadline {
        Some(d) => tokio::time::sleep_until(d).await,
        None => std::future::pending().await,
    }
}

/// Owns the log: writes every frame that comes, ticks the flush timer,
/// finishes the file when the channel closes.
fn write_loop(
    rx: FrameReceiver,
    opts: &RecordOptions,
    source: &dyn LiveSource,
    stats: &WriterStats,
) -> Result<()> {
    let header = |source: &dyn LiveSource| LogHeader {
        source: source.describe(),
        frame_rate: source
            .frame_rate()
            .filter(|r| r.is_finite() && *r > 0.0)
            .unwrap_or(opts.default_frame_rate),
    };
    let mut log: Option<Recorder> = None;
    let mut last: Option<i64> = None;
    loop {
        match rx.recv_timeout(WRITER_TICK) {
            Ok(frame) => {
                let w = match &mut log {
                    Some(w) => w,
                    None => log.insert(Recorder::create(
                        &opts.out,
                        header(source),
                        opts.flush_interval,
                        stats.recording.clone(),
                    )?),
                };
                // A failed write is counted and logged by the recorder,
                // which goes on in a new file once writes work again.
                w.write_frame(&frame);
                if let Some(prev) = last {
                    if frame.frame > prev {
                        let gap = frame.frame.saturating_sub(prev).saturating_sub(1);
                        stats
                            .missed_frames
                            .fetch_add(gap.unsigned_abs(), Ordering::Relaxed);
                    } else if frame.frame < prev {
                        stats.restarts.fetch_add(1, Ordering::Relaxed);
                    }
                }
                last = Some(frame.frame);
                stats.last_frame.store(frame.frame, Ordering::Relaxed);
                stats
                    .last_markers
                    .store(frame.markers.len() as u64, Ordering::Relaxed);
                stats
                    .samples
                    .fetch_add(frame.markers.len() as u64, Ordering::Relaxed);
                stats.frames.fetch_add(1, Ordering::Relaxed);
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        if let Some(w) = &mut log {
            w.tick();
        }
    }
    let w = match log {
        Some(w) => w,
        // Nothing arrived: still leave a valid, empty log.
        None => Recorder::create(
            &opts.out,
            header(source),
            opts.flush_interval,
            stats.recording.clone(),
        )?,
    };
    let counts = w.finish();
    if counts.frames_lost > 0 {
        tracing::warn!("{counts}");
    }
    Ok(())
}

/// The `treemocap record` command: builds the source from the settings
/// (`--osc ADDR:PORT` or `--natnet SERVER`), records until the shutdown
/// signal or `--seconds`, and prints what it did.
pub fn command(
    rt: &tokio::runtime::Handle,
    shutdown: &crate::shutdown::Shutdown,
    source: Arc<dyn LiveSource>,
    opts: &RecordOptions,
) -> Result<RecordSummary> {
    print(format_args!("recording to {}\n", opts.out.display()))?;
    let summary = rt.block_on(record(
        source,
        opts,
        shutdown.receiver(),
        |event| match event {
            // Recording goes on when the reader of the progress is gone.
            RecordEvent::Status(s) => {
                let _ = print(format_args!("{s}\n"));
            }
            RecordEvent::Progress(p) => {
                let _ = print(format_args!("{}\n", progress_line(&p)));
            }
        },
    ))?;
    print(format_args!("{}\n", progress_line(&summary.progress)))?;
    print(format_args!("{}\n", summary.source))?;
    if summary.progress.frames == 0 {
        // A header alone is no recording: leave nothing to be mistaken for one.
        let _ = std::fs::remove_file(&summary.out);
        return Err(Error::Runtime(format!(
            "no frame came from {} in {:.1} s; nothing was recorded (NatNet multicast: check \
             natnet.interface, the group and the data port; OSC: check the sender's address)",
            summary.source.source, summary.progress.elapsed_s
        )));
    }
    print(format_args!("wrote {}\n", summary.out.display()))?;
    Ok(summary)
}
