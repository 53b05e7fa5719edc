//! `RealTimeArm`'s ports: the bridge's sending half queues nothing while
//! the joints talk (issue 15: `motorwire bridge --bus sim` kept every joint
//! frame in a port it never read, about 60 KB/s with three idle joints).
#![allow(clippy::unwrap_used, clippy::panic)]

use std::thread;
use std::time::Duration;

use motorwire_bridge::sim::RealTimeArm;
use motorwire_bridge::{Bridge, BridgeConfig, Output, Runner};
use motorwire_translate::BusMap;

const MAP: &str = include_str!("../../../fixtures/maps/demo-arm.toml");

#[test]
fn the_sending_port_stays_empty_while_the_joints_talk() {
    let map = BusMap::from_toml(MAP).unwrap();
    let config = BridgeConfig {
        feedback_period: Some(Duration::from_millis(20)),
        ..BridgeConfig::default()
    };
    let bridge = Bridge::new(map, config).unwrap();
    let arm = RealTimeArm::start(bridge.map()).unwrap();
    // What a second `port()` as the sending half would keep.
    let unread = arm.port();
    let mut tx = arm.sender();
    let rx = arm.port();
    let runner = Runner::new();
    let input = runner.input();
    let mut feedback = 0;
    let bridge = thread::scope(|s| {
        let run = s.spawn(|| {
            runner.run(bridge, &mut tx, rx, |o| {
                if matches!(o, Output::Feedback(_)) {
                    feedback += 1;
                }
            })
        });
        thread::sleep(Duration::from_millis(600));
        input.finish();
        run.join().unwrap().unwrap()
    });
    assert!(bridge.is_finished());
    assert!(feedback > 0, "the joints were active and talking");
    let frames = unread.queued();
    assert!(
        frames > 100,
        "the joints sent {frames} frames; expected hundreds in 0.6 s"
    );
    assert_eq!(tx.queued(), 0, "after {frames} joint frames");
}
