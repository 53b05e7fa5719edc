//! Reading input lines: bounded, and an unreadable line that names a stop
//! is said to.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use std::io::{BufReader, Read};

use motorwire_bridge::{DEFAULT_MAX_LINE, ReadLine, UNREADABLE_HEAD, read_line};

/// The bound these tests read with (a runner's is its `max_line`).
const MAX_LINE: usize = 64 * 1024;

fn read_all(bytes: &[u8], capacity: usize) -> Vec<ReadLine> {
    let mut r = BufReader::with_capacity(capacity, bytes);
    let mut out = Vec::new();
    loop {
        let l = read_line(&mut r, MAX_LINE).unwrap();
        if l == ReadLine::End {
            return out;
        }
        out.push(l);
    }
}

/// A too-long `line` (without its newline) as it is read: whether it
/// names a stop, its first bytes, its length.
fn too_long(names_stop: bool, line: &[u8]) -> ReadLine {
    ReadLine::TooLong {
        names_stop,
        head: line[..UNREADABLE_HEAD.min(line.len())].to_vec(),
        length: line.len() as u64,
    }
}

fn not_utf8(names_stop: bool, line: &[u8]) -> ReadLine {
    ReadLine::NotUtf8 {
        names_stop,
        head: line.to_vec(),
        length: line.len() as u64,
    }
}

#[test]
fn lines_too_long_and_not_utf8_say_whether_they_name_a_stop() {
    // The name at every place relative to the 64 KiB bound, read in
    // chunks of every size that splits it.
    for at in [
        0,
        100,
        MAX_LINE - 20,
        MAX_LINE - 7,
        MAX_LINE,
        MAX_LINE + 3000,
    ] {
        let mut line = vec![b'x'; MAX_LINE + 5000];
        line.splice(at..at + 14, *b"emergency_stop");
        let unread = line.clone();
        line.push(b'\n');
        line.extend_from_slice(b"{\"a\":1}\n");
        for capacity in [1, 5, 7, 13, 14, 8192] {
            assert_eq!(
                read_all(&line, capacity),
                [too_long(true, &unread), ReadLine::Line("{\"a\":1}".into())],
                "at {at}, capacity {capacity}"
            );
        }
    }
    let mut plain = vec![b'x'; MAX_LINE + 1];
    plain.extend_from_slice(b"emergency_sto");
    let unread = plain.clone();
    plain.extend_from_slice(b"\npy\n");
    assert_eq!(
        read_all(&plain, 7),
        [too_long(false, &unread), ReadLine::Line("py".into())]
    );
    // Exactly MAX_LINE bytes is a line.
    let max = vec![b'y'; MAX_LINE];
    assert_eq!(
        read_all(&[&max[..], b"\n"].concat(), 8192),
        [ReadLine::Line(String::from_utf8(max).unwrap())]
    );
    assert_eq!(
        read_all(
            b"{\"emergency_stop\":\xff}\n\xfe\r\n{\"emergency\\u005fstop\": 1, \"x\": \"\xff\"}\n",
            8192
        ),
        [
            not_utf8(true, b"{\"emergency_stop\":\xff}"),
            not_utf8(false, b"\xfe\r"),
            not_utf8(true, b"{\"emergency\\u005fstop\": 1, \"x\": \"\xff\"}")
        ]
    );
    // Too long with a `\u` escape: it may spell the name.
    let mut escaped = vec![b'x'; MAX_LINE + 10];
    escaped.extend_from_slice(b"\\u0065");
    let unread = escaped.clone();
    escaped.push(b'\n');
    assert_eq!(read_all(&escaped, 7), [too_long(true, &unread)]);
    // Without its newline at the end: too long all the same, and nothing
    // over the bound is held.
    let mut endless = std::io::repeat(b'z').take(10 * MAX_LINE as u64);
    let mut r = BufReader::new(&mut endless);
    assert_eq!(
        read_line(&mut r, MAX_LINE).unwrap(),
        too_long(false, &vec![b'z'; 10 * MAX_LINE])
    );
}

#[test]
fn an_endless_line_gives_the_input_up() {
    let mut endless = std::io::repeat(b'z');
    let mut r = BufReader::new(&mut endless);
    let e = read_line(&mut r, DEFAULT_MAX_LINE).unwrap_err();
    assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
    assert_eq!(
        e.to_string(),
        "a line over 1048576 bytes has no end within 16 MiB more; the input was given up"
    );
}
