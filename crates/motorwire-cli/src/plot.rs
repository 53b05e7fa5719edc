//! `motorwire plot DIR --svg FILE`: a recording drawn for a person.

use std::path::PathBuf;

use motorwire_bridge::replay::{Recorded, Recording};
use motorwire_translate::BusMap;

use crate::chart::{self, Digest};
use crate::console::{note, say};

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The recording's directory (`motorwire bridge --record DIR`).
    dir: PathBuf,
    /// Where to write the SVG.
    #[arg(long, value_name = "FILE")]
    svg: PathBuf,
    /// The bus map for the motors' units and limits, instead of the one
    /// the recording holds.
    #[arg(long, value_name = "FILE")]
    map: Option<String>,
    /// Draw this motor (repeat for more). Default: every motor that moved,
    /// had a target or was stopped by its deadman.
    #[arg(long = "motor", value_name = "NAME")]
    motors: Vec<String>,
}

pub(crate) fn run(args: &Args) -> u8 {
    match plot(args) {
        Ok(()) => 0,
        Err(e) => {
            note!("motorwire plot: {e}");
            2
        }
    }
}

/// One record of a recording, taken into `d` for [`chart::draw`]: its
/// output lines, and its input lines' times.
fn take(d: &mut Digest, t: std::time::Duration, r: &Recorded) {
    let t = t.as_secs_f64();
    match r {
        Recorded::Line { .. } => d.at(t),
        Recorded::Output { to, value } => d.output(t, *to, value),
        _ => {}
    }
}

fn plot(args: &Args) -> Result<(), String> {
    let dir = &args.dir;
    // The map first: only its motors' samples and targets are kept.
    let map = match &args.map {
        Some(path) => crate::bridge::load_map(path)?,
        None => {
            let setup = Recording::setup_of(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
            let Some(setup) = setup else {
                return Err(format!(
                    "{}: session.json has no setup (its map): give one with --map",
                    dir.display()
                ));
            };
            BusMap::from_toml(&setup.map).map_err(|e| format!("the recorded map: {e}"))?
        }
    };
    for m in &args.motors {
        if map.motor(m).is_none() {
            return Err(format!("--motor {m}: not a motor of the map"));
        }
    }
    // Read a record at a time: only what the chart draws is kept.
    let mut digest = Digest::of_motors(map.motors().map(|m| m.name.as_str()));
    let recording = Recording::scan_partial(dir, |t, r| take(&mut digest, t, &r))
        .map_err(|e| format!("{}: {e}", dir.display()))?;
    if recording.cut {
        note!(
            "motorwire plot: {}: the recording did not end cleanly: its last line, cut in the middle of its write, is left out",
            dir.display()
        );
    }
    let title = format!("motorwire recording {}", dir.display());
    let drawn = chart::draw(digest, &map, &args.motors, &title, &args.svg)?;
    say!(
        "{}: {} motors, {} marks",
        args.svg.display(),
        drawn.panels,
        drawn.marks
    )
    .map_err(|e| format!("standard output: {e}"))
}
