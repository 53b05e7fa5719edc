//! Reading documents from files and stdin, never holding more than the
//! configured maximum document size (plus one byte) of any one document.

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read};

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
pub(crate) fn next_line(
    reader: &mut dyn BufRead,
    limit: usize,
    line_no: &mut usize,
) -> io::Result<Option<Document>> {
    loop {
        let mut bytes = Vec::new();
        let mut too_large = false;
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
                    if !too_large {
                        if bytes.len() + chunk.len() > limit {
                            too_large = true;
                            bytes.clear();
                        } else {
                            bytes.extend_from_slice(chunk);
                        }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(input: &str, limit: usize) -> Vec<(usize, String)> {
        let mut r: &[u8] = input.as_bytes();
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
