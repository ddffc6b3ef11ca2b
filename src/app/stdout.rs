//! Command output on standard output. A reader that closed the pipe
//! (`treemocap inspect --json … | head -c 800`) no longer wants the output:
//! the rest is dropped and the command ends quietly with its work done,
//! instead of panicking as `println!` does (exit 101). Any other write error
//! (a full disk behind `> file`) is an error.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{Error, Result};

/// Set once standard output is closed by its reader.
static CLOSED: AtomicBool = AtomicBool::new(false);

/// Writes `args` to standard output (use with `format_args!`).
pub fn print(args: std::fmt::Arguments) -> Result<()> {
    if CLOSED.load(Ordering::Relaxed) {
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    match out.write_fmt(args).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            CLOSED.store(true, Ordering::Relaxed);
            Ok(())
        }
        Err(e) => Err(Error::Runtime(format!(
            "cannot write to standard output: {e}"
        ))),
    }
}
