//! `motorwire bridge --orion SPEC`: the byte stream to the Orion arm
//! controller (WIRE-FACTS §4.1).

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use motorwire_bridge::OrionPort;
use motorwire_sim::orion::OrionConfig;

/// The serial line's default speed (8N1, no flow control).
pub(crate) const DEFAULT_BAUD: u32 = 115_200;

/// Where the controller is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum OrionSpec {
    /// A serial port at a baud rate.
    Serial { path: String, baud: u32 },
    /// A TCP connection.
    Tcp(String),
    /// motorwire's simulated controller, in this process.
    Sim,
}

/// Parses `serial:PATH[@BAUD]`, `tcp:ADDR` or `sim`.
pub(crate) fn parse(spec: &str) -> Result<OrionSpec, String> {
    if spec == "sim" {
        return Ok(OrionSpec::Sim);
    }
    if let Some(addr) = spec.strip_prefix("tcp:") {
        if addr.is_empty() {
            return Err("--orion tcp:ADDR needs an address, e.g. tcp:192.168.1.50:5000".to_owned());
        }
        return Ok(OrionSpec::Tcp(addr.to_owned()));
    }
    if let Some(rest) = spec.strip_prefix("serial:") {
        let (path, baud) = match rest.rsplit_once('@') {
            Some((path, baud)) => {
                let baud: u32 = baud
                    .parse()
                    .ok()
                    .filter(|b| *b > 0)
                    .ok_or_else(|| format!("--orion {spec}: {baud:?} is not a baud rate"))?;
                (path, baud)
            }
            None => (rest, DEFAULT_BAUD),
        };
        if path.is_empty() {
            return Err(format!(
                "--orion {spec}: serial:PATH needs a path, e.g. serial:/dev/ttyACM0"
            ));
        }
        return Ok(OrionSpec::Serial {
            path: path.to_owned(),
            baud,
        });
    }
    Err(format!(
        "--orion {spec}: expected serial:PATH[@BAUD], tcp:ADDR or sim"
    ))
}

/// A serial port's reader: a read that times out (nothing arrived) is
/// tried again, so only a real error ends the stream.
struct Patient(Box<dyn serialport::SerialPort>);

impl Read for Patient {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        loop {
            match self.0.read(buf) {
                Err(e) if e.kind() == io::ErrorKind::TimedOut => {}
                other => return other,
            }
        }
    }
}

/// How long a broken TCP link waits between attempts to connect again.
const RECONNECT_EVERY: Duration = Duration::from_millis(200);

/// A TCP link to the controller that connects again when it breaks (the
/// controller, or the gateway in front of it, restarted): the bridge sees
/// the controller silent (its motors offline), then heard again. The
/// reader and the writer share the connection; whichever finds it broken
/// first connects again, and the other takes the new one.
#[derive(Clone)]
struct Tcp {
    addr: SocketAddr,
    /// The connection and how many times it was made.
    current: Arc<Mutex<(u64, TcpStream)>>,
}

impl Tcp {
    fn connect(addr: SocketAddr) -> io::Result<TcpStream> {
        let s = TcpStream::connect_timeout(&addr, Duration::from_secs(5))?;
        let _ = s.set_nodelay(true);
        Ok(s)
    }

    /// The connection now, and its number.
    fn stream(&self) -> io::Result<(u64, TcpStream)> {
        let c = self.current.lock().unwrap_or_else(PoisonError::into_inner);
        Ok((c.0, c.1.try_clone()?))
    }

    /// Connection `broken` failed: connect again (once; `Err` if that
    /// fails), unless the other side already did.
    fn renew(&self, broken: u64) -> io::Result<()> {
        let mut c = self.current.lock().unwrap_or_else(PoisonError::into_inner);
        if c.0 != broken {
            return Ok(());
        }
        let s = Self::connect(self.addr)?;
        *c = (broken + 1, s);
        Ok(())
    }
}

/// The reading half: it never ends; a broken connection is made again.
struct TcpReader(Tcp);

impl Read for TcpReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        loop {
            let (n, mut s) = self.0.stream()?;
            match s.read(buf) {
                Ok(0) => {}
                Ok(got) => return Ok(got),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(_) => {}
            }
            while self.0.renew(n).is_err() {
                std::thread::sleep(RECONNECT_EVERY);
            }
        }
    }
}

/// The writing half: a write to a broken connection connects again once
/// and writes there; if that fails too, the write fails.
struct TcpWriter(Tcp);

impl Write for TcpWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let (n, mut s) = self.0.stream()?;
        match s.write(buf) {
            Ok(w) => Ok(w),
            Err(_) => {
                self.0.renew(n)?;
                self.0.stream()?.1.write(buf)
            }
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        self.0.stream()?.1.flush()
    }
}

/// Opens the stream `spec` names.
pub(crate) fn open(spec: &OrionSpec) -> Result<OrionPort, String> {
    match spec {
        OrionSpec::Sim => {
            let config = OrionConfig {
                beacon_interval: Some(Duration::from_millis(200)),
                ..OrionConfig::default()
            };
            let (reader, writer) = motorwire_sim::orion::spawn_in_process(config)
                .map_err(|e| format!("--orion sim: {e}"))?;
            Ok(OrionPort {
                reader: Box::new(reader),
                writer: Box::new(writer),
            })
        }
        OrionSpec::Tcp(addr) => {
            let target = addr
                .to_socket_addrs()
                .map_err(|e| format!("--orion tcp:{addr}: {e}"))?
                .next()
                .ok_or_else(|| format!("--orion tcp:{addr}: no such address"))?;
            let stream = Tcp::connect(target).map_err(|e| format!("--orion tcp:{addr}: {e}"))?;
            let link = Tcp {
                addr: target,
                current: Arc::new(Mutex::new((0, stream))),
            };
            Ok(OrionPort {
                reader: Box::new(TcpReader(link.clone())),
                writer: Box::new(TcpWriter(link)),
            })
        }
        OrionSpec::Serial { path, baud } => {
            let port = serialport::new(path.as_str(), *baud)
                .data_bits(serialport::DataBits::Eight)
                .parity(serialport::Parity::None)
                .stop_bits(serialport::StopBits::One)
                .flow_control(serialport::FlowControl::None)
                .timeout(Duration::from_secs(1))
                .open()
                .map_err(|e| format!("--orion serial:{path}: {e}"))?;
            let writer = port
                .try_clone()
                .map_err(|e| format!("--orion serial:{path}: {e}"))?;
            Ok(OrionPort {
                reader: Box::new(Patient(port)),
                writer: Box::new(writer),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_and_bad_ones_say_why() {
        assert_eq!(parse("sim"), Ok(OrionSpec::Sim));
        assert_eq!(
            parse("serial:/dev/ttyACM0"),
            Ok(OrionSpec::Serial {
                path: "/dev/ttyACM0".to_owned(),
                baud: 115_200
            })
        );
        assert_eq!(
            parse("serial:/dev/ttyUSB1@9600"),
            Ok(OrionSpec::Serial {
                path: "/dev/ttyUSB1".to_owned(),
                baud: 9600
            })
        );
        assert_eq!(
            parse("tcp:10.0.0.2:5000"),
            Ok(OrionSpec::Tcp("10.0.0.2:5000".to_owned()))
        );
        assert_eq!(
            parse("serial:/dev/ttyACM0@fast"),
            Err("--orion serial:/dev/ttyACM0@fast: \"fast\" is not a baud rate".to_owned())
        );
        assert_eq!(
            parse("serial:/dev/x@0"),
            Err("--orion serial:/dev/x@0: \"0\" is not a baud rate".to_owned())
        );
        assert_eq!(
            parse("usb"),
            Err("--orion usb: expected serial:PATH[@BAUD], tcp:ADDR or sim".to_owned())
        );
        assert!(parse("tcp:").is_err());
        assert!(parse("serial:").is_err());
    }
}
