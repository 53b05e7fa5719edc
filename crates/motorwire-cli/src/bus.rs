//! `--bus` specifications: `socketcan:IFACE` (Linux SocketCAN) and
//! `fdcanusb:PATH` (mjbots' fdcanusb adapter, or a moteus UART, on a
//! serial port).

use std::io::{Read, Write};
use std::time::Duration;

use motorwire_can::fdcanusb::FdcanusbBus;
use motorwire_can::{CanBus, Error, Frame, Received};

/// How long a read of an fdcanusb's serial port waits before it gives the
/// reader's loop its turn (the bridge's reader polls every 20 ms).
const SERIAL_READ_TIMEOUT: Duration = Duration::from_millis(20);

/// The reading and the writing half of a serial port.
type Halves = (Box<dyn Read + Send>, Box<dyn Write + Send>);

/// A bus a `--bus` names.
pub(crate) enum Bus {
    #[cfg(target_os = "linux")]
    SocketCan(motorwire_can::socketcan::SocketCanBus),
    Fdcanusb(FdcanusbBus<Box<dyn Read + Send>, Box<dyn Write + Send>>),
    /// No CAN bus (`--bus none`): a map of serial servos alone. Nothing is
    /// ever heard; a frame to send is refused.
    None,
}

impl CanBus for Bus {
    fn send(&mut self, frame: &Frame) -> Result<(), Error> {
        match self {
            #[cfg(target_os = "linux")]
            Self::SocketCan(b) => b.send(frame),
            Self::Fdcanusb(b) => b.send(frame),
            Self::None => Err(Error::Io {
                op: "--bus none",
                kind: std::io::ErrorKind::Unsupported,
                message: "there is no CAN bus to send on".to_owned(),
            }),
        }
    }

    fn recv(&mut self, timeout: Duration) -> Result<Received, Error> {
        match self {
            #[cfg(target_os = "linux")]
            Self::SocketCan(b) => b.recv(timeout),
            Self::Fdcanusb(b) => b.recv(timeout),
            Self::None => {
                std::thread::sleep(timeout);
                Err(Error::Timeout(timeout))
            }
        }
    }
}

fn usage(spec: &str) -> String {
    format!(
        "--bus {spec:?}: expected socketcan:IFACE (for example socketcan:vcan0), fdcanusb:PATH (for example fdcanusb:/dev/ttyACM0), sim, or none (serial servos alone)"
    )
}

/// The serial port of an fdcanusb and a second handle to it (one to read,
/// one to write).
fn serial(path: &str) -> Result<Halves, String> {
    // The adapter is a USB CDC device: the baud rate is not on any wire.
    let port = serialport::new(path, 115_200)
        .timeout(SERIAL_READ_TIMEOUT)
        .open()
        .map_err(|e| format!("--bus fdcanusb:{path}: {e}"))?;
    let writer = port
        .try_clone()
        .map_err(|e| format!("--bus fdcanusb:{path}: {e}"))?;
    Ok((Box::new(port), Box::new(writer)))
}

/// Opens one bus for sending and receiving.
pub(crate) fn open(spec: &str) -> Result<Bus, String> {
    match spec.split_once(':') {
        #[cfg(target_os = "linux")]
        Some(("socketcan", iface)) if !iface.is_empty() => {
            motorwire_can::socketcan::SocketCanBus::open(iface)
                .map(Bus::SocketCan)
                .map_err(|e| e.to_string())
        }
        #[cfg(not(target_os = "linux"))]
        Some(("socketcan", _)) => Err(format!("--bus {spec:?}: SocketCAN needs Linux")),
        Some(("fdcanusb", path)) if !path.is_empty() => {
            let (reader, writer) = serial(path)?;
            Ok(Bus::Fdcanusb(FdcanusbBus::new(reader, writer)))
        }
        None if spec == "none" => Ok(Bus::None),
        _ => Err(usage(spec)),
    }
}

/// Opens a bus as two: one that sends, one that receives (the bridge's
/// halves). A SocketCAN interface is opened twice; an fdcanusb's serial
/// port once, its reading and its writing shared out.
pub(crate) fn open_pair(spec: &str) -> Result<(Bus, Bus), String> {
    match spec.split_once(':') {
        Some(("fdcanusb", path)) if !path.is_empty() => {
            let (reader, writer) = serial(path)?;
            let tx = FdcanusbBus::new(Box::new(std::io::empty()) as Box<dyn Read + Send>, writer);
            let rx = FdcanusbBus::new(reader, Box::new(std::io::sink()) as Box<dyn Write + Send>);
            Ok((Bus::Fdcanusb(tx), Bus::Fdcanusb(rx)))
        }
        _ => Ok((open(spec)?, open(spec)?)),
    }
}

/// How long a read of a servo port waits before its reader's loop tries
/// again.
const SERVO_READ_TIMEOUT: Duration = Duration::from_millis(50);

/// Each of `map`'s serial servo ports opened at its baud rate (8N1, no
/// flow control), in the map's order.
pub(crate) fn servo_links(
    map: &motorwire_translate::BusMap,
) -> Result<Vec<motorwire_bridge::ServoLink>, String> {
    map.servo_ports()
        .iter()
        .map(|p| {
            let (reader, writer) = open_servo_port(&p.path, p.baud)
                .map_err(|e| format!("servo port {} at {} baud: {e}", p.path, p.baud))?;
            let (path, baud) = (p.path.clone(), p.baud);
            Ok(motorwire_bridge::ServoLink {
                reader,
                writer,
                reopen: Some(Box::new(move || open_servo_port(&path, baud))),
            })
        })
        .collect()
}

/// A servo port opened at `baud`: its reader and its writer.
fn open_servo_port(path: &str, baud: u32) -> std::io::Result<Halves> {
    let port = serialport::new(path, baud)
        .timeout(SERVO_READ_TIMEOUT)
        .open()
        .map_err(std::io::Error::from)?;
    let writer = port.try_clone().map_err(std::io::Error::from)?;
    Ok((Box::new(port), Box::new(writer)))
}
