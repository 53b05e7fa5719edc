//! `motorwire sim servos`: simulated serial bus servos on a pseudo-terminal,
//! in real time, for code that opens a serial port (LeRobot's motor buses,
//! the vendors' SDKs, `motorwire bridge`).

use std::io::{Read, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use motorwire_servo::{Protocol, table};
use motorwire_sim::servo::{ServoBus, ServoFaults};
use serialport::{SerialPort, TTYPort};

use crate::console::note;

/// Simulated servos on a pseudo-terminal.
#[derive(Debug, clap::Args)]
pub(crate) struct ServosArgs {
    /// The protocol: `scs0` (Feetech STS/SMS), `scs1` (Feetech SCS),
    /// `dxl2` (Dynamixel Protocol 2.0); it must be the model's.
    #[arg(long)]
    protocol: String,
    /// The servos' model: `sts3215`, `scs0009`, `xl330-m288`,
    /// `xl430-w250`, `xm430-w350`.
    #[arg(long)]
    model: String,
    /// Their ids, comma-separated (`1,2,3,4,5,6`).
    #[arg(long, value_delimiter = ',', required = true)]
    ids: Vec<u8>,
    /// Where to link the pseudo-terminal (a serial port's path for the
    /// code under test); an existing link there is replaced, anything else
    /// there is refused. The link is left when the process is killed.
    #[arg(long, value_name = "PATH")]
    pty: PathBuf,
    /// Faults, comma-separated: `drop=P`, `corrupt=P`, `late=P`,
    /// `late-ms=N` (each answer dropped, one bit flipped, or sent late, with
    /// probability P), e.g. `drop=0.01,corrupt=0.01`.
    #[arg(long, value_name = "FAULTS")]
    faults: Option<String>,
    /// The faults' seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A hand that sweeps every servo whose torque is off this many
    /// degrees each way from its middle, once every `--sweep-period-ms`,
    /// as a person does to calibrate an arm (`motorwire servo calibrate`).
    #[arg(long, value_name = "DEG")]
    sweep: Option<f64>,
    /// The hand's period.
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    sweep_period_ms: u64,
}

fn faults(spec: &str) -> Result<ServoFaults, String> {
    let mut f = ServoFaults::default();
    let mut seen: Vec<&str> = Vec::new();
    for part in spec.split(',').filter(|p| !p.is_empty()) {
        let (key, value) = part
            .split_once('=')
            .ok_or_else(|| format!("--faults: {part:?} is not KEY=VALUE"))?;
        if seen.contains(&key) {
            return Err(format!("--faults: {key} is given twice"));
        }
        seen.push(key);
        let p = || -> Result<f64, String> {
            value
                .parse::<f64>()
                .ok()
                .filter(|p| (0.0..=1.0).contains(p))
                .ok_or_else(|| format!("--faults: {key}={value} is not a probability (0 to 1)"))
        };
        match key {
            "drop" => f.drop = p()?,
            "corrupt" => f.corrupt = p()?,
            "late" => f.late = p()?,
            "late-ms" => {
                let ms: u64 = value
                    .parse()
                    .map_err(|_| format!("--faults: late-ms={value} is not milliseconds"))?;
                f.late_by = Duration::from_millis(ms);
                if f.late == 0.0 {
                    f.late = 1.0;
                }
            }
            other => {
                return Err(format!(
                    "--faults: unknown fault {other:?} (drop, corrupt, late, late-ms)"
                ));
            }
        }
    }
    Ok(f)
}

pub(crate) fn servos(args: &ServosArgs) -> u8 {
    match serve(args) {
        Ok(()) => 0,
        Err(e) => {
            note!("motorwire sim servos: {e}");
            2
        }
    }
}

fn serve(args: &ServosArgs) -> Result<(), String> {
    let model = table::model(&args.model).ok_or_else(|| {
        let names: Vec<&str> = table::MODELS.iter().map(|m| m.name).collect();
        format!("unknown model {:?} ({})", args.model, names.join(", "))
    })?;
    let protocol = Protocol::from_name(&args.protocol)
        .ok_or_else(|| format!("unknown protocol {:?} (scs0, scs1, dxl2)", args.protocol))?;
    if protocol != model.protocol {
        return Err(format!(
            "{} speaks {}, not {}",
            model.name,
            model.protocol.name(),
            protocol.name()
        ));
    }
    let faults = args
        .faults
        .as_deref()
        .map(faults)
        .transpose()?
        .unwrap_or_default();
    let mut bus = ServoBus::new(model, &args.ids)
        .map_err(|e| e.to_string())?
        .with_faults(faults, args.seed);
    if let Some(degrees) = args.sweep {
        if !(degrees.is_finite() && (0.0..=180.0).contains(&degrees)) || args.sweep_period_ms == 0 {
            return Err(format!(
                "--sweep {degrees}: degrees in 0..=180, with a --sweep-period-ms above 0"
            ));
        }
        bus = bus.with_hand(degrees, Duration::from_millis(args.sweep_period_ms));
    }
    let (mut master, slave) = TTYPort::pair().map_err(|e| format!("a pseudo-terminal: {e}"))?;
    let pts = slave
        .name()
        .ok_or_else(|| "the pseudo-terminal has no path".to_owned())?;
    // Its other end is the client's to open (exclusively, as a serial
    // port library opens one): this one lets it go. Until a client has it
    // open, reading finds nothing (EIO), and is tried again.
    drop(slave);
    match std::fs::symlink_metadata(&args.pty) {
        Ok(m) if m.file_type().is_symlink() => {
            let _ = std::fs::remove_file(&args.pty);
        }
        Ok(_) => {
            return Err(format!(
                "{} exists and is not a link: it is left as it is",
                args.pty.display()
            ));
        }
        Err(_) => {}
    }
    std::os::unix::fs::symlink(&pts, &args.pty)
        .map_err(|e| format!("linking {} to {pts}: {e}", args.pty.display()))?;
    master
        .set_timeout(Duration::from_millis(50))
        .map_err(|e| e.to_string())?;
    note!(
        "motorwire sim servos: {} {} servo(s) (ids {:?}) on {pts}, linked at {}",
        args.ids.len(),
        model.name,
        args.ids,
        args.pty.display()
    );
    let start = Instant::now();
    let mut buf = [0u8; 4096];
    // Runs until the process is interrupted (SIGINT's default action).
    loop {
        let n = match master.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            // No client has the terminal open: its end hangs up (the
            // serial port library says a broken pipe; Linux, EIO).
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe || e.raw_os_error() == Some(5) => {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
            Err(e) => return Err(format!("reading the pseudo-terminal: {e}")),
        };
        let at = Instant::now();
        let answers = bus.write(start.elapsed(), buf.get(..n).unwrap_or(&[]));
        for a in answers {
            // Each answer at its return delay after the instruction, one
            // after another on the half-duplex bus.
            let due = at + a.delay;
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
            match master.write_all(&a.bytes) {
                Ok(()) => {}
                // The client closed the port before the answer went (a
                // late answer): it is lost, as on a bus nobody listens to,
                // and the servos wait for the next client.
                Err(e)
                    if e.kind() == std::io::ErrorKind::BrokenPipe
                        || e.raw_os_error() == Some(5) => {}
                Err(e) => return Err(format!("writing the pseudo-terminal: {e}")),
            }
        }
    }
}
