//! `motorwire replay DIR`: a recorded session's inputs fed again into the
//! bridge on the simulated bus, and what comes out compared with the
//! recording.

use std::path::PathBuf;
use std::time::Duration;

use motorwire_bridge::Bridge;
use motorwire_record::replay::{self, Comparison, Pace, Recording};
use motorwire_translate::BusMap;

use crate::console::{note, say};

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The recording's directory (`motorwire bridge --record DIR`).
    dir: PathBuf,
    /// Replay against this bus map instead of the recorded one (to see
    /// what a changed map would have done).
    #[arg(long, value_name = "FILE")]
    map: Option<String>,
    /// At the recorded pace (a recorded second takes a second) instead of
    /// as fast as the simulation runs.
    #[arg(long)]
    real_time: bool,
    /// How far a motor's position or arrival error caught in motion may
    /// be from the recorded one (in its unit): a session recorded in real
    /// time stops or reads a joint a few milliseconds off its replay.
    /// Other numbers: within 0.05 (a number in a message, a unit of its
    /// last printed place).
    #[arg(long, value_name = "UNITS", default_value_t = 2.0)]
    motion_tolerance: f64,
    /// The same for a velocity caught in motion (units a second).
    #[arg(long, value_name = "UNITS", default_value_t = 5.0)]
    velocity_tolerance: f64,
    /// The longest recording replayed, in seconds of its clock (a longer
    /// one is refused: its clock may be damaged, and it would be simulated
    /// for long).
    #[arg(long, value_name = "SECONDS", default_value_t = 6 * 3600)]
    max_span: u64,
    /// Print the comparison as one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// Replay a recording that is incomplete (it dropped records, or did
    /// not end cleanly) as far as it goes, saying so, instead of refusing
    /// it: what it lost cannot be compared, and may make the replay
    /// diverge.
    #[arg(long)]
    allow_incomplete: bool,
}

/// The exit status of a replay that diverged.
const EXIT_DIVERGED: u8 = 1;

pub(crate) fn run(args: &Args) -> u8 {
    match replay_dir(args) {
        Ok(code) => code,
        Err(e) => {
            note!("motorwire replay: {e}");
            2
        }
    }
}

fn secs(d: Duration) -> String {
    format!("{:.6} s", d.as_secs_f64())
}

fn replay_dir(args: &Args) -> Result<u8, String> {
    for (flag, v) in [
        ("--motion-tolerance", args.motion_tolerance),
        ("--velocity-tolerance", args.velocity_tolerance),
    ] {
        if !(v.is_finite() && (0.0..=1e6).contains(&v)) {
            return Err(format!(
                "{flag} {v}: expected a number of units, 0 to 1000000"
            ));
        }
    }
    let dir = &args.dir;
    // Read as far as it goes (its counts checked against its files when
    // it is whole), then refused if it is not whole, unless allowed: first
    // for records it lost, then, once it is known to have a setup, for an
    // end it lacks (a recording from before replay has neither).
    let recording =
        Recording::read_to_replay_lossy(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let incomplete = recording.incomplete();
    let refused = |why: &str| {
        format!(
            "{}: an incomplete recording: {why}; not replayed (--allow-incomplete replays it as far as it goes)",
            dir.display()
        )
    };
    if let Some(why) = &incomplete
        && recording.dropped > 0
        && !args.allow_incomplete
    {
        return Err(refused(why));
    }
    let setup = recording.setup.clone().ok_or_else(|| {
        format!(
            "{}: session.json has no setup (recorded by a motorwire without replay)",
            dir.display()
        )
    })?;
    if let Some(why) = &incomplete {
        if !args.allow_incomplete {
            return Err(refused(why));
        }
        note!(
            "motorwire replay: {}: an incomplete recording, replayed as far as it goes (--allow-incomplete): {why}{}",
            dir.display(),
            if recording.cut {
                "; lines.jsonl's last line, cut in the middle of its write, left out"
            } else {
                ""
            }
        );
    }
    let map = match &args.map {
        Some(path) => crate::bridge::load_map(path)?,
        None => BusMap::from_toml(&setup.map).map_err(|e| format!("the recorded map: {e}"))?,
    };
    let config = setup.bridge_config().map_err(|e| e.to_string())?;
    let wire = config.client.wire;
    let bridge = Bridge::new(map.clone(), config).map_err(|e| e.to_string())?;
    let replayed = replay::replay(
        &recording,
        bridge,
        setup.sim_config().map_err(|e| e.to_string())?,
        Pace {
            real_time: args.real_time,
            max_span: Duration::from_secs(args.max_span),
            ..Pace::default()
        },
    )
    .map_err(|e| e.to_string())?;
    let c = replay::compare(
        &recording,
        &replayed,
        &map,
        wire,
        &replay::Tolerance {
            motion: args.motion_tolerance,
            motion_rate: args.velocity_tolerance,
            ..replay::Tolerance::default()
        },
    );
    let shown = if args.json {
        say!("{}", summary_json(&c, &replayed, &setup.bus, &recording))
    } else {
        summary_text(&c, &replayed, &setup.bus, incomplete.as_deref())
    };
    shown.map_err(|e| format!("standard output: {e}"))?;
    Ok(if c.divergence.is_some() {
        EXIT_DIVERGED
    } else {
        0
    })
}

fn summary_json(
    c: &Comparison,
    r: &replay::Replayed,
    bus: &str,
    recording: &Recording,
) -> serde_json::Value {
    let d = c.divergence.as_ref().map(|d| {
        serde_json::json!({
            "at_us": u64::try_from(d.at.as_micros()).unwrap_or(u64::MAX),
            "stream": d.stream,
            "recorded": d.recorded,
            "recorded_at_us": d.recorded_at.map(|t| u64::try_from(t.as_micros()).unwrap_or(u64::MAX)),
            "replayed": d.replayed,
            "replayed_at_us": d.replayed_at.map(|t| u64::try_from(t.as_micros()).unwrap_or(u64::MAX)),
        })
    });
    serde_json::json!({
        "same": c.divergence.is_none(),
        "complete": recording.is_complete(),
        "incomplete": recording.incomplete(),
        "ended_cleanly": recording.ended,
        "dropped": recording.dropped,
        "recorded_bus": bus,
        "inputs": r.inputs,
        "simulated_us": u64::try_from(r.simulated.as_micros()).unwrap_or(u64::MAX),
        "took_us": u64::try_from(r.took.as_micros()).unwrap_or(u64::MAX),
        "compared": {
            "answers": c.answers,
            "events": c.events,
            "frames": c.frames,
            "orion_lines": c.orion_lines,
        },
        "divergence": d,
    })
}

fn summary_text(
    c: &Comparison,
    r: &replay::Replayed,
    bus: &str,
    incomplete: Option<&str>,
) -> std::io::Result<()> {
    if let Some(why) = incomplete {
        say!("an incomplete recording, replayed as far as it goes: {why}")?;
    }
    let speed = r.simulated.as_secs_f64() / r.took.as_secs_f64().max(1e-9);
    say!(
        "replayed {} inputs over {} of simulated time in {} ({speed:.1}x real time), against the simulator (recorded on {bus})",
        r.inputs,
        secs(r.simulated),
        secs(r.took),
    )?;
    say!(
        "compared {} answers, {} events, {} frames, {} Orion lines",
        c.answers,
        c.events,
        c.frames,
        c.orion_lines
    )?;
    match &c.divergence {
        None if incomplete.is_some() => {
            say!("the same: no divergence, as far as the incomplete recording goes")
        }
        None => say!("the same: no divergence"),
        Some(d) => {
            say!("first divergence at {}, in {}:", secs(d.at), d.stream)?;
            let side = |v: &Option<serde_json::Value>, at: Option<Duration>| match (v, at) {
                (Some(v), Some(at)) => format!("(at {}) {v}", secs(at)),
                _ => "nothing".to_owned(),
            };
            say!("  recorded: {}", side(&d.recorded, d.recorded_at))?;
            say!("  replayed: {}", side(&d.replayed, d.replayed_at))
        }
    }
}
