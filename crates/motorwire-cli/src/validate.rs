//! `motorwire validate`.

use std::io::{self, Write};

use clap::ValueEnum;
use motorwire_wia::{MessageKind, Report, Rule, TimestampWindow, Validator, Violation};
use serde::Serialize;

use crate::console::note;
use crate::input::{self, Document, Refused};

/// The kinds `--kind` accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum KindArg {
    /// Infer the kind from the document's members.
    Auto,
    MotorCommand,
    MultiAxisCommand,
    MotorFeedback,
    Trajectory,
    PidConfig,
    SafetyLimits,
    ControlModeConfig,
}

impl KindArg {
    fn kind(self) -> Option<MessageKind> {
        match self {
            Self::Auto => None,
            Self::MotorCommand => Some(MessageKind::MotorCommand),
            Self::MultiAxisCommand => Some(MessageKind::MultiAxisCommand),
            Self::MotorFeedback => Some(MessageKind::MotorFeedback),
            Self::Trajectory => Some(MessageKind::Trajectory),
            Self::PidConfig => Some(MessageKind::PidConfig),
            Self::SafetyLimits => Some(MessageKind::SafetyLimits),
            Self::ControlModeConfig => Some(MessageKind::ControlModeConfig),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Format {
    /// One line per document, then one indented line per violation.
    Text,
    /// One JSON object per document.
    Json,
}

/// Validate WIA JSON messages.
///
/// Exit status: 0 when every document is valid, 1 when any is invalid,
/// 2 on a usage or I/O error (including a line with no end within 16 MiB
/// past --max-size, and a closed stdout).
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The kind of message; `auto` infers it and says which it chose.
    #[arg(long, value_enum, default_value_t = KindArg::Auto)]
    kind: KindArg,
    /// Judge by the JSON Schema alone, without WIA §10's semantic rules.
    #[arg(long)]
    schema_only: bool,
    /// The current time (Unix ms): timestamps further than `--max-age`
    /// from it, in the past or the future, are stale.
    #[arg(long, value_name = "UNIX_MS")]
    now: Option<u64>,
    /// With `--now`: the clock skew a timestamp may have either way (ms),
    /// the same window and default as the bridge's `--max-age` (0: not
    /// checked).
    #[arg(long, value_name = "MS", default_value_t = motorwire_bridge::DEFAULT_MAX_AGE_MS)]
    max_age: u64,
    /// Take members a kind's schema does not name (WIA's schemas leave
    /// objects open). Without it each is reported `unknown-member`, naming
    /// the nearest known member, as the bridge refuses it.
    #[arg(long)]
    allow_unknown: bool,
    /// Read one JSON document per line (JSON Lines); blank lines are skipped.
    #[arg(long)]
    lines: bool,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Text)]
    format: Format,
    /// The largest document accepted, in bytes (at most 16777216, 16 MiB),
    /// the same limit and default as the bridge's `--max-size` for a line.
    /// A bigger document, or line with --lines, is reported invalid
    /// (`document-too-large`) after reading at most this many bytes of it.
    #[arg(long, value_name = "BYTES", default_value_t = motorwire_bridge::DEFAULT_MAX_LINE,
          value_parser = parse_max_size)]
    max_size: usize,
    /// The deepest nesting accepted (at most 128).
    #[arg(long, value_name = "N", default_value_t = 32,
          value_parser = clap::value_parser!(u16).range(1..=128))]
    max_depth: u16,
    /// Files to validate; `-` is standard input.
    #[arg(required = true, value_name = "FILE")]
    files: Vec<String>,
}

/// The largest `--max-size` (16 MiB): a document is held whole in memory,
/// parsed, and checked against its schema, so the bound is on all three.
pub(crate) const MAX_SIZE_CEILING: usize = 16 << 20;

/// `--max-size` of `validate` and of the bridge: a number of bytes, 1 to
/// [`MAX_SIZE_CEILING`].
pub(crate) fn parse_max_size(s: &str) -> Result<usize, String> {
    let n: usize = s
        .parse()
        .map_err(|e| format!("{s:?} is not a number of bytes: {e}"))?;
    if n > MAX_SIZE_CEILING {
        return Err(format!(
            "{n} is over {MAX_SIZE_CEILING} (16 MiB), the largest line or document motorwire reads"
        ));
    }
    if n == 0 {
        return Err("0 bytes would take no line at all".to_owned());
    }
    Ok(n)
}

#[derive(Serialize)]
struct JsonResult<'a> {
    file: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    line: Option<usize>,
    kind: Option<MessageKind>,
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    auto: bool,
    valid: bool,
    errors: &'a [Violation],
    /// Violations found beyond those listed (at most
    /// `motorwire_wia::MAX_VIOLATIONS` are).
    #[serde(skip_serializing_if = "is_zero")]
    more_errors: usize,
}

#[allow(clippy::trivially_copy_pass_by_ref)] // serde passes a reference
const fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// `v` with `--now` (Unix ms) as its clock, when given.
pub(crate) fn with_clock(v: Validator, now: Option<u64>) -> Validator {
    match now {
        // Unix ms are exact in f64 until the year 285,000.
        #[allow(clippy::cast_precision_loss)]
        Some(now) => v.now_ms(now as f64),
        None => v,
    }
}

pub(crate) fn run(args: &Args) -> u8 {
    let validator = {
        let v = Validator::new()
            .max_document_size(args.max_size)
            .max_depth(usize::from(args.max_depth))
            .deny_unknown_members(!args.allow_unknown);
        // The bridge's window: `--max-age` either way, 0 not checked.
        #[allow(clippy::cast_precision_loss)] // ms are exact in f64 far beyond any skew
        let v = v.timestamp_window(if args.max_age > 0 {
            TimestampWindow::skew(args.max_age as f64)
        } else {
            TimestampWindow::ANY
        });
        with_clock(v, args.now)
    };
    let stdout = io::stdout();
    let mut out = io::BufWriter::new(stdout.lock());
    let mut any_invalid = false;
    let mut any_error = false;
    for file in &args.files {
        let result = validate_file(args, &validator, file, &mut out, &mut any_invalid);
        if let Err(e) = result {
            if e.kind() == io::ErrorKind::BrokenPipe {
                return 2;
            }
            any_error = true;
            let _ = out.flush();
            note!("motorwire validate: {file}: {e}");
        }
    }
    if out.flush().is_err() {
        return 2;
    }
    if any_error {
        2
    } else if any_invalid {
        1
    } else {
        0
    }
}

fn validate_file(
    args: &Args,
    validator: &Validator,
    file: &str,
    out: &mut dyn Write,
    any_invalid: &mut bool,
) -> io::Result<()> {
    let mut reader = input::open(file)?;
    if args.lines {
        let mut line_no = 0;
        while let Some(doc) = input::next_line(&mut *reader, args.max_size, &mut line_no)? {
            *any_invalid |= !judge(args, validator, file, doc, out)?;
        }
    } else {
        let doc = input::whole(&mut *reader, args.max_size)?;
        *any_invalid |= !judge(args, validator, file, doc, out)?;
    }
    Ok(())
}

/// Validates one document and prints its result; returns whether it was valid.
fn judge(
    args: &Args,
    validator: &Validator,
    file: &str,
    doc: Document,
    out: &mut dyn Write,
) -> io::Result<bool> {
    let auto = args.kind == KindArg::Auto;
    let report = match doc.text {
        Err(Refused::TooLarge { limit }) => Report::bounded(
            args.kind.kind(),
            vec![Violation::new(
                "",
                Rule::DocumentTooLarge,
                format!("the document is over {limit} bytes, the maximum"),
            )],
            0,
        ),
        Err(Refused::NotUtf8) => Report::bounded(
            args.kind.kind(),
            vec![Violation::new(
                "",
                Rule::JsonSyntax,
                "not valid JSON: the document is not UTF-8",
            )],
            0,
        ),
        Ok(text) => match (args.kind.kind(), args.schema_only) {
            (Some(kind), false) => validator.validate(kind, &text),
            (None, false) => validator.validate_auto(&text),
            (Some(kind), true) => validator.validate_schema_only(kind, &text),
            (None, true) => match MessageKind::infer(&text) {
                Ok(Some(kind)) => validator.validate_schema_only(kind, &text),
                // The full path explains why no kind could be told.
                _ => validator.validate_auto(&text),
            },
        },
    };
    let valid = report.is_valid();
    match args.format {
        Format::Json => {
            let line = JsonResult {
                file,
                line: doc.line,
                kind: report.kind,
                auto,
                valid,
                errors: &report.violations,
                more_errors: report.more,
            };
            serde_json::to_writer(&mut *out, &line).map_err(io::Error::other)?;
            writeln!(out)?;
        }
        Format::Text => {
            let place = match doc.line {
                Some(n) => format!("{file}:{n}"),
                None => file.to_owned(),
            };
            let kind = match (report.kind, auto) {
                (Some(k), true) => format!("{k} (auto)"),
                (Some(k), false) => k.to_string(),
                (None, _) => "unknown kind".to_owned(),
            };
            if valid {
                writeln!(out, "{place}: {kind}: valid")?;
            } else {
                writeln!(
                    out,
                    "{place}: {kind}: invalid, {} violation(s)",
                    report.count()
                )?;
                for v in &report.violations {
                    let pointer = if v.pointer.is_empty() {
                        "(document)"
                    } else {
                        &v.pointer
                    };
                    writeln!(out, "  {pointer}  [{}]  {}", v.rule, v.message)?;
                }
                if report.more > 0 {
                    writeln!(out, "  and {} more, not listed", report.more)?;
                }
            }
        }
    }
    Ok(valid)
}
