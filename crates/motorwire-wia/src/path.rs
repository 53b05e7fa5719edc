//! JSON pointers built lazily: a violation's pointer is rendered only when a
//! violation is recorded, so checking a valid document allocates nothing.

use std::fmt::Write as _;

#[derive(Clone, Copy)]
enum Segment<'a> {
    Key(&'a str),
    Index(usize),
}

/// A location in a document, as a chain of segments on the stack.
#[derive(Clone, Copy)]
pub(crate) struct Path<'a> {
    parent: Option<&'a Path<'a>>,
    segment: Option<Segment<'a>>,
}

impl<'a> Path<'a> {
    pub(crate) const ROOT: Path<'static> = Path {
        parent: None,
        segment: None,
    };

    pub(crate) fn key(&'a self, key: &'a str) -> Path<'a> {
        Path {
            parent: Some(self),
            segment: Some(Segment::Key(key)),
        }
    }

    pub(crate) fn index(&'a self, index: usize) -> Path<'a> {
        Path {
            parent: Some(self),
            segment: Some(Segment::Index(index)),
        }
    }

    /// The RFC 6901 pointer (`~` as `~0`, `/` as `~1`).
    pub(crate) fn render(&self) -> String {
        let mut segments = Vec::new();
        let mut at = Some(self);
        while let Some(p) = at {
            if let Some(s) = p.segment {
                segments.push(s);
            }
            at = p.parent;
        }
        let mut out = String::new();
        for s in segments.iter().rev() {
            out.push('/');
            match s {
                Segment::Key(k) => {
                    for c in k.chars() {
                        match c {
                            '~' => out.push_str("~0"),
                            '/' => out.push_str("~1"),
                            c => out.push(c),
                        }
                    }
                }
                Segment::Index(i) => {
                    let _ = write!(out, "{i}");
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_rfc6901_pointers() {
        let root = Path::ROOT;
        assert_eq!(root.render(), "");
        let motors = root.key("motors");
        let first = motors.index(0);
        let kp = first.key("pid_gains");
        let kp = kp.key("kp");
        assert_eq!(kp.render(), "/motors/0/pid_gains/kp");
        let odd = root.key("a/b~c");
        assert_eq!(odd.render(), "/a~1b~0c");
    }
}
