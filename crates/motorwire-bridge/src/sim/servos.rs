//! The simulated servos of a bus map's serial ports: stepped with the
//! simulated arm, or in real time behind a runner's servo links.

use std::sync::Arc;
use std::time::{Duration, Instant};

use motorwire_translate::{BusMap, Target};

use crate::error::BridgeError;

/// The simulated servos of one serial port, and their answers on their
/// way to the bridge (each at its time, in order).
#[derive(Debug)]
pub(super) struct SimServoPort {
    pub(super) bus: motorwire_sim::servo::ServoBus,
    pub(super) answers: std::collections::VecDeque<(Duration, Vec<u8>)>,
}

/// The simulated servos of `map`'s serial ports, one bus each.
pub(super) fn servo_buses(map: &BusMap) -> Result<Vec<SimServoPort>, BridgeError> {
    map.servo_ports()
        .iter()
        .enumerate()
        .map(|(k, port)| {
            let servos: Vec<(&'static motorwire_servo::table::Model, u8)> = map
                .motors()
                .filter_map(|m| match m.target {
                    Target::Servo(t) if usize::from(t.port) == k => Some((t.table()?, t.id)),
                    _ => None,
                })
                .collect();
            let bus = motorwire_sim::servo::ServoBus::mixed(&servos)
                .map_err(|e| BridgeError::SimServos(format!("servo port {}: {e}", port.path)))?;
            Ok(SimServoPort {
                bus,
                answers: std::collections::VecDeque::new(),
            })
        })
        .collect()
}

/// The simulated servos of `map`'s serial ports as links a
/// [`crate::runtime::Runner`] drives in real time ([`crate::runtime::Runner::with_servo_links`]):
/// each port's servos in this process, its bytes paced at the port's baud
/// rate (10 bits a byte, each way one packet after another) and each
/// answer sent after its servo's return delay, as on the wire.
///
/// # Errors
/// [`BridgeError::SimServos`]: a port whose servos cannot share one bus.
pub fn servo_links(map: &BusMap) -> Result<Vec<crate::runtime::ServoLink>, BridgeError> {
    servo_links_with(map, motorwire_sim::servo::ServoFaults::default(), 1)
}

/// [`servo_links`] whose servos' answers are dropped, corrupted or late as
/// `faults` says, drawn from `seed` (each port from its own).
///
/// # Errors
/// As [`servo_links`].
pub fn servo_links_with(
    map: &BusMap,
    faults: motorwire_sim::servo::ServoFaults,
    seed: u64,
) -> Result<Vec<crate::runtime::ServoLink>, BridgeError> {
    servo_buses(map)?
        .into_iter()
        .enumerate()
        .map(|(k, mut p)| {
            p.bus = p.bus.with_faults(faults, seed.wrapping_add(k as u64));
            p
        })
        .zip(map.servo_ports())
        .map(|(p, port)| {
            let wire = Arc::new(SimWire {
                state: std::sync::Mutex::new(WireState {
                    bus: p.bus,
                    answers: std::collections::VecDeque::new(),
                    start: Instant::now(),
                    tx_free: Duration::ZERO,
                    rx_free: Duration::ZERO,
                    closed: false,
                }),
                ready: std::sync::Condvar::new(),
                baud: port.baud.max(1),
            });
            Ok(crate::runtime::ServoLink {
                reader: Box::new(WireReader(Arc::clone(&wire))),
                writer: Box::new(WireWriter(wire)),
                reopen: None,
            })
        })
        .collect()
}

/// One simulated serial port in real time.
#[derive(Debug)]
struct SimWire {
    state: std::sync::Mutex<WireState>,
    ready: std::sync::Condvar,
    baud: u32,
}

#[derive(Debug)]
struct WireState {
    bus: motorwire_sim::servo::ServoBus,
    /// Answers on their way, each with when its last byte is in.
    answers: std::collections::VecDeque<(Instant, Vec<u8>)>,
    start: Instant,
    /// When the host's line and the servos' line are next free (since
    /// `start`).
    tx_free: Duration,
    rx_free: Duration,
    closed: bool,
}

impl SimWire {
    /// How long `n` bytes take on the wire.
    fn wire_time(&self, n: usize) -> Duration {
        let bits = u64::try_from(n).unwrap_or(u64::MAX).saturating_mul(10);
        Duration::from_nanos(bits.saturating_mul(1_000_000_000) / u64::from(self.baud))
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, WireState> {
        self.state
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

struct WireWriter(Arc<SimWire>);

impl std::io::Write for WireWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let wire = &self.0;
        let mut s = wire.lock();
        let now = s.start.elapsed();
        let sent = now.max(s.tx_free) + wire.wire_time(buf.len());
        s.tx_free = sent;
        for a in s.bus.write(sent, buf) {
            let at = (sent + a.delay).max(s.rx_free) + wire.wire_time(a.bytes.len());
            s.rx_free = at;
            let due = s.start + at;
            s.answers.push_back((due, a.bytes));
        }
        drop(s);
        wire.ready.notify_all();
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Drop for WireWriter {
    fn drop(&mut self) {
        self.0.lock().closed = true;
        self.0.ready.notify_all();
    }
}

struct WireReader(Arc<SimWire>);

impl std::io::Read for WireReader {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let wire = &self.0;
        let mut s = wire.lock();
        loop {
            let now = Instant::now();
            match s.answers.front().map(|(t, _)| *t) {
                Some(due) if due <= now => {
                    let Some((_, mut bytes)) = s.answers.pop_front() else {
                        continue;
                    };
                    let n = bytes.len().min(buf.len());
                    if let (Some(to), Some(from)) = (buf.get_mut(..n), bytes.get(..n)) {
                        to.copy_from_slice(from);
                    }
                    if n < bytes.len() {
                        bytes.drain(..n);
                        s.answers.push_front((due, bytes));
                    }
                    return Ok(n);
                }
                _ if s.closed => return Ok(0),
                Some(due) => {
                    s = wire
                        .ready
                        .wait_timeout(s, due - now)
                        .map(|(g, _)| g)
                        .unwrap_or_else(|e| e.into_inner().0);
                }
                None => {
                    s = wire
                        .ready
                        .wait_timeout(s, Duration::from_millis(100))
                        .map(|(g, _)| g)
                        .unwrap_or_else(|e| e.into_inner().0);
                }
            }
        }
    }
}
