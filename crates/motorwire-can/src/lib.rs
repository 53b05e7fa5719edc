#![doc = include_str!("../README.md")]
// The README links `socketcan::SocketCanBus`; without the feature (or off
// Linux) that module does not exist, so the link points at docs.rs instead.
// The HTML comment starts a block of its own: a link definition cannot
// interrupt the README's last paragraph, and rustdoc trims the leading
// newlines of a doc fragment.
#![cfg_attr(
    all(feature = "socketcan", target_os = "linux"),
    doc = "<!-- link definitions -->\n\n[`socketcan::SocketCanBus`]: crate::socketcan::SocketCanBus"
)]
#![cfg_attr(
    not(all(feature = "socketcan", target_os = "linux")),
    doc = "<!-- link definitions -->\n\n[`socketcan::SocketCanBus`]: https://docs.rs/motorwire-can/latest/motorwire_can/socketcan/struct.SocketCanBus.html"
)]
#![cfg_attr(docsrs, feature(doc_cfg))]

mod bus;
pub mod candump;
pub mod client;
mod error;
#[cfg(feature = "fdcanusb")]
#[cfg_attr(docsrs, doc(cfg(feature = "fdcanusb")))]
pub mod fdcanusb;
mod frame;
pub mod isotp;
pub mod retry;
pub mod segmented;
mod sim;
#[cfg(all(feature = "socketcan", target_os = "linux"))]
#[cfg_attr(docsrs, doc(cfg(all(feature = "socketcan", target_os = "linux"))))]
pub mod socketcan;

pub use bus::{AsyncCanBus, CanBus, FrameWaker, Received};
pub use error::Error;
pub use frame::{CLASSIC_MAX_LEN, CanId, FD_LENGTHS, FD_MAX_LEN, Frame, fd_len};
pub use sim::{Clock, FaultStats, Faults, SimBus, SimConfig, SimPort};
