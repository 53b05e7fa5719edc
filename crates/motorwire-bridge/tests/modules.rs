//! The crate's modules import each other in layers, never around a circle.
//!
//! Every path a module names (`use crate::a::b`, `crate::a::B` in its code,
//! `super::x` from below) is read from the sources, test modules left out.
//! An import from `p` to `q` is an edge between the two children of their
//! deepest common module that lead to each (`engine::admit` naming
//! `device::irpc::X` is an edge `engine -> device` among the crate's
//! modules); a module naming its own parent or child is no edge (that is
//! how a module and its parts are one thing). Among the children of each
//! module the edges must have no circle, and nothing inside the crate
//! names an item through the crate root's re-exports (`crate::Bridge`),
//! which would hide where it lives.

#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every source file of the crate: its path under `src/`
/// (`device/irpc.rs`) and its text.
fn sources() -> Vec<(String, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out = Vec::new();
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path: PathBuf = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if path.extension().and_then(|e| e.to_str()) != Some("rs") {
                continue;
            }
            let rel: Vec<String> = path
                .strip_prefix(&root)
                .unwrap()
                .iter()
                .map(|s| s.to_string_lossy().into_owned())
                .collect();
            out.push((rel.join("/"), std::fs::read_to_string(&path).unwrap()));
        }
    }
    out.sort();
    out
}

/// A module's path (`["device", "irpc"]`) and its source, test modules cut.
fn modules() -> Vec<(Vec<String>, String)> {
    let mut out: Vec<(Vec<String>, String)> = sources()
        .into_iter()
        .map(|(file, text)| {
            let mut module: Vec<String> = file
                .trim_end_matches(".rs")
                .split('/')
                .map(str::to_owned)
                .collect();
            if module.last().is_some_and(|s| s == "mod" || s == "lib") {
                module.pop();
            }
            (module, code_of(&text))
        })
        .collect();
    out.sort();
    out
}

/// The code of a source: comments and test modules left out.
fn code_of(text: &str) -> String {
    let mut code = String::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let t = line.trim_start();
        if t.starts_with("#[cfg(test)]")
            && lines
                .peek()
                .is_some_and(|n| n.trim_start().starts_with("mod "))
        {
            // A test module: skipped to the line at its indentation that
            // closes it (a test-only item elsewhere is read as code).
            let indent = line.len() - t.len();
            let Some(next) = lines.next() else { break };
            if next.trim_end().ends_with(';') {
                continue;
            }
            for l in lines.by_ref() {
                let lt = l.trim_start();
                if l.len() - lt.len() == indent && lt.starts_with('}') {
                    break;
                }
            }
            continue;
        }
        if t.starts_with("//") {
            continue;
        }
        let t = match t.find("//") {
            Some(i) if !t[..i].contains('"') => &t[..i],
            _ => t,
        };
        code.push_str(t);
        code.push('\n');
    }
    code
}

/// Every module path `module`'s code names: each `crate::` and `super::`
/// path, with its `{...}` groups expanded to their first segment.
fn named(module: &[String], code: &str, top: &BTreeSet<String>) -> Vec<(Vec<String>, String)> {
    let mut out = Vec::new();
    let b = code.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if !code.is_char_boundary(i) {
            i += 1;
            continue;
        }
        let rest = &code[i..];
        let (base, skip): (Vec<String>, usize) = if rest.starts_with("crate::")
            && (i == 0
                || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_' || b[i - 1] == b':'))
        {
            (Vec::new(), "crate::".len())
        } else if rest.starts_with("super::")
            && (i == 0
                || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_' || b[i - 1] == b':'))
        {
            let mut base = module.to_vec();
            let mut skip = 0;
            while code[i + skip..].starts_with("super::") {
                base.pop();
                skip += "super::".len();
            }
            (base, skip)
        } else {
            i += 1;
            continue;
        };
        i += skip;
        // The segments that follow, and a group's members.
        let mut path = base.clone();
        loop {
            let r = &code[i..];
            if r.starts_with('{') {
                let mut depth = 0;
                let mut end = i;
                for (k, c) in code[i..].char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                end = i + k;
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                for member in split_top(&code[i + 1..end]) {
                    let head: String = member
                        .trim()
                        .chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == ':')
                        .collect();
                    let segs: Vec<&str> = head
                        .split("::")
                        .filter(|s| !s.is_empty() && *s != "self")
                        .collect();
                    if !segs.is_empty() {
                        let mut p = path.clone();
                        p.extend(segs.iter().map(|s| s.to_string()));
                        out.push((p, member.trim().to_string()));
                    }
                }
                i = end + 1;
                break;
            }
            let seg: String = r
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if seg.is_empty() {
                break;
            }
            i += seg.len();
            path.push(seg);
            if code[i..].starts_with("::") {
                i += 2;
            } else {
                break;
            }
        }
        if path.len() > base.len() && !code[..i].ends_with('}') {
            let shown = path[base.len()..].join("::");
            out.push((path, shown));
        }
        let _ = top;
    }
    out
}

fn split_top(s: &str) -> Vec<&str> {
    let mut parts = Vec::new();
    let mut depth = 0;
    let mut start = 0;
    for (k, c) in s.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&s[start..k]);
                start = k + 1;
            }
            _ => {}
        }
    }
    parts.push(&s[start..]);
    parts
}

/// The edges among the children of each module: parent -> {(from, to)}.
type Edges = BTreeMap<Vec<String>, BTreeSet<(String, String)>>;

fn edges() -> (Edges, Vec<String>) {
    let mods = modules();
    let known: BTreeSet<Vec<String>> = mods.iter().map(|(m, _)| m.clone()).collect();
    let top: BTreeSet<String> = known
        .iter()
        .filter(|m| m.len() == 1)
        .map(|m| m[0].clone())
        .collect();
    let mut edges = Edges::new();
    let mut through_root = Vec::new();
    for (module, code) in &mods {
        if module.is_empty() {
            continue;
        }
        for (path, shown) in named(module, code, &top) {
            // The module the path names: its longest prefix that is one.
            let Some(target) = (1..=path.len())
                .rev()
                .map(|n| path[..n].to_vec())
                .find(|p| known.contains(p))
            else {
                if path.len() == 1 || !top.contains(&path[0]) {
                    through_root.push(format!("{} names crate::{shown}", module.join("::")));
                }
                continue;
            };
            let common = module
                .iter()
                .zip(&target)
                .take_while(|(a, b)| a == b)
                .count();
            if common == module.len() || common == target.len() {
                continue; // itself, an ancestor or a descendant
            }
            edges
                .entry(module[..common].to_vec())
                .or_default()
                .insert((module[common].clone(), target[common].clone()));
        }
    }
    (edges, through_root)
}

/// A circle among `edges`, if there is one.
fn circle(edges: &BTreeSet<(String, String)>) -> Option<Vec<String>> {
    let mut next: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for (a, b) in edges {
        next.entry(a).or_default().push(b);
    }
    fn visit<'a>(
        n: &'a str,
        next: &BTreeMap<&'a str, Vec<&'a str>>,
        on: &mut Vec<&'a str>,
        done: &mut BTreeSet<&'a str>,
    ) -> Option<Vec<String>> {
        if let Some(k) = on.iter().position(|m| *m == n) {
            let mut c: Vec<String> = on[k..].iter().map(|s| s.to_string()).collect();
            c.push(n.to_string());
            return Some(c);
        }
        if !done.insert(n) {
            return None;
        }
        on.push(n);
        for m in next.get(n).into_iter().flatten() {
            if let Some(c) = visit(m, next, on, done) {
                return Some(c);
            }
        }
        on.pop();
        None
    }
    let mut done = BTreeSet::new();
    for n in next.keys() {
        if let Some(c) = visit(n, &next, &mut Vec::new(), &mut done) {
            return Some(c);
        }
    }
    None
}

#[test]
fn no_module_imports_around_a_circle() {
    let (edges, through_root) = edges();
    if std::env::var_os("MOTORWIRE_SHOW_MODULES").is_some() {
        for (parent, e) in &edges {
            for (a, b) in e {
                println!("{}: {a} -> {b}", parent.join("::"));
            }
        }
    }
    assert!(
        edges.contains_key(&Vec::new()),
        "the crate's modules import nothing of each other?"
    );
    let circles: Vec<String> = edges
        .iter()
        .filter_map(|(parent, e)| {
            circle(e).map(|c| {
                let at = if parent.is_empty() {
                    "crate".to_string()
                } else {
                    parent.join("::")
                };
                format!("in {at}: {}", c.join(" -> "))
            })
        })
        .collect();
    assert!(
        circles.is_empty(),
        "modules import around a circle:\n{}",
        circles.join("\n")
    );
    assert!(
        through_root.is_empty(),
        "items named through the crate root (name their module):\n{}",
        through_root.join("\n")
    );
}

#[test]
fn the_checker_finds_a_circle_and_a_root_import() {
    // The reader and the search, on made-up code: a test that could not fail
    // would prove nothing of the crate.
    let top: BTreeSet<String> = ["a", "b"].iter().map(|s| s.to_string()).collect();
    let named_a = named(
        &["a".into()],
        "use crate::{b::X, Bridge};\nfn f() { super::b::y(); }",
        &top,
    );
    let paths: Vec<String> = named_a.iter().map(|(p, _)| p.join("::")).collect();
    assert_eq!(paths, ["b::X", "Bridge", "b::y"]);
    let e: BTreeSet<(String, String)> = [("a", "b"), ("b", "c"), ("c", "a")]
        .iter()
        .map(|(x, y)| (x.to_string(), y.to_string()))
        .collect();
    assert_eq!(circle(&e).unwrap(), ["a", "b", "c", "a"]);
    let e: BTreeSet<(String, String)> = [("a", "b"), ("b", "c"), ("a", "c")]
        .iter()
        .map(|(x, y)| (x.to_string(), y.to_string()))
        .collect();
    assert_eq!(circle(&e), None);
    assert_eq!(
        code_of("a\n#[cfg(test)]\nmod tests {\n    use super::*;\n}\nb\n"),
        "a\nb\n"
    );
}

/// Refusals are typed: a line's error is made from a `Refusal` in one
/// place (`output::refusal`), and no function says its error as a bare
/// `String`.
#[test]
fn every_error_is_typed_and_made_in_one_place() {
    let mut found = Vec::new();
    for (module, code) in modules() {
        let name = module.join("::");
        for (n, line) in code.lines().enumerate() {
            let made = ["ErrorBody::new(", "ErrorBody::refused(", "ErrorBody::gate("]
                .iter()
                .any(|c| line.contains(c));
            if made && name != "output::refusal" {
                found.push(format!("{name}: {line}"));
            }
            if let Some(at) = line.find("Result<") {
                let rest = &line[at..];
                let head = rest.split(['{', ';', '=']).next().unwrap_or(rest);
                if head.replace(' ', "").contains(",String>") {
                    found.push(format!("{name} (line {} of its code): {line}", n + 1));
                }
            }
        }
    }
    assert!(found.is_empty(), "untyped errors:\n{}", found.join("\n"));
}

/// The integration tests share one harness (`tests/common/`): no helper
/// is written in two test files.
#[test]
fn no_test_helper_is_written_twice() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let mut helpers: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("rs") {
            continue;
        }
        let file = path.file_name().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&path).unwrap();
        let mut attrs: Vec<&str> = Vec::new();
        for line in text.lines() {
            if line.starts_with("#[") {
                attrs.push(line);
                continue;
            }
            if line.starts_with("///") {
                continue;
            }
            if let Some(rest) = line.strip_prefix("fn ") {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !attrs.iter().any(|a| a.starts_with("#[test]")) {
                    helpers.entry(name).or_default().push(file.clone());
                }
            }
            attrs.clear();
        }
    }
    let twice: Vec<String> = helpers
        .iter()
        .filter(|(_, files)| files.len() > 1)
        .map(|(name, files)| format!("{name}: {}", files.join(", ")))
        .collect();
    assert!(
        twice.is_empty(),
        "helpers written twice (put them in tests/common/):\n{}",
        twice.join("\n")
    );
}

/// No file of the crate's sources is over 1,500 lines (its unit tests
/// counted), and the engine's dispatch, `engine/mod.rs`, is at most 1,200:
/// each concern is a file a reader takes in.
#[test]
fn every_source_file_is_a_size_a_reader_takes_in() {
    let mut over = Vec::new();
    let files = sources();
    for (rel, text) in &files {
        let lines = text.lines().count();
        let most = if rel == "engine/mod.rs" { 1_200 } else { 1_500 };
        if lines > most {
            over.push(format!("{rel}: {lines} lines (at most {most})"));
        }
    }
    assert!(files.len() > 30, "{} files", files.len());
    assert!(over.is_empty(), "{}", over.join("\n"));
}

/// The most lines a function takes, from its `fn` to its closing brace.
const MOST_LINES: usize = 80;

/// No function of the crate's sources (its unit tests counted) is over
/// [`MOST_LINES`] lines: each does one thing a reader takes in, a long one
/// split by what it does.
#[test]
fn no_function_is_over_eighty_lines() {
    let mut over = Vec::new();
    for (file, text) in sources() {
        for (line, name, lines) in functions(&text) {
            if lines > MOST_LINES {
                over.push(format!("{file}:{line} {name} ({lines} lines)"));
            }
        }
    }
    assert!(
        over.is_empty(),
        "functions over {MOST_LINES} lines (split each by what it does):\n{}",
        over.join("\n")
    );
}

/// The measure, on made-up code: a short and a long function, braces in
/// literals and comments, a function only declared.
#[test]
fn the_measure_counts_a_function_from_its_fn_to_its_closing_brace() {
    let source = r#"
    fn short() -> &'static str {
        "}" // }
    }

    // fn commented() {
    /// A long one.
    pub(crate) fn long<'a>(x: [u8; 2], s: &'a str) -> char {
        let open = '{';
        let quote = '\'';
        let raw = r"{{ fn not_one() {";
        /* } nested /* } */ } */
        if x[0] > 0 {
            return open;
        }
        s.chars().next().unwrap_or(quote)
    }

    trait T {
        fn declared(&self);
    }
"#;
    assert_eq!(
        functions(source),
        [(2, "short".to_owned(), 3), (8, "long".to_owned(), 10)]
    );
}

/// Every `fn` with a body in `text` (free, a method, nested; not one only
/// declared, its signature ending in `;`, nor one in a comment or a
/// literal): the line its `fn` is on, its name, and its lines from there
/// to its closing brace.
fn functions(text: &str) -> Vec<(usize, String, usize)> {
    let code = blank_comments_and_literals(text);
    let b = code.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let line_of = |at: usize| b[..at].iter().filter(|c| **c == b'\n').count() + 1;
    let mut out = Vec::new();
    for at in 0..b.len() {
        if !b[at..].starts_with(b"fn")
            || (at > 0 && ident(b[at - 1]))
            || !b.get(at + 2).is_some_and(u8::is_ascii_whitespace)
        {
            continue;
        }
        let name: String = code[at + 2..]
            .trim_start()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        if name.is_empty() {
            continue;
        }
        // Its body's opening brace: the first outside the signature's
        // brackets (`[u8; 4]`), unless a `;` ends it first.
        let mut depth = 0;
        let mut open = None;
        for (k, c) in b.iter().enumerate().skip(at) {
            match c {
                b'(' | b'[' => depth += 1,
                b')' | b']' => depth -= 1,
                b'{' if depth == 0 => {
                    open = Some(k);
                    break;
                }
                b';' if depth == 0 => break,
                _ => {}
            }
        }
        let Some(open) = open else { continue };
        let mut level = 0;
        let close = (open..b.len()).find(|&k| {
            match b[k] {
                b'{' => level += 1,
                b'}' => level -= 1,
                _ => {}
            }
            level == 0
        });
        if let Some(close) = close {
            out.push((line_of(at), name, line_of(close) - line_of(at) + 1));
        }
    }
    out
}

/// `text` with its comments and the insides of its string and char
/// literals blanked, newlines kept (each line keeps its number): its code.
fn blank_comments_and_literals(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match not_code_from(text, i) {
            Some(end) => {
                out.extend(b[i..end].iter().map(|&c| if c == b'\n' { c } else { b' ' }));
                i = end;
            }
            None => {
                out.push(b[i]);
                i += 1;
            }
        }
    }
    String::from_utf8(out).unwrap()
}

/// Where the comment or literal that starts at byte `i` of `text` ends
/// (`None`: none starts there; a lifetime is code).
fn not_code_from(text: &str, i: usize) -> Option<usize> {
    let b = text.as_bytes();
    let rest = &b[i..];
    // Where `what` is next found from `from` (the end: nowhere).
    let find = |from: usize, what: &[u8]| {
        (from..b.len())
            .find(|&k| b[k..].starts_with(what))
            .unwrap_or(b.len())
    };
    if rest.starts_with(b"//") {
        return Some(find(i, b"\n"));
    }
    if rest.starts_with(b"/*") {
        let mut depth = 0;
        let mut k = i;
        while k < b.len() {
            if b[k..].starts_with(b"/*") {
                depth += 1;
                k += 2;
            } else if b[k..].starts_with(b"*/") {
                depth -= 1;
                k += 2;
                if depth == 0 {
                    return Some(k);
                }
            } else {
                k += 1;
            }
        }
        return Some(b.len());
    }
    let starts_word = i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_');
    // A raw string, `r"..."`, `r#"..."#`, `br"..."`: no escapes in it.
    let raw = rest.strip_prefix(b"br").or(rest.strip_prefix(b"r"));
    if let Some(after_r) = raw.filter(|_| starts_word) {
        let hashes = after_r.iter().take_while(|c| **c == b'#').count();
        if after_r.get(hashes) == Some(&b'"') {
            let close = [b"\"".as_slice(), &after_r[..hashes]].concat();
            let from = i + (rest.len() - after_r.len()) + hashes + 1;
            return Some((find(from, &close) + close.len()).min(b.len()));
        }
    }
    if rest.starts_with(b"\"") {
        let mut k = i + 1;
        while k < b.len() && b[k] != b'"' {
            k += if b[k] == b'\\' { 2 } else { 1 };
        }
        return Some((k + 1).min(b.len()));
    }
    if rest.starts_with(b"'") {
        // A char literal (`'{'`, `'\''`, `'\u{7b}'`), not a lifetime
        // (`'a`, `'static`).
        if rest.get(1) == Some(&b'\\') {
            return Some((find(i + 3, b"'") + 1).min(b.len()));
        }
        let c = text[i + 1..].chars().next()?;
        if b.get(i + 1 + c.len_utf8()) == Some(&b'\'') {
            return Some(i + 2 + c.len_utf8());
        }
    }
    None
}
