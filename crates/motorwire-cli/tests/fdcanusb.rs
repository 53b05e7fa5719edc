//! `motorwire bridge --bus fdcanusb:PATH` against a pty that speaks mjbots'
//! fdcanusb protocol: the test is the adapter (it answers each `can send`
//! with `OK`) and a simulated moteus controller behind it (its replies come
//! back as `rcv` lines), as a real fdcanusb with a moteus on its bus does.
#![cfg(unix)]
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

mod common;

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motorwire_can::{CanId, Frame};
use motorwire_sim::moteus::{MoteusConfig, SimMoteus, mode};
use serialport::{SerialPort, TTYPort};

/// The adapter: reads `can send` lines from `port`, answers `OK`, hands
/// the frames to `moteus`, writes its replies as `rcv` lines. Every line
/// it took, in order.
fn adapter(
    mut port: TTYPort,
    moteus: Arc<Mutex<SimMoteus>>,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<Vec<String>> {
    std::thread::spawn(move || {
        port.set_timeout(Duration::from_millis(10)).unwrap();
        let start = Instant::now();
        let mut taken = Vec::new();
        let mut line = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            let mut byte = [0u8; 1];
            match port.read(&mut byte) {
                Ok(1) if byte[0] == b'\n' => {
                    let text = String::from_utf8(std::mem::take(&mut line)).unwrap();
                    let fields: Vec<&str> = text.split(' ').collect();
                    assert_eq!(fields[..2], ["can", "send"], "{text}");
                    port.write_all(b"OK\r\n").unwrap();
                    let id = CanId::extended(u32::from_str_radix(fields[2], 16).unwrap()).unwrap();
                    let data: Vec<u8> = (0..fields[3].len() / 2)
                        .map(|i| u8::from_str_radix(&fields[3][2 * i..2 * i + 2], 16).unwrap())
                        .collect();
                    let frame = Frame::fd(id, &data).unwrap();
                    let mut m = moteus.lock().unwrap();
                    m.handle_frame(start.elapsed(), &frame);
                    while let Some(r) = m.poll_transmit() {
                        let hex: String = r.data().iter().map(|b| format!("{b:02X}")).collect();
                        port.write_all(
                            format!("rcv {:x} {hex} E B F\r\n", r.id().raw()).as_bytes(),
                        )
                        .unwrap();
                    }
                    taken.push(text);
                }
                Ok(1) => line.push(byte[0]),
                _ => moteus.lock().unwrap().handle_timeout(start.elapsed()),
            }
        }
        taken
    })
}

#[test]
fn the_bridge_drives_a_moteus_through_an_fdcanusb() {
    let (master, slave) = TTYPort::pair().unwrap();
    let path = slave.name().unwrap();
    let moteus = Arc::new(Mutex::new(SimMoteus::new(MoteusConfig::new(1)).unwrap()));
    let stop = Arc::new(AtomicBool::new(false));
    let adapter = adapter(master, Arc::clone(&moteus), Arc::clone(&stop));
    let map = std::env::temp_dir().join(format!("motorwire-fdcanusb-{}.toml", std::process::id()));
    std::fs::write(
        &map,
        "[motors.hip]\ndialect = \"moteus\"\nid = 1\nquery_rate_hz = 20\n\
         limits = { min_position = -90, max_position = 90, max_velocity = 360, max_acceleration = 1440, max_torque = 3 }\n",
    )
    .unwrap();
    let bus = format!("fdcanusb:{path}");
    let mut bridge = common::spawn(&[
        "bridge",
        "--map",
        map.to_str().unwrap(),
        "--bus",
        &bus,
        "--max-age",
        "0",
        "--feedback-hz",
        "0",
    ]);
    let mut stdin = bridge.stdin.take().unwrap();
    // The stop waits for the move's arrival.
    let mut lines = common::Lines::of(bridge.stdout.take().unwrap());
    stdin
        .write_all(b"{\"motor_id\":\"hip\",\"timestamp\":0,\"control_mode\":\"position\",\"setpoint\":45}\n")
        .unwrap();
    // The move is 0.125 rev at 1 rev/s: well within 10 s.
    lines.until("arrival of the hip", Duration::from_secs(10), |l| {
        l.contains("\"arrived\":true")
    });
    assert!((moteus.lock().unwrap().position() - 0.125).abs() < 1e-4);
    stdin.write_all(b"{\"emergency_stop\":true}\n").unwrap();
    std::thread::sleep(Duration::from_millis(300));
    drop(stdin);
    let status = bridge.wait().unwrap();
    let seen = lines.finish();
    stop.store(true, Ordering::Relaxed);
    let taken = adapter.join().unwrap();
    drop(slave);
    let stdout = seen.join("\n");
    assert_eq!(status.code(), Some(0), "{stdout}");
    assert!(stdout.contains("\"emergency_stop\":true"), "{stdout}");
    assert_eq!(moteus.lock().unwrap().mode(), mode::STOPPED);
    // Each line as mjbots' line encoder writes it: id, data padded to its
    // CAN-FD length with 0x50, bit-rate switching and FD. The register
    // frames ask for a reply (0x8001); the diagnostic stream's text does
    // not (0x0001: subframe 0x40), its polls do (0x42).
    assert!(
        taken.iter().all(|l| (l.starts_with("can send 8001 ")
            || l.starts_with("can send 0001 40"))
            && l.ends_with(" BF")),
        "{taken:?}"
    );
    // Over the same adapter, the controller's own bounds were read and set
    // to the map's range (±90°, ±0.25 rev; its own were ±0.5).
    let m = moteus.lock().unwrap();
    assert_eq!(
        m.console_lines(),
        [
            "conf get servopos.position_min",
            "conf get servopos.position_max",
            "conf set servopos.position_min -0.25",
            "conf set servopos.position_max 0.25"
        ]
    );
    assert_eq!(
        (m.config().position_min, m.config().position_max),
        (-0.25, 0.25)
    );
    drop(m);
    // The first move: position mode (01000A), then its registers from 0x020.
    assert!(
        taken
            .iter()
            .any(|l| l.starts_with("can send 8001 01000A0E20")),
        "{taken:?}"
    );
    // The stop, last of the commands (queries may follow).
    let stop_line = "can send 8001 01000011001C0401110B130D BF";
    let last_command = taken.iter().rposition(|l| l.contains(" 0100")).unwrap();
    assert_eq!(taken[last_command], stop_line, "{taken:?}");
    let _ = std::fs::remove_file(map);
}
