//! Writing to the standard streams without panicking.
//!
//! `println!` and `eprintln!` panic when their stream is a pipe nobody
//! reads any more (EPIPE), which turns a closed terminal or `| head` into
//! exit status 101 and a backtrace. Here a closed stderr is ignored (there
//! is nowhere left to say anything), and a closed stdout is an error the
//! caller turns into its exit status. `main.rs` denies `print_stdout` and
//! `print_stderr` so the panicking macros cannot come back.

use std::fmt;
use std::io::{self, Write};

/// One line on stderr, formatted as `eprintln!` does; a write error (a
/// closed pipe) is ignored.
macro_rules! note {
    ($($arg:tt)*) => {
        $crate::console::stderr_line(format_args!($($arg)*))
    };
}
pub(crate) use note;

/// One line on stdout, formatted as `println!` does: `Err` when stdout is
/// closed, never a panic.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::console::stdout_line(format_args!($($arg)*))
    };
}
pub(crate) use say;

/// Writes `args` and a newline to stderr, ignoring any error.
pub(crate) fn stderr_line(args: fmt::Arguments<'_>) {
    let mut err = io::stderr().lock();
    let _ = err.write_fmt(args).and_then(|()| err.write_all(b"\n"));
}

/// Writes `args` and a newline to stdout.
pub(crate) fn stdout_line(args: fmt::Arguments<'_>) -> io::Result<()> {
    let mut out = io::stdout().lock();
    out.write_fmt(args)?;
    out.write_all(b"\n")
}
