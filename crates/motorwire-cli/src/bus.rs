//! `--bus` specifications.

#[cfg(target_os = "linux")]
pub(crate) type Bus = motorwire_can::socketcan::SocketCanBus;

/// Opens `socketcan:IFACE`.
#[cfg(target_os = "linux")]
pub(crate) fn open(spec: &str) -> Result<Bus, String> {
    match spec.split_once(':') {
        Some(("socketcan", iface)) if !iface.is_empty() => {
            Bus::open(iface).map_err(|e| e.to_string())
        }
        _ => Err(format!(
            "--bus {spec:?}: expected socketcan:IFACE (for example socketcan:vcan0)"
        )),
    }
}

/// SocketCAN exists only on Linux.
#[cfg(not(target_os = "linux"))]
pub(crate) fn open(spec: &str) -> Result<motorwire_can::SimPort, String> {
    Err(format!("--bus {spec:?}: SocketCAN needs Linux"))
}
