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

/// A module's path (`["device", "irpc"]`) and its source, test modules cut.
fn modules() -> Vec<(Vec<String>, String)> {
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
            let rel = path.strip_prefix(&root).unwrap().with_extension("");
            let mut module: Vec<String> = rel
                .iter()
                .map(|s| s.to_string_lossy().into_owned())
                .collect();
            if module.last().is_some_and(|s| s == "mod" || s == "lib") {
                module.pop();
            }
            let text = std::fs::read_to_string(&path).unwrap();
            out.push((module, code_of(&text)));
        }
    }
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
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut stack = vec![root.clone()];
    let mut over = Vec::new();
    let mut files = 0;
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            files += 1;
            let lines = std::fs::read_to_string(&path).unwrap().lines().count();
            let rel = path
                .strip_prefix(&root)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            let most = if rel == "engine/mod.rs" { 1_200 } else { 1_500 };
            if lines > most {
                over.push(format!("{rel}: {lines} lines (at most {most})"));
            }
        }
    }
    assert!(files > 30, "{files} files");
    assert!(over.is_empty(), "{}", over.join("\n"));
}
