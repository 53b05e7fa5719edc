//! `motorwire bridge --orion SPEC`: the byte stream to the Orion arm
//! controller (WIRE-FACTS §4.1).

use std::io::{self, Read};
use std::net::{TcpStream, ToSocketAddrs};
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
            let stream = TcpStream::connect_timeout(&target, Duration::from_secs(5))
                .map_err(|e| format!("--orion tcp:{addr}: {e}"))?;
            let _ = stream.set_nodelay(true);
            let reader = stream
                .try_clone()
                .map_err(|e| format!("--orion tcp:{addr}: {e}"))?;
            Ok(OrionPort {
                reader: Box::new(reader),
                writer: Box::new(stream),
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
