//! `motorwire plot DIR --svg FILE`: a recording drawn for a person.

use std::path::PathBuf;

use motorwire_record::replay::{Recorded, Recording, Scanned};
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

/// What the chart says of a recording that is not the whole session (it
/// lost records, or did not end cleanly); `None` for one that is.
fn incomplete_notice(s: &Scanned) -> Option<String> {
    let mut lacks = Vec::new();
    if s.dropped > 0 {
        lacks.push(format!(
            "{} records lost{}",
            s.dropped,
            s.dropped_span.map_or_else(
                || " (when, the recording does not say)".to_owned(),
                |(a, b)| format!(
                    " from {:.2} s to {:.2} s (shaded)",
                    a.as_secs_f64(),
                    b.as_secs_f64()
                )
            )
        ));
    }
    if !s.ended {
        lacks.push(
            "it did not end cleanly (the bridge was killed, or its disk stopped answering): drawn up to its last record"
                .to_owned(),
        );
    }
    (!lacks.is_empty()).then(|| format!("incomplete recording: {}", lacks.join("; ")))
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
            "motorwire plot: {}: the recording {}: its last line, cut in the middle of its write, is left out",
            dir.display(),
            if recording.ended {
                "lost records"
            } else {
                "did not end cleanly"
            }
        );
    }
    if let Some(notice) = incomplete_notice(&recording) {
        note!(
            "motorwire plot: {}: an incomplete recording: {}",
            dir.display(),
            recording.incomplete().unwrap_or_default()
        );
        let lost = recording
            .dropped_span
            .map(|(a, b)| (a.as_secs_f64(), b.as_secs_f64()));
        digest.incomplete(notice, lost);
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
