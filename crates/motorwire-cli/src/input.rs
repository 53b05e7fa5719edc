//! Reading documents from files and stdin, never holding more than the
//! configured maximum document size (plus one byte) of any one document,
//! and never reading without end: a line over its limit is skipped to its
//! end, but only for [`MAX_SKIP`] bytes (so `/dev/zero` ends in an error,
//! not a loop), and a file read whole is read up to its limit plus one byte.

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Write};
use std::path::Path;

/// How far past its limit an over-long line is skipped looking for its
/// end (16 MiB); an input with no newline within that is given up on with
/// an error (it is not text lines: `/dev/zero`, a binary file).
pub(crate) const MAX_SKIP: usize = 16 << 20;

/// One document read from an input.
pub(crate) struct Document {
    /// 1-based line number, for `--lines`.
    pub(crate) line: Option<usize>,
    /// The text, or why it could not be taken as text.
    pub(crate) text: Result<String, Refused>,
}

/// A document refused before validation.
pub(crate) enum Refused {
    /// More than `limit` bytes.
    TooLarge { limit: usize },
    /// Not UTF-8.
    NotUtf8,
}

pub(crate) fn open(path: &str) -> io::Result<Box<dyn BufRead>> {
    if path == "-" {
        Ok(Box::new(BufReader::new(io::stdin())))
    } else {
        Ok(Box::new(BufReader::new(File::open(path)?)))
    }
}

/// Standard input (`-`) or the file at `path`, unbuffered.
pub(crate) fn open_raw(path: &Path) -> io::Result<Box<dyn Read>> {
    if path == Path::new("-") {
        Ok(Box::new(io::stdin().lock()))
    } else {
        Ok(Box::new(File::open(path)?))
    }
}

/// The whole file at `path` (never standard input) as text, reading at
/// most `limit` bytes plus one; the error says what was wrong (the caller
/// names the file).
pub(crate) fn read_text_file(path: &str, limit: usize) -> Result<String, String> {
    let mut reader = BufReader::new(File::open(path).map_err(|e| e.to_string())?);
    match whole(&mut reader, limit).map_err(|e| e.to_string())?.text {
        Ok(text) => Ok(text),
        Err(Refused::TooLarge { limit }) => {
            Err(format!("the file is over {limit} bytes, the limit"))
        }
        Err(Refused::NotUtf8) => Err("the file is not UTF-8".to_owned()),
    }
}

fn decode(bytes: Vec<u8>) -> Result<String, Refused> {
    String::from_utf8(bytes).map_err(|_| Refused::NotUtf8)
}

/// The whole input as one document.
pub(crate) fn whole(reader: &mut dyn BufRead, limit: usize) -> io::Result<Document> {
    let mut bytes = Vec::new();
    let cap = u64::try_from(limit).unwrap_or(u64::MAX).saturating_add(1);
    reader.take(cap).read_to_end(&mut bytes)?;
    let text = if bytes.len() > limit {
        Err(Refused::TooLarge { limit })
    } else {
        decode(bytes)
    };
    Ok(Document { line: None, text })
}

/// Reads the next non-blank line as a document; a line longer than `limit`
/// is skipped to its end and refused as too large.
///
/// # Errors
/// The reader's; [`io::ErrorKind::InvalidData`] when an over-long line has
/// no end within [`MAX_SKIP`] bytes past `limit` (the rest of the input is
/// not read).
pub(crate) fn next_line(
    reader: &mut dyn BufRead,
    limit: usize,
    line_no: &mut usize,
) -> io::Result<Option<Document>> {
    loop {
        let mut bytes = Vec::new();
        let mut too_large = false;
        let mut skipped = 0usize;
        let mut saw_any = false;
        loop {
            let (consumed, done) = {
                let buf = reader.fill_buf()?;
                if buf.is_empty() {
                    (0, true)
                } else {
                    saw_any = true;
                    let (chunk, done) = match buf.iter().position(|&b| b == b'\n') {
                        Some(i) => (buf.get(..i).unwrap_or_default(), Some(i + 1)),
                        None => (buf, None),
                    };
                    if too_large {
                        skipped = skipped.saturating_add(chunk.len());
                    } else if bytes.len() + chunk.len() > limit {
                        too_large = true;
                        skipped = bytes.len() + chunk.len() - limit;
                        bytes.clear();
                    } else {
                        bytes.extend_from_slice(chunk);
                    }
                    if too_large && done.is_none() && skipped > MAX_SKIP {
                        return Err(io::Error::new(
                            io::ErrorKind::InvalidData,
                            format!(
                                "line {} is over {limit} bytes and has no end within {} MiB more; \
                                 the rest of the input is not read",
                                *line_no + 1,
                                MAX_SKIP >> 20
                            ),
                        ));
                    }
                    match done {
                        Some(n) => (n, true),
                        None => (buf.len(), false),
                    }
                }
            };
            reader.consume(consumed);
            if done {
                break;
            }
        }
        if !saw_any {
            return Ok(None);
        }
        *line_no += 1;
        if bytes.last() == Some(&b'\r') {
            bytes.pop();
        }
        if too_large {
            return Ok(Some(Document {
                line: Some(*line_no),
                text: Err(Refused::TooLarge { limit }),
            }));
        }
        if bytes.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        return Ok(Some(Document {
            line: Some(*line_no),
            text: decode(bytes),
        }));
    }
}

/// Input read line by line for output written line by line: `out` is
/// flushed whenever the input has nothing buffered, that is just before a
/// read that may wait. A result is therefore on its way as soon as its line
/// is in, however long the input stays open (`candump -L vcan0 | motorwire
/// candump decode -`), while a file read in one go is still written in
/// large blocks.
pub(crate) struct Live<W: Write> {
    input: BufReader<Box<dyn Read>>,
    out: W,
    out_failed: bool,
}

impl<W: Write> Live<W> {
    pub(crate) fn new(input: Box<dyn Read>, out: W) -> Self {
        Self {
            input: BufReader::with_capacity(64 * 1024, input),
            out,
            out_failed: false,
        }
    }

    /// Where the output goes.
    pub(crate) fn out(&mut self) -> &mut W {
        &mut self.out
    }

    /// Whether a read failed because flushing the output did (stdout
    /// closed), not because of the input.
    pub(crate) fn out_failed(&self) -> bool {
        self.out_failed
    }

    fn flush_before_wait(&mut self) -> io::Result<()> {
        if self.input.buffer().is_empty() {
            self.out.flush().inspect_err(|_| self.out_failed = true)?;
        }
        Ok(())
    }
}

impl<W: Write> Read for Live<W> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.flush_before_wait()?;
        self.input.read(buf)
    }
}

impl<W: Write> BufRead for Live<W> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        self.flush_before_wait()?;
        self.input.fill_buf()
    }

    fn consume(&mut self, amount: usize) {
        self.input.consume(amount);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(input: &(impl AsRef<[u8]> + ?Sized), limit: usize) -> Vec<(usize, String)> {
        let mut r: &[u8] = input.as_ref();
        let mut n = 0;
        let mut out = Vec::new();
        while let Some(d) = next_line(&mut r, limit, &mut n).unwrap() {
            let t = match d.text {
                Ok(t) => t,
                Err(Refused::TooLarge { limit }) => format!("<too large {limit}>"),
                Err(Refused::NotUtf8) => "<not utf-8>".to_owned(),
            };
            out.push((d.line.unwrap(), t));
        }
        out
    }

    #[test]
    fn lines_are_numbered_skipping_blanks_and_bounded() {
        assert_eq!(
            lines("{\"a\":1}\n\n  \n{\"b\":2}\r\n0123456789\nend", 8),
            vec![
                (1, "{\"a\":1}".to_owned()),
                (4, "{\"b\":2}".to_owned()),
                (5, "<too large 8>".to_owned()),
                (6, "end".to_owned()),
            ]
        );
    }

    #[test]
    fn one_bad_byte_costs_one_line() {
        assert_eq!(
            lines(b"a\n\xff b\nc\n", 8),
            vec![
                (1, "a".to_owned()),
                (2, "<not utf-8>".to_owned()),
                (3, "c".to_owned()),
            ]
        );
    }

    #[test]
    fn an_over_long_line_is_skipped_but_not_forever() {
        // Over the limit, but it ends within MAX_SKIP: one refused line.
        let mut input = vec![b'x'; 100_000];
        input.extend_from_slice(b"\nnext\n");
        let mut r = BufReader::new(&input[..]);
        let mut n = 0;
        let first = next_line(&mut r, 16, &mut n).unwrap().unwrap();
        assert!(matches!(first.text, Err(Refused::TooLarge { limit: 16 })));
        assert_eq!(
            next_line(&mut r, 16, &mut n)
                .unwrap()
                .unwrap()
                .text
                .ok()
                .unwrap(),
            "next"
        );
        // /dev/zero: no end at all; given up after MAX_SKIP, with the line number.
        let mut r = BufReader::new(io::repeat(0));
        let mut n = 0;
        let e = next_line(&mut r, 16, &mut n).err().unwrap();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert!(
            e.to_string()
                .starts_with("line 1 is over 16 bytes and has no end"),
            "{e}"
        );
    }

    /// Counts flushes.
    #[derive(Default)]
    struct Flushes(Vec<u8>, usize);

    impl Write for Flushes {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.0.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            self.1 += 1;
            Ok(())
        }
    }

    #[test]
    fn live_output_is_flushed_only_before_a_read_that_may_wait() {
        let mut live = Live::new(Box::new(&b"a\nb\n"[..]), Flushes::default());
        let mut n = 0;
        // The first read finds nothing buffered: a flush (of nothing) first.
        next_line(&mut live, 8, &mut n).unwrap().unwrap();
        assert_eq!(live.out().1, 1);
        writeln!(live.out(), "A").unwrap();
        // "b" is already buffered: no flush.
        next_line(&mut live, 8, &mut n).unwrap().unwrap();
        assert_eq!(live.out().1, 1);
        writeln!(live.out(), "B").unwrap();
        // The next read may wait: both results go out before it.
        assert!(next_line(&mut live, 8, &mut n).unwrap().is_none());
        assert_eq!(live.out().1, 2);
        assert_eq!(live.out().0, b"A\nB\n");
    }

    #[test]
    fn whole_input_is_bounded() {
        let mut r: &[u8] = b"0123456789";
        assert!(matches!(
            whole(&mut r, 9).unwrap().text,
            Err(Refused::TooLarge { limit: 9 })
        ));
        let mut r: &[u8] = b"0123456789";
        assert_eq!(whole(&mut r, 10).unwrap().text.ok().unwrap(), "0123456789");
        let mut r: &[u8] = b"\xff\xfe";
        assert!(matches!(
            whole(&mut r, 10).unwrap().text,
            Err(Refused::NotUtf8)
        ));
    }
}
