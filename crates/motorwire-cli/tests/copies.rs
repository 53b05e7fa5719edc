//! Files kept as copies inside the crates so that each published package
//! carries what it needs, checked byte for byte against the workspace's
//! originals. In a packaged crate (no workspace around it) each check says so
//! and skips.
//!
//! - `motorwire demo` embeds the bus map and the multi-axis command from this
//!   crate's `demo/`: copies of `fixtures/maps/demo-arm.toml` and
//!   `fixtures/wia/valid/doc-3.2-multi-axis-command.json`.
//! - Every crate ships `LICENSE-MIT` and `LICENSE-APACHE`: copies of the
//!   workspace root's.
#![allow(clippy::unwrap_used, clippy::panic)]

use std::path::{Path, PathBuf};

fn here() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The workspace root, or `None` (with a message) in a packaged crate.
fn workspace() -> Option<PathBuf> {
    let root = here().join("../..");
    if root.join("fixtures").is_dir() && root.join("crates").is_dir() {
        Some(root)
    } else {
        eprintln!(
            "skipped: {} is not the motorwire workspace (a packaged crate)",
            root.display()
        );
        None
    }
}

fn assert_identical(copy: &Path, original: &Path) {
    let a = std::fs::read(copy).unwrap_or_else(|e| panic!("{}: {e}", copy.display()));
    let b = std::fs::read(original).unwrap();
    assert!(
        a == b,
        "{} differs from {}: copy it over",
        copy.display(),
        original.display()
    );
}

#[test]
fn demo_files_are_identical_to_the_workspace_fixtures() {
    let Some(root) = workspace() else { return };
    for (copy, original) in [
        ("demo/demo-arm.toml", "fixtures/maps/demo-arm.toml"),
        ("demo/so101.toml", "fixtures/maps/so101.toml"),
        (
            "demo/doc-3.2-multi-axis-command.json",
            "fixtures/wia/valid/doc-3.2-multi-axis-command.json",
        ),
    ] {
        assert_identical(&here().join(copy), &root.join(original));
    }
}

#[test]
fn every_crate_ships_the_workspace_license_files() {
    let Some(root) = workspace() else { return };
    let mut crates = 0;
    for entry in std::fs::read_dir(root.join("crates")).unwrap() {
        let dir = entry.unwrap().path();
        if !dir.join("Cargo.toml").is_file() {
            continue;
        }
        crates += 1;
        for license in ["LICENSE-MIT", "LICENSE-APACHE"] {
            assert_identical(&dir.join(license), &root.join(license));
        }
    }
    assert!(crates >= 11, "found {crates} crates under crates/");
}
