//! The sans-IO `Bridge` driven from your own loop.
//!
//! ```sh
//! cargo run --example bridge_loop
//! ```
//!
//! The bridge does no I/O and reads no clock: you hand it input lines
//! (`handle_line`), received frames (`handle_frame`) and the time, and take
//! from it the frames to send (`poll_transmit`), the lines to print
//! (`poll_output`) and when to call it next (`poll_timeout`). Here the bus
//! is motorwire's in-memory one in simulated time with a simulated joint on
//! it, so the run is exact and instant; on hardware the same loop sends on
//! a `motorwire_can::socketcan` bus and sleeps until `poll_timeout` or a
//! frame arrives (which is what `motorwire_bridge::Runner` does for you).

use std::io::Write;
use std::time::Duration;

use motorwire_bridge::sim::joint_config;
use motorwire_bridge::{Bridge, BridgeConfig, Origin, Output};
use motorwire_can::{CanBus, SimBus, SimConfig};
use motorwire_sim::SimJoint;
use motorwire_translate::BusMap;

const MAP: &str = r#"
[motors.elbow]
dialect = "irpc"
node = 0x12
limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500, max_jerk = 2000 }
"#;

/// The input: when each line arrives, and the line.
const LINES: [(u64, &str); 3] = [
    (
        100,
        r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":60}"#,
    ),
    (
        2000,
        r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":170}"#,
    ),
    (
        2100,
        r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":30,"velocity_limit":90}"#,
    ),
];

fn run(out: &mut dyn Write) -> Result<(), Box<dyn std::error::Error>> {
    let map = BusMap::from_toml(MAP)?;
    let elbow = map
        .motor("elbow")
        .and_then(joint_config)
        .ok_or("no elbow joint")?;
    let config = BridgeConfig {
        // Feedback lines every 100 ms would drown the example's output.
        feedback_period: None,
        ..BridgeConfig::default()
    };
    let mut bridge = Bridge::new(map, config)?;

    // The bus, and the joint at its own port (as a separate device would be).
    let bus = SimBus::new(SimConfig::default())?;
    let mut port = bus.port();
    let mut joint = SimJoint::new(elbow)?;
    let mut joint_port = bus.port();

    let origin = Origin(1);
    let mut pending = LINES.iter().peekable();
    let end = Duration::from_secs(5);
    bridge.start(bus.now());
    let mut finishing = false;
    loop {
        let now = bus.now();
        while let Some((_, line)) = pending.next_if(|(at, _)| Duration::from_millis(*at) <= now) {
            bridge.handle_line(now, origin, line);
        }
        if !finishing && now >= end {
            // The end of input: moves finish, then the joints are deactivated.
            bridge.finish(now);
            finishing = true;
        }
        // Everything due now, until nobody has anything more to do.
        loop {
            let mut busy = false;
            while let Some(frame) = bridge.poll_transmit() {
                port.send(&frame)?;
                busy = true;
            }
            if busy {
                bridge.flushed(now);
            }
            busy |= joint.serve(&mut joint_port, now)?;
            while let Some(received) = port.try_recv() {
                bridge.handle_frame(now, &received.frame);
                busy = true;
            }
            if bridge.poll_timeout().is_some_and(|t| t <= now) {
                bridge.handle_timeout(now);
                busy = true;
            }
            while let Some(output) = bridge.poll_output() {
                match output {
                    Output::Result { .. } | Output::Arrival { .. } => {
                        writeln!(out, "{:>5} ms  {}", now.as_millis(), output.to_json())?;
                    }
                    Output::Event(_) | Output::Feedback(_) | Output::ToOne { .. } => {}
                }
            }
            if !busy {
                break;
            }
        }
        if bridge.is_finished() {
            break;
        }
        // Sleep until the next thing anyone has to do.
        let next = [
            bridge.poll_timeout(),
            bus.next_delivery(),
            joint.poll_timeout(),
            pending.peek().map(|(at, _)| Duration::from_millis(*at)),
            (!finishing).then_some(end),
        ]
        .into_iter()
        .flatten()
        .min()
        .ok_or("nothing left to wait for")?;
        bus.advance_to(next.max(now + Duration::from_nanos(1)));
    }
    writeln!(
        out,
        "finished at {} ms; the joint is at {:.3} deg, {:?}",
        bus.now().as_millis(),
        joint.position(),
        joint.state()
    )?;
    Ok(())
}

fn main() -> std::process::ExitCode {
    match run(&mut std::io::stdout()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("bridge_loop: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    /// The output, exactly.
    const EXPECTED: &str = r##"  100 ms  {"ok":true,"line":1,"motor_id":"elbow","acked":["elbow"],"arrival_follows":true,"latency_us":0,"ack_us":0,"losses":["max_velocity: defaulted: 120 from the bus map","max_acceleration: defaulted: 500 from the bus map","max_deceleration: defaulted: 500, the max_acceleration from the bus map (the bus map gives no max_deceleration)","max_jerk: defaulted: 2000 from the bus map"]}
 1060 ms  {"arrived":true,"line":1,"motor_id":"elbow","after_ms":960,"motors":[{"motor_id":"elbow","arrived":true,"target":60.0,"error":0.008907318,"after_ms":960}]}
 2000 ms  {"ok":false,"line":2,"motor_id":"elbow","error":{"kind":"refused","rule":"outside_limit","message":"elbow: setpoint 170 is outside max_position (bus map) 150","motor":"elbow","field":"setpoint","value":170.0,"limit":150.0,"limit_name":"max_position","limit_source":"bus map"}}
 2100 ms  {"ok":true,"line":3,"motor_id":"elbow","acked":["elbow"],"arrival_follows":true,"latency_us":0,"ack_us":0,"losses":["max_acceleration: defaulted: 500 from the bus map","max_deceleration: defaulted: 500, the max_acceleration from the bus map (the bus map gives no max_deceleration)","max_jerk: defaulted: 2000 from the bus map"]}
 2860 ms  {"arrived":true,"line":3,"motor_id":"elbow","after_ms":760,"motors":[{"motor_id":"elbow","arrived":true,"target":30.0,"error":0.0040416718,"after_ms":760}]}
finished at 5000 ms; the joint is at 30.000 deg, Inactive
"##;

    #[test]
    fn drives_the_bridge_and_the_joint() {
        let mut out = Vec::new();
        assert!(super::run(&mut out).is_ok());
        assert_eq!(String::from_utf8_lossy(&out), EXPECTED);
    }
}
