//! motorwire's examples: small programs to copy from, each run from the
//! workspace root with `cargo run --example NAME`.
//!
//! | example | what it shows |
//! |---|---|
//! | `validate_wia` | validate WIA messages, print every violation (rule, JSON pointer, message) |
//! | `irpc_frame` | encode an iRPC `SetTargetV2` with a real header into a CAN-FD frame, decode it back |
//! | `scurve` | plan a jerk-limited S-curve move and sample it |
//! | `translate_frames` | a bus map from a file, a WIA command through the safety gate into ready-to-send CAN-FD frames |
//! | `bridge_loop` | the sans-IO `Bridge` driven from your own loop, with a simulated joint on an in-memory bus |
//!
//! Beside them: `python/bridge_client.py` talks to a running
//! `motorwire bridge` over its local socket and over TCP with the Python
//! standard library only, and `no-std-joint/` is a joint's firmware loop
//! (no_std, no alloc) that builds for a Cortex-M4F.

/// The path of a file in the workspace's `fixtures/` (`rel` relative to
/// it), wherever the example is run from.
pub fn fixture(rel: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures")
        .join(rel)
}

/// The root README's Rust program, compiled and run as a doctest (`cargo
/// test -p motorwire-examples --doc`) exactly as it reads there (a whole
/// `fn main`, nothing hidden), so that it stays true and what a newcomer
/// pastes into a new project compiles.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct RootReadme;
