//! The data rows of an export read in large blocks, cut at row boundaries
//! and parsed on worker threads, handed back in file order.
//!
//! Why: a dense export parses at a few hundred MB/s on one core, a tenth
//! of what reading it from a warm cache costs (issue 15). Blocks of whole
//! rows are independent once the header is known ([`super::rows`]), so
//! they are parsed side by side; the reader only reads, cuts and merges.
//!
//! Memory stays flat: at most `workers + 2` blocks are read ahead of the
//! frames handed out, whatever the file's length. A row is cut only at a
//! line end; a row running past a block pulls in the next ones until its
//! line end or the row limit, past which it is refused like before
//! (naming its line) without reading further.

use std::collections::VecDeque;
use std::io::{self, Read};
use std::sync::Arc;
use std::thread::JoinHandle;

use crossbeam_channel::{bounded, Receiver, Sender};

use super::rows::{Layout, Parsed, RowParser};

/// How the data rows are read: threads and block size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReadOptions {
    /// Threads parsing rows beside the reading one; 0 parses on the
    /// reading thread (the single-threaded path).
    pub workers: usize,
    /// Bytes read at a time, and the usual size of a chunk of rows handed
    /// to a worker. Larger amortises the hand-over; smaller keeps memory
    /// and the latency of the first frame down.
    pub block_bytes: usize,
}

impl Default for ReadOptions {
    /// As many workers as cores, two at most: parsing is nearly all of the
    /// work (the reading thread only reads, cuts and merges, and waits
    /// meanwhile), and the frames' consumer needs a core too.
    fn default() -> Self {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        ReadOptions {
            workers: if cores > 1 { cores.min(2) } else { 0 },
            block_bytes: 256 << 10,
        }
    }
}

/// A chunk's place in the file-order queue.
pub(super) enum Pending {
    /// Parsed on the reading thread (no workers, or a file of one block).
    Ready(Parsed),
    /// Being parsed by a worker; its result arrives here.
    Working(Receiver<Parsed>),
    /// The row after the chunks before this one passed the row limit
    /// without a line end: refused at its line, nothing read after it.
    TooLong,
    /// The OS refused to read.
    Io(io::Error),
}

/// Work for a worker: a chunk of whole rows and where to send its frames.
struct Job {
    bytes: Vec<u8>,
    reply: Sender<Parsed>,
}

/// The worker threads, started when the file turns out longer than a block.
struct Pool {
    jobs: Option<Sender<Job>>,
    /// Blocks parsed, back for reuse (no allocation per block).
    spare: Receiver<Vec<u8>>,
    handles: Vec<JoinHandle<()>>,
}

impl Pool {
    fn start(layout: &Arc<Layout>, workers: usize, depth: usize) -> io::Result<Pool> {
        let (jobs, job_rx) = bounded::<Job>(depth);
        let (spare_tx, spare) = bounded::<Vec<u8>>(depth);
        let mut handles = Vec::with_capacity(workers);
        for i in 0..workers {
            let (job_rx, spare_tx) = (job_rx.clone(), spare_tx.clone());
            let mut parser = RowParser::new(Arc::clone(layout));
            let handle = std::thread::Builder::new()
                .name(format!("csv-rows-{i}"))
                .spawn(move || {
                    for job in job_rx {
                        // The reader may have stopped waiting (an error
                        // before, or dropped): then the frames go nowhere.
                        let _ = job.reply.send(parser.parse(&job.bytes));
                        let _ = spare_tx.try_send(job.bytes);
                    }
                })?;
            handles.push(handle);
        }
        Ok(Pool {
            jobs: Some(jobs),
            spare,
            handles,
        })
    }
}

impl Drop for Pool {
    /// Closes the job queue and waits for the workers, each of which ends
    /// after the chunk it holds.
    fn drop(&mut self) {
        self.jobs = None;
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

/// Reads the data rows after the header in blocks and queues them in file
/// order, parsed or being parsed.
pub(super) struct Chunks {
    source: Box<dyn Read + Send>,
    layout: Arc<Layout>,
    options: ReadOptions,
    /// Bytes after the last line end read: the start of the next chunk.
    carry: Vec<u8>,
    /// The source has no more bytes, or a refusal was queued.
    ended: bool,
    pool: Option<Pool>,
    /// Parses chunks on the reading thread.
    local: RowParser,
    queue: VecDeque<Pending>,
}

impl Chunks {
    /// Data rows from `source`, which is positioned just after the header.
    pub(super) fn new(
        source: Box<dyn Read + Send>,
        layout: Arc<Layout>,
        options: ReadOptions,
    ) -> Self {
        let block_bytes = options
            .block_bytes
            .clamp(64, layout.limits.max_bytes.max(64));
        Chunks {
            source,
            local: RowParser::new(Arc::clone(&layout)),
            layout,
            options: ReadOptions {
                block_bytes,
                ..options
            },
            carry: Vec::new(),
            ended: false,
            pool: None,
            queue: VecDeque::new(),
        }
    }

    /// How many chunks are read ahead of the one being handed out.
    fn depth(&self) -> usize {
        self.options.workers + 2
    }

    /// The next chunk in file order; `None` once the file is read.
    pub(super) fn next_chunk(&mut self) -> Option<Pending> {
        while !self.ended && self.queue.len() < self.depth().max(1) {
            self.read_chunk();
            if self.options.workers == 0 {
                break; // no read-ahead without workers
            }
        }
        self.queue.pop_front()
    }

    /// A buffer for a block, reused when a worker gave one back.
    fn buffer(&mut self) -> Vec<u8> {
        let mut buf = self
            .pool
            .as_ref()
            .and_then(|p| p.spare.try_recv().ok())
            .unwrap_or_default();
        buf.clear();
        buf.reserve(self.options.block_bytes + self.carry.len());
        buf.extend_from_slice(&self.carry);
        buf
    }

    /// Reads the next block (more if a row runs past it) and queues the
    /// whole rows it holds.
    fn read_chunk(&mut self) {
        let mut buf = self.buffer();
        // Bytes of `buf` already known to hold no line end.
        let mut searched = buf.len();
        loop {
            let want = buf.len() + self.options.block_bytes;
            match fill(&mut self.source, &mut buf, want) {
                Ok(()) => {}
                Err(e) => {
                    self.ended = true;
                    self.dispatch_before(buf, Pending::Io(e));
                    return;
                }
            }
            if buf.len() < want {
                // The end of the file: the rest is the last chunk, its
                // last row perhaps without a line end.
                self.carry.clear();
                self.ended = true;
                if !buf.is_empty() {
                    self.dispatch(buf, true);
                }
                return;
            }
            if let Some(i) = buf[searched..].iter().rposition(|&b| b == b'\n') {
                let cut = searched + i + 1;
                self.carry.clear();
                self.carry.extend_from_slice(&buf[cut..]);
                buf.truncate(cut);
                self.dispatch(buf, false);
                return;
            }
            searched = buf.len();
            if buf.len() > self.layout.limits.max_bytes {
                self.carry.clear();
                self.ended = true;
                self.queue.push_back(Pending::TooLong);
                return;
            }
        }
    }

    /// Queues `last` after the whole rows of `buf` (the bytes before the
    /// last line end; the rest is an incomplete row that will never end).
    fn dispatch_before(&mut self, mut buf: Vec<u8>, last: Pending) {
        let cut = buf.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        buf.truncate(cut);
        if !buf.is_empty() {
            self.dispatch(buf, false);
        }
        self.queue.push_back(last);
    }

    /// Queues a chunk of whole rows: parsed here when there are no workers
    /// or when the file is a single chunk, else sent to a worker.
    fn dispatch(&mut self, bytes: Vec<u8>, last: bool) {
        let alone = last && self.queue.is_empty() && self.pool.is_none();
        if self.options.workers == 0 || alone {
            self.queue
                .push_back(Pending::Ready(self.local.parse(&bytes)));
            return;
        }
        if self.pool.is_none() {
            match Pool::start(&self.layout, self.options.workers, self.depth()) {
                Ok(pool) => self.pool = Some(pool),
                Err(_) => {
                    // No thread to be had: read on alone.
                    self.options.workers = 0;
                    self.queue
                        .push_back(Pending::Ready(self.local.parse(&bytes)));
                    return;
                }
            }
        }
        let (reply, result) = bounded(1);
        let job = Job { bytes, reply };
        let sent = self
            .pool
            .as_ref()
            .and_then(|p| p.jobs.as_ref())
            .map(|jobs| jobs.send(job));
        match sent {
            Some(Ok(())) => self.queue.push_back(Pending::Working(result)),
            // Every worker is gone (they only stop when the pool is
            // dropped, or by a bug): parse here rather than lose rows.
            Some(Err(e)) => self
                .queue
                .push_back(Pending::Ready(self.local.parse(&e.0.bytes))),
            None => {}
        }
    }
}

/// Reads from `source` into `buf` until it holds `want` bytes or the
/// source ends.
fn fill(source: &mut dyn Read, buf: &mut Vec<u8>, want: usize) -> io::Result<()> {
    while buf.len() < want {
        let n = Read::take(&mut *source, (want - buf.len()) as u64).read_to_end(buf);
        match n {
            Ok(0) => return Ok(()),
            Ok(_) => {}
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}
