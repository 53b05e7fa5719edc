//! `motorwire plan`: JSON lines of move requests in, one JSON line (or CSV
//! samples) out per request; optionally an SVG plot of each planned move.

use std::num::NonZeroU64;
use std::path::{Path, PathBuf};

use clap::{Args as ClapArgs, ValueEnum};
use motorwire_planner::{Float, MotionProfile, Profile, Request, plan, plan_with_duration};
use serde::Deserialize;

use crate::console::note;
use crate::lines::filter;

/// Plan moves.
#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    /// The float type the planner computes in.
    #[arg(long, value_enum, default_value_t = Precision::F64)]
    precision: Precision,
    /// Plan every move to take exactly this many seconds (at least its
    /// minimum) instead of the shortest time.
    #[arg(long, value_name = "T")]
    duration: Option<f64>,
    /// Print samples every DT seconds (whole microseconds) as CSV
    /// `t,position,velocity,acceleration,jerk` instead of the JSON summary.
    #[arg(long, value_name = "DT")]
    sample: Option<f64>,
    /// Draw position, velocity, acceleration and jerk against time into an
    /// SVG file; the move on input line N > 1 goes to FILE-N.svg.
    #[arg(long, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    /// The unit of `start` and `target`, for the plot's axes: positions in
    /// UNIT, velocities in UNIT/s, accelerations in UNIT/s², jerk in
    /// UNIT/s³ (the planner itself is unit-free).
    #[arg(long, value_name = "UNIT", default_value = "deg")]
    unit: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Precision {
    F64,
    F32,
}

/// One input line.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Move {
    start: f64,
    target: f64,
    #[serde(default)]
    start_velocity: f64,
    #[serde(default)]
    target_velocity: f64,
    #[serde(default)]
    start_acceleration: f64,
    max_velocity: f64,
    max_acceleration: f64,
    max_deceleration: Option<f64>,
    max_jerk: Option<f64>,
    #[serde(default = "adaptive")]
    profile: ProfileName,
}

fn adaptive() -> ProfileName {
    ProfileName::Adaptive
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "lowercase")]
enum ProfileName {
    Trapezoidal,
    Scurve,
    Adaptive,
}

/// The most CSV rows one move may produce.
const MAX_SAMPLES: u64 = 10_000_000;

impl Move {
    fn request<F: Float>(&self) -> Request<F> {
        Request {
            start: F::from_f64(self.start),
            target: F::from_f64(self.target),
            start_velocity: F::from_f64(self.start_velocity),
            target_velocity: F::from_f64(self.target_velocity),
            start_acceleration: F::from_f64(self.start_acceleration),
            max_velocity: F::from_f64(self.max_velocity),
            max_acceleration: F::from_f64(self.max_acceleration),
            max_deceleration: self.max_deceleration.map(F::from_f64),
            max_jerk: self.max_jerk.map(F::from_f64),
            profile: match self.profile {
                ProfileName::Trapezoidal => MotionProfile::Trapezoidal,
                ProfileName::Scurve => MotionProfile::SCurve,
                ProfileName::Adaptive => MotionProfile::Adaptive,
            },
            overshoot: motorwire_planner::Overshoot::Allow,
        }
    }
}

pub(crate) fn run(args: &Args) -> u8 {
    let tick = match args.sample.map(tick_us).transpose() {
        Ok(t) => t,
        Err(e) => {
            note!("motorwire plan: --sample: {e}");
            return 2;
        }
    };
    if let Some(d) = args.duration
        && !(d.is_finite() && d >= 0.0)
    {
        note!("motorwire plan: --duration must be a finite number of seconds >= 0");
        return 2;
    }
    let mut line = 0usize;
    let mut header = false;
    filter(|text| {
        line += 1;
        let mv: Move = serde_json::from_str(text).map_err(|e| format!("bad request: {e}"))?;
        match args.precision {
            Precision::F64 => one::<f64>(args, &mv, tick, line, &mut header),
            Precision::F32 => one::<f32>(args, &mv, tick, line, &mut header),
        }
    })
}

fn one<F: Float>(
    args: &Args,
    mv: &Move,
    tick: Option<NonZeroU64>,
    line: usize,
    header: &mut bool,
) -> Result<String, String> {
    let req = mv.request::<F>();
    let profile = match args.duration {
        Some(t) => plan_with_duration(&req, F::from_f64(t)),
        None => plan(&req),
    }
    .map_err(|e| e.to_string())?;
    if let Some(path) = &args.plot {
        let path = numbered(path, line);
        draw(&profile, &path, &args.unit)
            .map_err(|e| format!("plotting to {}: {e}", path.display()))?;
    }
    match tick {
        Some(tick) => csv(&profile, tick, header),
        None => Ok(summary(&profile)),
    }
}

fn summary<F: Float>(p: &Profile<F>) -> String {
    let phases: Vec<serde_json::Value> = p
        .phases()
        .map(|ph| {
            serde_json::json!({
                "duration": ph.duration.to_f64(),
                "jerk": ph.start.jerk.to_f64(),
                "acceleration": ph.start.acceleration.to_f64(),
                "velocity": ph.start.velocity.to_f64(),
                "position": ph.start.position.to_f64(),
            })
        })
        .collect();
    let ((lo, t_lo), (hi, t_hi)) = p.position_extremes();
    let (peak_v, peak_t) = p.peak_velocity();
    let mut out = serde_json::json!({
        "duration": p.duration().to_f64(),
        "peak_velocity": peak_v.to_f64(),
        "peak_velocity_time": peak_t.to_f64(),
        "peak_acceleration": p.peak_acceleration().to_f64(),
        "position_min": [lo.to_f64(), t_lo.to_f64()],
        "position_max": [hi.to_f64(), t_hi.to_f64()],
        "overshoot": p.overshoot().is_some(),
        "phases": phases,
    });
    if let (Some(by), Some(obj)) = (p.overshoot(), out.as_object_mut()) {
        obj.insert("overshoot_by".to_owned(), serde_json::json!(by.to_f64()));
    }
    out.to_string()
}

/// `--sample DT` in whole microseconds.
fn tick_us(dt: f64) -> Result<NonZeroU64, String> {
    if !dt.is_finite() || dt <= 0.0 {
        return Err(format!("{dt} is not a positive number of seconds"));
    }
    let us = (dt * 1e6).round();
    if !(1.0..=1e15).contains(&us) {
        return Err(format!("{dt} s is not between 1 microsecond and 1e9 s"));
    }
    if (us - dt * 1e6).abs() > 1e-6 * us.max(1.0) {
        return Err(format!("{dt} s is not a whole number of microseconds"));
    }
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    NonZeroU64::new(us as u64).ok_or_else(|| format!("{dt} s rounds to zero microseconds"))
}

fn csv<F: Float>(p: &Profile<F>, tick: NonZeroU64, header: &mut bool) -> Result<String, String> {
    #[allow(clippy::cast_precision_loss)]
    let rows = p.duration().to_f64() * 1e6 / tick.get() as f64;
    if rows > MAX_SAMPLES as f64 {
        return Err(format!(
            "sampling {} s every {} us would print over {MAX_SAMPLES} rows",
            p.duration(),
            tick.get()
        ));
    }
    let mut out = String::new();
    if !*header {
        out.push_str("t,position,velocity,acceleration,jerk\n");
        *header = true;
    }
    for (t_us, s) in p.ticks(tick) {
        use std::fmt::Write as _;
        let _ = writeln!(
            out,
            "{}.{:06},{},{},{},{}",
            t_us / 1_000_000,
            t_us % 1_000_000,
            s.position.to_f64(),
            s.velocity.to_f64(),
            s.acceleration.to_f64(),
            s.jerk.to_f64()
        );
    }
    // `filter` adds the line's newline.
    out.pop();
    Ok(out)
}

/// FILE for line 1, FILE-N.svg for line N.
fn numbered(path: &Path, line: usize) -> PathBuf {
    if line <= 1 {
        return path.to_path_buf();
    }
    let stem = path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let ext = path
        .extension()
        .map_or_else(|| "svg".to_owned(), |e| e.to_string_lossy().into_owned());
    path.with_file_name(format!("{stem}-{line}.{ext}"))
}

/// Four stacked panels against one time axis.
fn draw<F: Float>(p: &Profile<F>, path: &Path, unit: &str) -> Result<(), String> {
    use plotters::prelude::*;
    let duration = p.duration().to_f64().max(1e-9);
    let n = 1000u32;
    let samples: Vec<(f64, [f64; 4])> = (0..=n)
        .map(|i| {
            let t = duration * f64::from(i) / f64::from(n);
            let s = p.sample(F::from_f64(t));
            (
                t,
                [
                    s.position.to_f64(),
                    s.velocity.to_f64(),
                    s.acceleration.to_f64(),
                    s.jerk.to_f64(),
                ],
            )
        })
        .collect();
    let root = SVGBackend::new(path, (1000, 1100)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let panels = root.split_evenly((4, 1));
    // Every axis says its unit: time in seconds below each panel, and
    // each quantity in the move's unit beside it.
    let names = [
        format!("position ({unit})"),
        format!("velocity ({unit}/s)"),
        format!("acceleration ({unit}/s²)"),
        format!("jerk ({unit}/s³)"),
    ];
    let colors = [BLUE, GREEN, RED, MAGENTA];
    for (k, area) in panels.iter().enumerate() {
        let name = names.get(k).map_or("", String::as_str);
        let values = samples
            .iter()
            .map(|(_, v)| v.get(k).copied().unwrap_or(0.0));
        let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        let pad = ((hi - lo) * 0.08).max(1e-9 * hi.abs().max(1.0));
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .caption(name, ("sans-serif", 22))
            .x_label_area_size(32)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..duration, (lo - pad)..(hi + pad))
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 15))
            .x_desc("time (s)")
            .y_desc(name)
            .draw()
            .map_err(|e| e.to_string())?;
        let color = colors.get(k).copied().unwrap_or(BLACK);
        chart
            .draw_series(LineSeries::new(
                samples
                    .iter()
                    .map(|(t, v)| (*t, v.get(k).copied().unwrap_or(0.0))),
                color.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())
}
