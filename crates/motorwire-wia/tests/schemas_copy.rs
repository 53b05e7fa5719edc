//! The crate's `schemas/` is a copy of the workspace's `schemas/` (the single
//! source of truth), kept inside the crate so the published package carries
//! the files `MessageKind::schema` embeds. This test keeps the two identical,
//! byte for byte; in a packaged crate (no workspace around it) it says so and
//! skips.
#![allow(clippy::unwrap_used, clippy::panic)]

use std::path::{Path, PathBuf};

fn json_files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".json"))
        .collect();
    names.sort();
    names
}

#[test]
fn crate_schemas_are_identical_to_the_workspace_schemas() {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let root = here.join("../../schemas");
    if !root.is_dir() {
        eprintln!(
            "skipped: {} does not exist (a packaged crate, outside the workspace)",
            root.display()
        );
        return;
    }
    let copy = here.join("schemas");
    let names = json_files(&root);
    assert_eq!(
        names,
        json_files(&copy),
        "copy the workspace's schemas/ into crates/motorwire-wia/schemas/"
    );
    for name in &names {
        let a = std::fs::read(root.join(name)).unwrap();
        let b = std::fs::read(copy.join(name)).unwrap();
        if a != b {
            panic!("schemas/{name} differs from crates/motorwire-wia/schemas/{name}: copy it over");
        }
    }
}
