//! 10,000 commands from the client to a simulated joint over a bus that
//! drops 10%, duplicates 10% and corrupts 5% of frames: each ends acked
//! exactly once or reported failed after its retries; the joint never
//! executes a request twice; nothing panics.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::collections::{BTreeMap, HashMap, HashSet};
use std::time::Duration;

use motorwire_can::client::{ClientConfig, Event, Outcome};
use motorwire_can::{Faults, SimConfig};
use motorwire_irpc::{MotionProfile, Payload, SetTargetPayloadV2};
use motorwire_sim::rig::Rig;
use motorwire_sim::{JointConfig, SimError};

const JOINT: u16 = 0x10;

fn command(i: u32) -> SetTargetPayloadV2 {
    // Distinct consecutive targets within ±90°, alternating profiles.
    let target = ((i.wrapping_mul(7919) % 1801) as f32 - 900.0) / 10.0;
    SetTargetPayloadV2 {
        target_angle: target,
        max_velocity: 100.0,
        target_velocity: 0.0,
        max_acceleration: 500.0,
        max_deceleration: 400.0,
        max_jerk: if i.is_multiple_of(2) { 2000.0 } else { 0.0 },
        profile: if i.is_multiple_of(2) {
            MotionProfile::SCurve
        } else {
            MotionProfile::Trapezoidal
        },
        max_current: 0.0,
        max_temperature: 0.0,
    }
}

struct Tally {
    acked: u32,
    nacked: BTreeMap<u16, u32>,
    timed_out: u32,
    ghosts: usize,
    altered: usize,
}

/// Runs `n` commands through `faults` and checks every invariant; returns the tally.
fn run(n: u32, seed: u64, faults: Faults) -> Result<Tally, SimError> {
    let mut rig = Rig::new(
        SimConfig {
            seed,
            faults,
            latency: Duration::from_micros(150),
            ..SimConfig::default()
        },
        ClientConfig::default(),
        [JointConfig::new(JOINT)],
    )?;
    rig.joint_mut(JOINT).expect("the joint").keep_log();
    let mut sent: HashMap<u32, Payload> = HashMap::new();
    let mut completions: HashMap<u32, u32> = HashMap::new();
    let mut acked_ids = Vec::new();
    let mut tally = Tally {
        acked: 0,
        nacked: BTreeMap::new(),
        timed_out: 0,
        ghosts: 0,
        altered: 0,
    };
    let retries = rig.client.config().retries;
    let mut i = 0;
    while i < n {
        // Bring the joint up (again, if a corrupted frame reset it).
        let state = rig.joint(JOINT).map(|j| j.state());
        if state != Some(motorwire_irpc::LifecycleState::Active) {
            for p in [Payload::Configure, Payload::Activate] {
                let c = rig.request(JOINT, p)?;
                sent.insert(c.msg_id, p);
            }
            continue;
        }
        let cmd = Payload::SetTargetV2(command(i));
        let c = rig.request(JOINT, cmd)?;
        sent.insert(c.msg_id, cmd);
        *completions.entry(c.msg_id).or_default() += 1;
        match c.outcome {
            Outcome::Acked => {
                tally.acked += 1;
                acked_ids.push(c.msg_id);
            }
            Outcome::Nacked(code) => *tally.nacked.entry(code.0).or_default() += 1,
            Outcome::TimedOut => {
                assert_eq!(c.attempts, retries + 1, "timed out before every retry");
                tally.timed_out += 1;
            }
        }
        // Completions are also never reported twice through the event queue.
        for e in rig.take_events() {
            if let Event::Completed(c) = e {
                *completions.entry(c.msg_id).or_default() += 1;
            }
        }
        i += 1;
    }
    assert!(
        completions.values().all(|&k| k == 1),
        "a request completed twice"
    );
    assert_eq!(
        tally.acked + tally.timed_out + tally.nacked.values().sum::<u32>(),
        n
    );

    let joint = rig.joint(JOINT).expect("the joint");
    // Executions of exactly what the client sent under that msg_id.
    let mut genuine: HashMap<u32, u32> = HashMap::new();
    let mut corrupted_ids = HashSet::new();
    for e in joint.log() {
        match sent.get(&e.msg_id) {
            Some(p) if *p == e.payload => {
                *genuine.entry(e.msg_id).or_default() += 1;
            }
            Some(_) => {
                tally.altered += 1;
                corrupted_ids.insert(e.msg_id);
            }
            None => {
                tally.ghosts += 1;
                corrupted_ids.insert(e.msg_id);
            }
        }
    }
    assert!(
        genuine.values().all(|&k| k == 1),
        "the joint executed a request twice"
    );
    for id in &acked_ids {
        // Acked means executed once, unless a corrupted frame carrying the
        // same msg_id got there first (the joint then answers the real one
        // as a duplicate): only corruption can do that.
        assert!(
            genuine.get(id) == Some(&1) || corrupted_ids.contains(id),
            "acked msg_id {id} was not executed"
        );
    }
    let stats = rig.bus().stats();
    // Only a flipped bit that still decodes can make the joint run something
    // the client did not send (iRPC carries no checksum).
    assert!(tally.ghosts + tally.altered <= usize::try_from(stats.corrupted).unwrap_or(0));
    Ok(tally)
}

#[test]
fn ten_thousand_commands_through_drop_duplicate_and_corruption() -> Result<(), SimError> {
    let faults = Faults {
        drop: 0.10,
        duplicate: 0.10,
        corrupt: 0.05,
        ..Faults::default()
    };
    let t = run(10_000, 0x5EED, faults)?;
    eprintln!(
        "acked {}, nacked {:?}, timed out {}, ghost executions {}, altered executions {}",
        t.acked, t.nacked, t.timed_out, t.ghosts, t.altered
    );
    // At these rates an attempt fails about a quarter of the time; four
    // attempts all failing is rare.
    assert!(t.acked >= 9_900, "only {} acked", t.acked);
    assert!(t.timed_out <= 100);
    // A nack can only come from a corrupted frame: a value the joint then
    // refused, or a flipped bit in the Nack itself (so any code).
    assert!(t.nacked.values().sum::<u32>() <= 100, "{:?}", t.nacked);
    Ok(())
}

#[test]
fn without_corruption_everything_executed_is_exactly_what_was_sent() -> Result<(), SimError> {
    let faults = Faults {
        drop: 0.10,
        duplicate: 0.10,
        delay: 0.10,
        reorder: 0.05,
        ..Faults::default()
    };
    let t = run(3_000, 42, faults)?;
    assert_eq!((t.ghosts, t.altered), (0, 0));
    assert!(t.nacked.is_empty(), "{:?}", t.nacked);
    assert_eq!(t.acked + t.timed_out, 3_000);
    Ok(())
}

#[test]
fn the_same_seed_gives_the_same_run() -> Result<(), SimError> {
    let faults = Faults {
        drop: 0.2,
        duplicate: 0.2,
        corrupt: 0.1,
        ..Faults::default()
    };
    let a = run(500, 9, faults)?;
    let b = run(500, 9, faults)?;
    assert_eq!(
        (a.acked, a.timed_out, a.nacked),
        (b.acked, b.timed_out, b.nacked)
    );
    Ok(())
}
