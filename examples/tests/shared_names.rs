//! The root README's table of names two crates share is the crates' own:
//! every public type name (`pub struct`, `enum`, `type`, `trait` opening a
//! line) declared in more than one crate under `crates/` is a
//! row of the table, and every row's name is declared in two crates.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn the_readme_names_every_type_name_two_crates_share() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut crates_by_name: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for krate in std::fs::read_dir(root.join("crates")).unwrap() {
        let krate = krate.unwrap().path();
        let name = krate.file_name().unwrap().to_string_lossy().into_owned();
        let mut files = Vec::new();
        sources(&krate.join("src"), &mut files);
        for file in files {
            for line in std::fs::read_to_string(&file).unwrap().lines() {
                // Declarations inside a macro's body are indented.
                let line = line.trim_start();
                for kind in ["pub struct ", "pub enum ", "pub type ", "pub trait "] {
                    if let Some(rest) = line.strip_prefix(kind) {
                        let ident: String = rest
                            .chars()
                            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                            .collect();
                        if ident.starts_with(|c: char| c.is_ascii_uppercase()) {
                            crates_by_name
                                .entry(ident)
                                .or_default()
                                .insert(name.clone());
                        }
                    }
                }
            }
        }
    }
    let shared: BTreeSet<&String> = crates_by_name
        .iter()
        .filter(|(_, crates)| crates.len() > 1)
        .map(|(n, _)| n)
        .collect();
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let start = readme.find("**Names two crates share.**").unwrap();
    let table = &readme[start..start + readme[start..].find("\n\n`AngleUnit`").unwrap()];
    let rows: BTreeSet<String> = table
        .lines()
        .filter(|l| l.starts_with("| `"))
        .flat_map(|l| {
            let first = l.split(" | ").next().unwrap();
            first
                .split('`')
                .skip(1)
                .step_by(2)
                .map(str::to_owned)
                .collect::<Vec<_>>()
        })
        .collect();
    for name in &shared {
        assert!(
            rows.contains(*name),
            "{name} is declared in {:?} and missing from the README's table of names two crates share",
            crates_by_name[*name]
        );
    }
    for row in &rows {
        assert!(
            shared.contains(row),
            "the README's table names {row}, which is declared in {:?} only",
            crates_by_name.get(row)
        );
    }
    // AngleUnit is declared once.
    assert_eq!(
        crates_by_name["AngleUnit"],
        BTreeSet::from(["motorwire-core".to_owned()])
    );
}
