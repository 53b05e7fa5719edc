//! `BusMap::from_path`: a map read from a file, and each way reading one
//! fails. Self-contained (temporary files), so it ships with the package.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;

use motorwire_irpc::WireVersion;
use motorwire_translate::{BusMap, MapError, Target};

/// A file of the test's own in the temporary directory, removed on drop.
struct TempFile(PathBuf);

impl TempFile {
    fn new(name: &str, contents: &[u8]) -> TempFile {
        let path = std::env::temp_dir().join(format!(
            "motorwire-map-file-{}-{name}.toml",
            std::process::id()
        ));
        std::fs::write(&path, contents).unwrap();
        TempFile(path)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

#[test]
fn a_map_file_reads_as_from_toml_reads_its_text() {
    let text = "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\nwire = \"v2.1\"\n";
    let file = TempFile::new("ok", text.as_bytes());
    let map = BusMap::from_path(&file.0).unwrap();
    assert_eq!(map, BusMap::from_toml(text).unwrap());
    assert_eq!(
        map.motor("elbow").map(|m| m.target),
        Some(Target::Irpc {
            node: 0x12,
            wire: WireVersion::V2_1
        })
    );
}

#[test]
fn a_missing_file_is_a_read_error_naming_it() {
    let err = BusMap::from_path("no/such/dir/map.toml").unwrap_err();
    let MapError::Read { path, kind, .. } = &err else {
        panic!("{err:?}");
    };
    assert_eq!(
        (path.as_str(), *kind),
        ("no/such/dir/map.toml", std::io::ErrorKind::NotFound)
    );
    assert!(
        err.to_string()
            .starts_with("bus map no/such/dir/map.toml: No such file or directory"),
        "{err}"
    );
}

#[test]
fn a_file_over_one_mib_is_refused_after_reading_one_byte_more() {
    let mut big = b"# padding\n".repeat(104_858);
    big.truncate(1_048_577);
    let file = TempFile::new("big", &big);
    let err = BusMap::from_path(&file.0).unwrap_err();
    assert_eq!(
        err,
        MapError::TooLarge {
            path: file.0.display().to_string(),
            limit: 1_048_576
        }
    );
}

#[cfg(unix)]
#[test]
fn dev_zero_ends_at_the_limit() {
    assert_eq!(
        BusMap::from_path("/dev/zero").unwrap_err(),
        MapError::TooLarge {
            path: "/dev/zero".to_owned(),
            limit: 1_048_576
        }
    );
}

#[test]
fn a_file_that_is_not_utf8_names_the_byte() {
    let file = TempFile::new("latin1", b"# caf\xe9\n");
    assert_eq!(
        BusMap::from_path(&file.0).unwrap_err(),
        MapError::NotUtf8 {
            path: file.0.display().to_string(),
            offset: 5
        }
    );
}

#[test]
fn a_file_with_a_bad_map_is_the_map_error() {
    let file = TempFile::new("bad", b"[motors.elbow]\ndialect = \"irpc\"\n");
    assert_eq!(
        BusMap::from_path(&file.0).unwrap_err().to_string(),
        "bus map: motors.elbow speaks irpc and needs node"
    );
}
